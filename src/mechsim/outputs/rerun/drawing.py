"""Samples drawn: gathered per stream as they come and drawn in blocks of rows with numpy.

A stream is a topic (for /tf, the frames of one message). Drawn are scalars, drifts (each
epoch's first value taken per stream: a time going back by more than 1 ns is a reset), frame
chains composed row by row with vectorised quaternion products, link and trail segments, and
diagnostics levels. A frame's chain takes the frames of its own block row by row and any other
frame at its latest pose (mechsim's frames: the one /tf message of a system, and /tf_static).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from mechsim.outputs.rerun.entities import ENERGY_TERMS, path, stamp_ns
from mechsim.outputs.rerun.series import Buffers
from mechsim.outputs.rerun.world import System, World
from mechsim.systems.base import Law

if TYPE_CHECKING:
    from mechsim.outputs.messages import Columns, EnergyColumns, TransformColumns

#: A stream's gathered samples are drawn once this many have come (and before anything that
#: changes how they are drawn: a system_info, /tf_static, a live send, the end).
DRAW_ROWS = 1024
_BALANCE = Law("work_balance")


@dataclass
class Stream:
    """Samples of one topic (for /tf: of one set of frames) gathered as they come, drawn
    together: pieces of columns joined into one block of rows."""

    topic: str
    shape: Any = None  # the names (state, invariants, observables) or parent frames it has
    ns: list[np.ndarray] = field(default_factory=list)
    values: list[Columns] = field(default_factory=list)
    rows: int = 0
    #: Per system: the latest sample time drawn [ns of sim time] (a time earlier by more
    #: than 1 ns is a reset: the stream's epoch starts again)
    last_t: dict[str, int] = field(default_factory=dict)


@functools.cache
def _transform_columns_type() -> type:
    from mechsim.outputs.messages import TransformColumns

    return TransformColumns


def transform_columns(msg: Any) -> list[tuple[int, TransformColumns]]:
    """A TFMessage as one-row transform columns, one per run of transforms with one stamp."""
    from mechsim.outputs.messages import TransformColumns

    runs: list[tuple[int, list[str], list[str], list[list[float]]]] = []
    for tr in msg.transforms:
        stamp = stamp_ns(tr.header.stamp)
        if not runs or runs[-1][0] != stamp:
            runs.append((stamp, [], [], []))
        a, r = tr.transform.translation, tr.transform.rotation
        runs[-1][1].append(tr.header.frame_id)
        runs[-1][2].append(tr.child_frame_id)
        runs[-1][3].append([a.x, a.y, a.z, r.x, r.y, r.z, r.w])
    return [(stamp, TransformColumns(parents, children, np.array([rows], dtype=np.float64)))
            for stamp, parents, children, rows in runs]


def _initials(v: np.ndarray, starts: list[int], v0: float | None) -> tuple[np.ndarray, float]:
    """Each row's initial value, that of its epoch's first row (``v0`` for rows before the
    first start, when the epoch began earlier), and the last epoch's."""
    out = np.empty_like(v)
    cur = v0
    bounds = [0, *starts, len(v)]
    for a, b in zip(bounds[:-1], bounds[1:], strict=False):
        if a == b:
            continue
        if cur is None or a in starts:
            cur = float(v[a])
        out[a:b] = cur
    assert cur is not None
    return out, cur


class Drawing:
    """The streams gathered and not drawn yet, drawn into ``buffers`` with what ``world``
    knows of the systems and frames."""

    def __init__(self, rec: Any, world: World, buffers: Buffers) -> None:
        self.rec = rec
        self.world = world
        self.buffers = buffers
        #: Samples gathered and not drawn yet: by topic (for transforms: topic and frames)
        self.streams: dict[Any, Stream] = {}

    def gather(self, topic: str, ns: np.ndarray, values: Columns) -> Stream:
        """Keep a piece of a stream's samples; draw the stream once it holds ``DRAW_ROWS``.
        (Called for every piece of every topic of a paced run: kept lean.)"""
        kind = type(values)
        shape: Any
        if kind is dict:
            key: Any = topic
            shape = values.keys()  # type: ignore[union-attr]
        elif kind is _transform_columns_type():
            key = (topic, *values.children)  # type: ignore[union-attr]
            shape = values.parents  # type: ignore[union-attr]
        else:  # EnergyColumns
            key, shape = topic, None
        s = self.streams.get(key)
        if s is None:
            s = self.streams[key] = Stream(topic, shape)
        elif s.shape != shape:  # other names or parents: what came before is drawn as it was
            self.draw(s)
            s.shape = shape
        s.ns.append(ns)
        s.values.append(values)
        s.rows += len(ns)
        if s.rows >= DRAW_ROWS:
            self.draw(s)
        return s

    def settle(self) -> None:
        """Draw everything gathered."""
        for s in self.streams.values():
            self.draw(s)

    def draw(self, s: Stream) -> None:
        """Draw a stream's gathered samples (its blocks of rows joined) and forget them."""
        if not s.rows:
            return
        from mechsim.outputs.messages import TransformColumns, joined_columns

        ns = np.concatenate(s.ns).astype(np.int64, copy=False)
        values = joined_columns(s.values)
        s.ns, s.values, s.rows = [], [], 0
        if isinstance(values, TransformColumns):
            self._draw_transforms(s, ns, values)
            return
        base, _, leaf = s.topic.rpartition("/")
        st = self.world.system(base.strip("/"))
        t = ns - st.offset_ns
        starts = self._epochs(s, st, t)
        if isinstance(values, dict):
            for name, v in values.items():
                v = np.asarray(v, dtype=np.float64)
                self.buffers.scalars(path("plots", st.ns, leaf, name), t, v)
                if leaf == "invariants":
                    self._draw_drift(st, name, t, v, starts)
        else:
            self._draw_energy(st, t, values, starts)  # type: ignore[arg-type]

    @staticmethod
    def _epochs(s: Stream, st: System, t: np.ndarray) -> list[int]:
        """Rows of ``t`` (sample times of ``st`` on stream ``s``) where the time went back by
        more than 1 ns since the latest sample: the system was reset, a new epoch begins."""
        last = s.last_t.get(st.ns, 0)
        starts: list[int] = []
        lo = 0
        while lo < len(t):
            seg = t[lo:]
            latest = np.maximum(np.maximum.accumulate(seg), last)
            before = np.concatenate(([last], latest[:-1]))
            back = np.flatnonzero(seg < before - 1)
            if not back.size:
                last = int(latest[-1])
                break
            k = lo + int(back[0])
            starts.append(k)
            last = int(t[k])
            lo = k + 1
        s.last_t[st.ns] = st.last_t = last
        return starts

    def _draw_energy(self, st: System, t: np.ndarray, e: EnergyColumns,
                     starts: list[int]) -> None:
        for term in ENERGY_TERMS:
            self.buffers.scalars(path("plots", st.ns, "energy", term), t,
                                 np.asarray(getattr(e, term), dtype=np.float64))
        balance = np.asarray(_BALANCE.value(energy=e), dtype=np.float64)
        initial, st.balance0 = _initials(balance, starts, st.balance0)
        self.buffers.scalars(path("plots", st.ns, "balance_residual"), t,
                             _BALANCE.deviation(balance, initial))

    def _draw_drift(self, st: System, name: str, t: np.ndarray, v: np.ndarray,
                    starts: list[int]) -> None:
        """Drift of invariant ``name``: its law's deviation from the epoch's first value."""
        law = st.laws.get(name) or Law.for_invariant(name)
        initial, st.invariants0[name] = _initials(v, starts, st.invariants0.get(name))
        self.buffers.scalars(path("plots", st.ns, "drift", name), t, law.deviation(v, initial))

    def _draw_transforms(self, s: Stream, ns: np.ndarray, tc: TransformColumns) -> None:
        """Transforms of each frame relative to its parent entity; then, per system, its links
        and trail segments between frame origins in world, at every row."""
        values = np.asarray(tc.values, dtype=np.float64)
        columns: dict[str, int] = {}  # frame -> its transform in this block
        systems: dict[str, tuple[System, np.ndarray, list[int]]] = {}
        for k, (parent_id, child_id) in enumerate(zip(tc.parents, tc.children, strict=True)):
            child = child_id.lstrip("/")
            parent = parent_id.lstrip("/") or "world"
            fr = self.world.declare_frame(child, parent)
            fr.translation = tuple(float(x) for x in values[-1, k, :3])  # type: ignore[assignment]
            fr.rotation = tuple(float(x) for x in values[-1, k, 3:])  # type: ignore[assignment]
            fr.known = True
            columns[child] = k
            sys_ns = child.partition("/")[0]
            if sys_ns not in systems:
                st = self.world.system(sys_ns)
                t = ns - st.offset_ns
                starts = self._epochs(s, st, t)
                systems[sys_ns] = (st, t, starts)
            self.buffers.append(fr.entity, "transform", systems[sys_ns][1], values[:, k, :])
            if parent == "world":
                self.world.extend(values[:, k, :3])
        self._draw_segments(list(systems.values()), columns, values)

    def _draw_segments(self, systems: list[tuple[System, np.ndarray, list[int]]],
                       columns: dict[str, int], values: np.ndarray) -> None:
        """Links and trail segments between frame origins in world, at every row of a block
        of transforms (``values``, frame -> index ``columns``)."""
        world: dict[str, np.ndarray | None] = {}

        def position(fid: str) -> np.ndarray | None:
            if fid not in world:
                world[fid] = self.world.positions(fid, columns, values)
            return world[fid]

        for st, t, starts in systems:
            for entity, a, b in st.links:
                pa, pb = position(a), position(b)
                if pa is None or pb is None:
                    continue
                self.world.extend(pa)
                self.world.extend(pb)
                self.buffers.append(entity, "strip", t, np.stack([pa, pb], axis=1))
            for entity, fid in st.trails:
                p = position(fid)
                if p is None:
                    if starts:
                        st.last_trail.pop(entity, None)
                    continue
                self.world.extend(p)
                # Segments from the previous origin (none before an epoch's first sample).
                prev = np.empty_like(p)
                prev[1:] = p[:-1]
                last = None if starts[:1] == [0] else st.last_trail.get(entity)
                prev[0] = p[0] if last is None else last
                prev[starts] = p[starts]
                st.last_trail[entity] = tuple(float(x) for x in p[-1])  # type: ignore[assignment]
                self.buffers.append(entity, "strip", t, np.stack([prev, p], axis=1))

    def diagnostics(self, msg: Any) -> None:
        """A DiagnosticArray: the level of each ``mechsim/<ns>/<law>`` status (0 OK, 1 WARN,
        2 ERROR, 3 STALE), at its stamp (at the system's latest sample if unstamped)."""
        import rerun as rr

        for s in msg.status:
            prefix, _, rest = s.name.partition("/")
            if prefix != "mechsim" or "/" not in rest:
                continue
            ns, _, law = rest.partition("/")
            st = self.world.system(ns)
            stamp = stamp_ns(msg.header.stamp)
            t = stamp - st.offset_ns if stamp else st.last_t
            level = s.level[0] if isinstance(s.level, bytes | bytearray) else int(s.level)
            entity = path("plots", ns, "diagnostics", law)
            if entity not in self.buffers.series:
                self.rec.log(entity, rr.SeriesLines(
                    names=law, interpolation_mode=rr.components.InterpolationMode.StepAfter),
                    static=True)
            self.buffers.scalars(entity, np.array([t], dtype=np.int64),
                                 np.array([level], dtype=np.float64))
