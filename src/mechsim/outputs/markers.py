"""A system drawn for RViz and Foxglove's 3D panel: ``visualization_msgs/MarkerArray``.

What is drawn is the model's own description of its look (``Model.visuals()``, the one Rerun
draws from too): each :class:`~mechsim.systems.base.Visual` becomes one marker of the
instance's namespace (``Marker.ns``, ids in the order of ``visuals()``):

- sphere (a bob), box (an anchor, a pivot, a container), polyline (a wire, a surface's
  outline), arrow and axes: locked to their frame (``header.frame_id`` "<ns>/<frame>",
  ``frame_locked``), so they move with /tf;
- link (a rod, a spring): a LINE_LIST between the two frames' origins, in "world";
- trail: the recent path of a frame's origin as LINE_STRIPs in "world": points kept every
  stride-th sample (``TRAIL_POINTS`` of them span ``TRAIL_SPAN`` time scales of the model,
  ``Model.time_scale``), then the current position. It is drawn in two parts: a body (the
  ``BODY`` older kept points, up to the newest whose number is a multiple of ``SEGMENT``)
  that changes every ``SEGMENT`` kept points, and a head (the kept points since the body's
  newest, then the current position; ``SEGMENT + 1`` points, the oldest repeated where
  fewer) that changes with every sample: the last 57 to 64 kept points are shown.

A frame named "world" in a visual is the instance's origin.

Like /tf and /tf_static, the look is split by what changes (:meth:`MarkerEncoder.fixed`,
:meth:`MarkerEncoder.encode`):

- ``<ns>/markers_static`` (latched): a DELETEALL of the namespace, then every frame-locked
  visual. Their content never changes while the model's look is the same, and /tf moves them,
  so the set is published once per look (again when a parameter change alters it);
- ``<ns>/markers``, one message per sample: the links and the trails' heads only (a model
  without them has no such topic), each an ADD of the same namespace and id in every
  message, so RViz and Foxglove replace them in place;
- ``<ns>/markers_trails`` (latched): the trails' bodies (the same ids), one message with the
  samples where they change (:meth:`MarkerEncoder.bodies`) and the first one after a new
  look or epoch.

Each message on a topic holds everything that topic draws, so the latest one of each draws
the system (a late subscriber, a seek in a bag). All messages of one model share one layout
per topic, so a block of samples is encoded at once (``outputs.wire.Layout``: only the
moving points and the stamps change).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from mechsim.outputs.wire import Layout, encode
from mechsim.systems._rotation import quat_product, rotate
from mechsim.systems.base import Model, Visual

TYPE_NAME = "visualization_msgs/msg/MarkerArray"
#: Points a trail keeps before the current one, spread over ``TRAIL_SPAN`` time scales.
TRAIL_POINTS = 64
TRAIL_SPAN = 2.0
#: Kept points a trail's head holds at most: its body (the older kept points, on the trail
#: body topic) changes only once the head is full, every ``SEGMENT`` kept points.
SEGMENT = 8
#: Kept points of a body: its newest is also the head's oldest (the trail is one line).
BODY = TRAIL_POINTS - SEGMENT + 1
#: The kinds of visual that move in "world" (drawn on the per-sample topic).
MOVING = ("link", "trail")
#: Axes colours (x, y, z: red, green, blue, as RViz and Foxglove draw frames).
_AXES = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def _color(rgb: tuple[float, ...]) -> ColorRGBA:
    return ColorRGBA(r=rgb[0], g=rgb[1], b=rgb[2], a=1.0)


def _point(p: Any) -> Point:
    return Point(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def cleared(name: str, ns: int) -> MarkerArray:
    """A DELETEALL of namespace ``name``, stamped ``ns``: what an instance drew goes."""
    m = Marker(ns=name, action=Marker.DELETEALL)
    m.header.stamp = Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
    return MarkerArray(markers=[m])


def _drawable(v: Visual, frames: set[str]) -> bool:
    ends = [v.frame] + ([v.to_frame] if v.kind == "link" else [])
    known = all(f == "world" or f in frames for f in ends if f)
    if v.kind == "trail":
        return v.frame in frames
    if v.kind == "link":
        return known and bool(v.to_frame)
    return known and (v.kind != "arrow" or bool(v.points))


def drawn(model: Model) -> list[Visual]:
    """The visuals of ``model`` that can be drawn (their frames are the model's)."""
    if not model.frames:
        return []
    frames = {f.child for f in model.frames}
    return [v for v in model.visuals() if _drawable(v, frames)]


def topics_of(model: Model) -> tuple[bool, bool]:
    """Does ``model`` draw (frame-locked markers: ``<ns>/markers_static``, moving ones:
    ``<ns>/markers``)?"""
    kinds = {v.kind for v in drawn(model)}
    return bool(kinds - set(MOVING)), bool(kinds & set(MOVING))


class MarkerEncoder:
    """The markers of one model's instance (``name``, world-rooted frames at ``origin``)."""

    def __init__(self, model: Model, name: str, origin: tuple[float, float, float]) -> None:
        self.name = name
        self.origin = np.asarray(origin, dtype=float)
        self.specs = list(model.frames)
        self.index = {f.child: k for k, f in enumerate(self.specs)}
        self.parent = [self.index.get(f.parent) for f in self.specs]
        self.visuals = drawn(model)
        self.links = [(self.index.get(v.frame), self.index.get(v.to_frame or ""))
                      for v in self.visuals if v.kind == "link"]
        self.trails = [self.index[v.frame] for v in self.visuals if v.kind == "trail"]
        #: The frames whose world origins the moving markers draw, and their ancestors, by
        #: generation: the world-rooted ones, then their children, and so on (the other
        #: frames' origins are not computed).
        self.generations = self._generations(self._ancestry(
            [k for pair in self.links for k in pair if k is not None] + self.trails))
        self.time_scale = float(model.time_scale())
        #: The ids (indices in ``visuals``) of the frame-locked visuals and of the moving ones.
        self.fixed_ids = [i for i, v in enumerate(self.visuals) if v.kind not in MOVING]
        self.moving_ids = [i for i, v in enumerate(self.visuals) if v.kind in MOVING]
        self.prototype = MarkerArray(markers=[self._marker(i, self.visuals[i])
                                              for i in self.moving_ids])
        #: The layout of the per-sample markers; None: nothing moves (no per-sample topic).
        self.layout = Layout(TYPE_NAME, self.prototype) if self.moving_ids else None
        self.block = None if self.layout is None else self.layout.block([
            f"markers.{m}.points.{j}.{c}" for m, marker in enumerate(self.prototype.markers)
            for j in range(len(marker.points)) for c in "xyz"])
        #: The trail bodies (``<ns>/trail_bodies``): the older kept points of every trail.
        self.body_layout = Layout(TYPE_NAME, MarkerArray(markers=[
            self._body(i) for i in self.moving_ids if self.visuals[i].kind == "trail"])) \
            if self.trails else None
        self.body_block = None if self.body_layout is None else self.body_layout.block([
            f"markers.{m}.points.{j}.{c}" for m in range(len(self.trails))
            for j in range(BODY) for c in "xyz"])
        #: The trail points kept so far: their times and world positions (kept, trails, 3).
        self.kept_t = np.zeros(0)
        self.kept_p = np.zeros((0, len(self.trails), 3))
        #: The block ``encode`` made last (``bodies``), and the newest point's time of the
        #: last body made (NaN: none yet).
        self._block: tuple[np.ndarray, ...] = ()
        self._sent = math.nan

    @property
    def look(self) -> bytes:
        """What the frame-locked markers draw (their CDR bytes without stamps): equal for two
        encoders whose ``fixed`` sets differ only in their stamps."""
        return encode(TYPE_NAME, self.fixed(0))

    def fixed(self, ns: int) -> MarkerArray:
        """The ``<ns>/markers_static`` message stamped ``ns``: a DELETEALL of the namespace
        (what an earlier look drew goes), then every frame-locked marker."""
        markers = cleared(self.name, ns).markers
        markers += [self._marker(i, self.visuals[i]) for i in self.fixed_ids]
        for m in markers:
            m.header.stamp = markers[0].header.stamp
        return MarkerArray(markers=markers)

    def _ancestry(self, frames: list[int]) -> set[int]:
        """``frames`` and every ancestor of theirs."""
        found: set[int] = set()
        for k in frames:
            at: int | None = k
            while at is not None and at not in found:
                found.add(at)
                at = self.parent[at]
        return found

    def _generations(self, frames: set[int]) -> list[list[int]]:
        """The indices ``frames`` (closed under parents) by generation: those without a
        parent, then the children of those, and so on."""
        generations: list[list[int]] = []
        placed: set[int] = set()
        while len(placed) < len(frames):
            ready = [k for k in sorted(frames) if k not in placed
                     and (self.parent[k] is None or self.parent[k] in placed)]
            if not ready:
                raise ValueError("the model's frames form a cycle")
            generations.append(ready)
            placed.update(ready)
        return generations

    def _marker(self, i: int, v: Visual) -> Marker:
        """The marker of visual ``v`` (``i``: its id), with the moving points at the origin."""
        m = Marker(ns=self.name, id=i, action=Marker.ADD, color=_color(
            tuple(c / 255.0 for c in v.color)))
        m.pose.orientation.w = 1.0
        locked = v.kind not in MOVING
        m.header.frame_id = self._frame_id(v.frame) if locked else "world"
        m.frame_locked = locked
        if v.frame == "world" and locked:
            m.pose.position = _point(self.origin)
        r = float(v.radius)
        if v.kind == "sphere":
            m.type = Marker.SPHERE
            m.scale.x = m.scale.y = m.scale.z = 2 * r
        elif v.kind == "box":
            m.type = Marker.CUBE
            m.scale.x, m.scale.y, m.scale.z = (2 * float(s) for s in v.size)
        elif v.kind == "polyline":
            m.type, m.scale.x = Marker.LINE_STRIP, 2 * r
            m.points = [_point(p) for p in v.points]
        elif v.kind == "arrow":
            m.type = Marker.ARROW
            m.scale.x, m.scale.y = 0.4 * r, 0.8 * r
            m.points = [Point(), _point(v.points[0])]
        elif v.kind == "axes":
            m.type, m.scale.x = Marker.LINE_LIST, 0.05 * r
            m.points = [q for axis in range(3) for q in (Point(), _point(r * np.eye(3)[axis]))]
            m.colors = [_color(_AXES[axis]) for axis in range(3) for _ in (0, 1)]
        elif v.kind == "link":
            m.type, m.scale.x = Marker.LINE_LIST, 2 * r
            m.points = [Point(), Point()]
        else:  # trail
            m.type, m.scale.x = Marker.LINE_STRIP, 2 * min(r, 0.01)
            m.points = [Point() for _ in range(SEGMENT + 1)]
        return m

    def _body(self, i: int) -> Marker:
        """The body of trail ``i`` (its older kept points: the trail's look, BODY points)."""
        m = self._marker(i, self.visuals[i])
        m.points = [Point() for _ in range(BODY)]
        return m

    def _frame_id(self, frame: str) -> str:
        return "world" if frame == "world" else f"{self.name}/{frame}"

    def world_origins(self, placed: np.ndarray) -> np.ndarray:
        """(samples, frames, 3): the origin in "world" of each frame of ``generations`` (the
        others' are zero), from the frames as published (``MessageFactory.placed``: relative
        to their parents, world-rooted ones moved by the origin)."""
        n, count = placed.shape[0], len(self.specs)
        # Component-major (component, frame, sample): each component of a generation is one
        # contiguous block, and the arithmetic element-wise, as frame by frame.
        frames = np.ascontiguousarray(placed.transpose(2, 1, 0))
        pos = np.zeros((3, count, n))
        rot = np.zeros((4, count, n))
        for k in self.generations:
            parents = [self.parent[j] for j in k]
            if parents[0] is None:  # the first generation: the frames without a parent
                pos[:, k], rot[:, k] = frames[:3, k], frames[3:, k]
                continue
            p = np.asarray(parents, dtype=np.int64)
            qp = rot[:, p]
            pos[:, k] = pos[:, p] + np.stack(rotate(qp, frames[:3, k]))
            rot[:, k] = np.stack(quat_product(qp, frames[3:, k]))
        return pos.transpose(2, 1, 0)

    def _at(self, pos: np.ndarray, k: int | None) -> np.ndarray:
        return np.broadcast_to(self.origin, pos[:, 0].shape) if k is None else pos[:, k]

    def encode(self, times: np.ndarray, ns: np.ndarray, placed: np.ndarray, rate: float,
               time_rows: np.ndarray | None = None) -> np.ndarray:
        """(samples, size) CDR rows of the moving markers of samples at ``times`` (stamps
        ``ns``), ``placed``: their frames as published; ``rate``: samples per simulated
        second. Only for a model with moving markers (``layout`` not None). The trail bodies
        of these samples: ``bodies`` (made once per block, after this)."""
        assert self.layout is not None and self.block is not None
        pos = self.world_origins(placed)
        heads = self._trails(times, ns, pos, rate) if self.trails else None
        links, trail = iter(self.links), 0
        columns = []
        for v in self.visuals:
            if v.kind == "link":
                a, b = next(links)
                columns.append(np.hstack([self._at(pos, a), self._at(pos, b)]))
            elif v.kind == "trail":
                assert heads is not None
                columns.append(heads[:, :, trail, :].reshape(times.shape[0], -1))
                trail += 1
        return self.layout.encode(ns, [(self.block, np.hstack(columns))], time_rows)

    def _trails(self, times: np.ndarray, ns: np.ndarray, pos: np.ndarray,
                rate: float) -> np.ndarray:
        """(samples, SEGMENT + 1, trails, 3): each sample's trail heads, the points kept since
        its body's newest (the oldest of them repeated where fewer), then its own; the bodies
        (``bodies``) are kept from this block. Points kept at or after the block's first
        sample were computed ahead and dropped (or belong to an epoch that ended):
        forgotten first."""
        now = pos[:, self.trails]
        stride = max(1, math.ceil(TRAIL_SPAN * self.time_scale * rate / TRAIL_POINTS))
        step = np.rint(times * rate).astype(np.int64)
        keep = step % stride == 0
        before = np.flatnonzero(self.kept_t < times[0] - 0.5 / rate)[-TRAIL_POINTS:]
        kept_t = np.concatenate([self.kept_t[before], times[keep]])
        kept_p = np.concatenate([self.kept_p[before], now[keep]])
        if kept_t.size == 0:
            kept_t, kept_p = times[:1], now[:1]
        last = np.maximum(np.searchsorted(kept_t, times, side="right") - 1, 0)
        # The body ends at the newest kept point whose number (since t = 0) is a multiple of
        # SEGMENT: it changes every SEGMENT kept points.
        number = np.rint(kept_t[last] * rate).astype(np.int64) // stride
        end = np.maximum(last - number % SEGMENT, 0)
        idx = np.maximum(last[:, None] - SEGMENT + 1 + np.arange(SEGMENT), end[:, None])
        # Kept: the points before this block a trail needs, and the block's own (until the
        # next block shows this one was not dropped): at most TRAIL_POINTS + a block.
        self.kept_t, self.kept_p = kept_t, kept_p
        self._block = (ns, kept_t[end], kept_p, end)
        return np.concatenate([kept_p[idx], now[:, None]], axis=1)

    def bodies(self) -> Callable[[int, int], list[tuple[int, bytes]]]:
        """For the block ``encode`` made last: what makes the trail body messages of its
        samples i to j (exclusive), as (sample, CDR bytes): one where a sample's body differs
        from the last one made (its newest point is another; the first sample after a new
        look or epoch), so a reader's latest body is always its sample's."""
        assert self.body_layout is not None and self.body_block is not None
        ns, newest, kept_p, end = self._block
        layout, block = self.body_layout, self.body_block

        def make(i: int, j: int) -> list[tuple[int, bytes]]:
            changed = newest[i:j] != np.concatenate([[self._sent], newest[i:j - 1]])
            at = i + np.flatnonzero(changed)
            if not at.size:
                return []
            self._sent = float(newest[j - 1])
            idx = np.maximum(end[at, None] - BODY + 1 + np.arange(BODY), 0)
            rows = layout.encode(ns[at], [(block, kept_p[idx].transpose(0, 2, 1, 3).reshape(
                at.size, -1))])
            return [(int(k), r.tobytes()) for k, r in zip(at, rows, strict=True)]
        return make

    def message(self, row: np.ndarray) -> MarkerArray:
        """The MarkerArray of one encoded row (for a sink that takes messages)."""
        from rclpy.serialization import deserialize_message

        return deserialize_message(row.tobytes(), MarkerArray)

    def take_trails(self, other: MarkerEncoder) -> None:
        """Go on with ``other``'s trail points (a new model of the same look: a parameter
        change keeps the path drawn so far)."""
        if other.trails == self.trails:
            self.kept_t, self.kept_p = other.kept_t, other.kept_p


__all__ = ["BODY", "MOVING", "SEGMENT", "TRAIL_POINTS", "TYPE_NAME", "MarkerEncoder", "cleared",
           "drawn", "topics_of"]
