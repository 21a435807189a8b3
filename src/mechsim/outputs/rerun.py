"""Rerun recordings of a run: the same ROS messages a run publishes (or a bag holds), drawn.

``RerunSink(path)`` is an Outlet sink (``write(topic, type_name, msg, qos, ns)``, see
``mechsim.ros.outlet``); ``convert_bag(bag, path)`` feeds a rosbag2 MCAP bag through the same
sink, so a recording made live and one converted from the run's bag hold the same entities.

Layout of the recording (Rerun 0.41, one timeline ``sim_time``: duration = stamp − time_offset):

  world                                  ViewCoordinates RIGHT_HAND_Z_UP (REP-103), static
  world/<ns>/<frame>[/<frame>...]        Transform3D of each /tf, /tf_static frame relative to its
                                         parent entity (quaternions xyzw, as in ROS)
  <frame entity>/sphere|box|arrow|polyline_<k>   the model's ``Visual`` shapes, static, in the frame
  <frame entity>                         TransformAxes3D for "axes" visuals
  world/<ns>/visuals/link_<a>_<b>        segment between two frame origins, in world coordinates
  world/<ns>/visuals/trail_<frame>       one segment per sample (previous → current origin); the
                                         blueprint shows it over all past time, i.e. a growing path
  plots/<ns>/energy/<term>               kinetic, potential, total, energy_function,
                                         work_external, work_dissipated [J]
  plots/<ns>/balance_residual            (total − total₀) − (W_ext − W_diss) [J]
  plots/<ns>/drift/<invariant>           I − I₀ (a constraint residual as it is: it should be 0),
                                         as the invariant's ``Law`` (from system_info) says
  plots/<ns>/invariants/<name>, plots/<ns>/observables/<name>, plots/<ns>/state/<coordinate>
  plots/<ns>/diagnostics/<law>           level 0 OK, 1 WARN, 2 ERROR, 3 STALE from /diagnostics
                                         statuses named ``mechsim/<ns>/<law>``

``RerunSink.live(url)`` streams the same entities and blueprint to a Rerun viewer or server
(gRPC, ``rerun+http://HOST:PORT/proxy``; ``mechsim.outputs.rerun_live`` serves one on loopback)
instead of writing a file: the buffered columns are sent every ``LIVE_PERIOD`` s of wall time.

A system is learned from its ``<ns>/system_info`` message: system id and parameters give the model
(``mechsim.load_system``), hence its frames and visuals. Its time offset is that message's stamp,
which is always simulation time 0 (``DEFAULT_TIME_OFFSET`` until one arrives). Time series and
moving transforms are buffered and sent as columns (``send_columns``), a few thousand rows at a
time: no per-message logging cost and no ``log_time`` timeline.
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
import shutil
import sys
import tempfile
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mechsim.errors import MechsimError
from mechsim.files import publish
from mechsim.systems.base import Law

TIMELINE = "sim_time"
ENERGY_TERMS = ("kinetic", "potential", "total", "energy_function", "work_external",
                "work_dissipated")
#: Topics (by last path element / absolute name) and types the sink draws; the rest is ignored.
HANDLED_TYPES = {
    "mechsim_msgs/msg/SystemInfo", "mechsim_msgs/msg/Energy", "mechsim_msgs/msg/NamedScalars",
    "sensor_msgs/msg/JointState", "tf2_msgs/msg/TFMessage",
    "diagnostic_msgs/msg/DiagnosticArray",
}
_FLUSH_ROWS = 4096
#: Live streams: buffered columns are sent at least this often [s of wall time].
LIVE_PERIOD = 0.1
#: Live streams: how long :meth:`RerunSink.close` waits for the viewer to take the rest [s].
LIVE_FLUSH_TIMEOUT = 10.0
_BALANCE = Law("work_balance")
#: Line colours within one plot, in order (Tableau 10: distinguishable, also in print).
_PALETTE = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
            (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207))


def _colours(n: int) -> list[tuple[int, int, int]]:
    """``n`` line colours, all different: the palette, else hues evenly around the circle."""
    import colorsys

    if n <= len(_PALETTE):
        return list(_PALETTE[:n])
    colours = []
    for k in range(n):
        r, g, b = colorsys.hsv_to_rgb(k / n, 0.8, 0.85)
        colours.append((int(255 * r), int(255 * g), int(255 * b)))
    return colours


def _ns(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _part(name: str) -> str:
    import rerun as rr

    return str(rr.escape_entity_path_part(name))


@functools.lru_cache(maxsize=65536)
def _path(*names: str) -> str:
    """An entity path from plain names, each '/'-separated name split into parts."""
    return "/".join(_part(p) for n in names for p in n.split("/") if p)


def _qmul(a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, float, float, float]:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def _qrot(q: tuple[float, ...], v: tuple[float, ...]) -> tuple[float, float, float]:
    """Rotate v by the unit quaternion q (xyzw)."""
    x, y, z, w = q
    vx, vy, vz = v
    # t = 2 q_vec × v; v' = v + w t + q_vec × t
    tx, ty, tz = 2 * (y * vz - z * vy), 2 * (z * vx - x * vz), 2 * (x * vy - y * vx)
    return (vx + w * tx + y * tz - z * ty, vy + w * ty + z * tx - x * tz,
            vz + w * tz + x * ty - y * tx)


@dataclass
class _Series:
    """Buffered rows of one entity: times [ns of sim time] and one value per row."""

    kind: str  # "scalar" | "transform" | "strip"
    times: list[int] = field(default_factory=list)
    values: list[Any] = field(default_factory=list)
    rows: int = 0


@dataclass
class _Frame:
    parent: str
    entity: str
    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    known: bool = False  # a transform has been received


@dataclass
class _System:
    ns: str
    instance: str
    offset_ns: int
    system: str = ""
    key: tuple[str, ...] = ()
    links: list[tuple[str, str, str]] = field(default_factory=list)  # entity, frame a, frame b
    trails: list[tuple[str, str]] = field(default_factory=list)  # entity, frame
    last_trail: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    balance0: float | None = None  # the work balance's value at the epoch's first sample
    invariants0: dict[str, float] = field(default_factory=dict)
    laws: dict[str, Law] = field(default_factory=dict)  # invariant laws from system_info
    last_t: int = 0
    #: "<stream>/<name>" (state, invariants, drift, observables) -> unit, from the model: the
    #: blueprint draws one unit per plot
    units: dict[str, str] = field(default_factory=dict)


#: Longest wait for Rerun to write what it buffered when a recording is closed [s] (a file
#: writer that died on a full disk once left an unbounded flush waiting under load).
FLUSH_TIMEOUT = 120.0


class RerunSink:
    """Outlet sink writing a Rerun ``.rrd`` recording; call :meth:`close` to finish the file.

    The recording is written into a private temporary directory (``mkdtemp``, mode 0700) beside
    ``path`` and renamed onto ``path`` by :meth:`close` once Rerun has flushed it completely, so
    a failed write (a full disk) never leaves a half-written ``path``, and the error names it.
    ``replace=False``: an existing ``path`` is never overwritten (MechsimError at close);
    :meth:`discard` drops the recording. After a hard kill the recording so far stays in the
    hidden ``.<name>.*.partial`` directory (Rerun reads it)."""

    def __init__(self, path: str | Path, *, application_id: str = "mechsim",
                 recording_id: str | None = None, replace: bool = True) -> None:
        import rerun as rr

        self.path: Path | None = Path(path)
        self.replace = replace
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._tmpdir = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", suffix=".partial",
                                                 dir=self.path.parent))
        except OSError as e:
            raise MechsimError(f"rrd {self.path}: cannot write ({e.strerror or e})") from None
        self._tmp = self._tmpdir / self.path.name
        try:
            self.rec = rr.RecordingStream(
                application_id, recording_id=recording_id or f"mechsim-{uuid.uuid4()}")
            self.rec.save(str(self._tmp), default_blueprint=self._blueprint())
        except BaseException:
            self._remove_tmp()
            raise
        self._start(live=False)

    @classmethod
    def live(cls, url: str, *, application_id: str = "mechsim",
             recording_id: str | None = None) -> RerunSink:
        """A sink streaming to the Rerun viewer or server at ``url`` (``rerun+http://…/proxy``)
        instead of a file. The blueprint is sent once the systems are known and again, as the
        .rrd's, by :meth:`close`, which waits up to ``LIVE_FLUSH_TIMEOUT`` s for the rest to
        be taken; the viewer keeps what it received."""
        import rerun as rr

        self = cls.__new__(cls)
        self.path, self.replace, self._tmpdir = None, False, None
        self.rec = rr.RecordingStream(
            application_id, recording_id=recording_id or f"mechsim-{uuid.uuid4()}")
        self.rec.connect_grpc(url, default_blueprint=self._blueprint())
        self._start(live=True)
        return self

    def _start(self, *, live: bool) -> None:
        import rerun as rr

        self.rec.set_log_time_enabled(False)
        self.rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        from mechsim.outputs.messages import DEFAULT_TIME_OFFSET

        self.default_offset_ns = int(round(DEFAULT_TIME_OFFSET * 1e9))
        self.systems: dict[str, _System] = {}
        self.frames: dict[str, _Frame] = {"world": _Frame("", "world", known=True)}
        self.series: dict[str, _Series] = {}
        self.bbox: tuple[np.ndarray | None, np.ndarray | None] = (None, None)
        self.messages = 0
        self.closed = False
        self.peaks: dict[str, float] = {}  # entity -> largest |value| sent (scalars)
        self._live_next: float | None = time.monotonic() + LIVE_PERIOD if live else None
        self._live_blueprint: tuple[Any, ...] = ()

    # --- sink protocol ------------------------------------------------------------------------
    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        if type_name not in HANDLED_TYPES:
            return
        self.messages += 1
        base, _, leaf = topic.rpartition("/")
        sys_ns = base.strip("/")
        if type_name == "tf2_msgs/msg/TFMessage":
            self._on_tf(msg)
        elif type_name == "diagnostic_msgs/msg/DiagnosticArray":
            self._on_diagnostics(msg)
        elif type_name == "mechsim_msgs/msg/SystemInfo":
            self._on_info(sys_ns, msg)
        elif type_name == "mechsim_msgs/msg/Energy":
            self._on_energy(self._system(sys_ns), msg)
        elif type_name == "mechsim_msgs/msg/NamedScalars":
            st = self._system(sys_ns)
            t = self._t(st, msg.header.stamp)
            if leaf == "invariants":
                self._on_invariants(st, t, msg)
            else:
                for scalar in msg.scalars:
                    self._scalar(_path("plots", st.ns, leaf, scalar.name), t, scalar.value)
        elif type_name == "sensor_msgs/msg/JointState" and leaf == "state":
            st = self._system(sys_ns)
            t = self._t(st, msg.header.stamp)
            for name, value in zip(msg.name, msg.position, strict=False):
                self._scalar(_path("plots", st.ns, "state", name), t, value)

    def close(self) -> None:
        """Send the buffered columns and the final blueprint; finish the file and rename it
        onto ``path``. Idempotent. MechsimError naming the file if it could not be written
        (nothing is left at ``path`` then, nor a temporary)."""
        if self.closed:
            return
        self.closed = True
        if self._live_next is not None:
            self._close_live()
            return
        try:
            for entity in list(self.series):
                self._flush(entity)
            self.rec.send_blueprint(self._blueprint(), make_active=True, make_default=True)
            # RuntimeError if Rerun's file writer stopped (disk full, ...) or, bounded, hangs.
            self.rec.flush(timeout_sec=FLUSH_TIMEOUT)
            self.rec.disconnect()
            fd = os.open(self._tmp, os.O_RDONLY | os.O_NOFOLLOW)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
            publish(self._tmp, self.path, replace=self.replace)
        except FileExistsError:
            raise MechsimError(f"rrd {self.path}: exists (not replaced)") from None
        except OSError as e:
            raise MechsimError(f"rrd {self.path}: write failed ({e.strerror or e}); "
                               "nothing written") from None
        except RuntimeError as e:
            raise MechsimError(f"rrd {self.path}: write failed (Rerun's file writer stopped: "
                               f"{str(e).splitlines()[0] if str(e) else 'no reason given'}); "
                               "nothing written") from None
        finally:
            self._remove_tmp()

    def discard(self) -> None:
        """Stop and drop the recording: ``path`` is left as it was. Idempotent."""
        if not self.closed:
            self.closed = True
            with contextlib.suppress(Exception):
                self.rec.disconnect()
        self._remove_tmp()

    def _close_live(self) -> None:
        try:
            for entity in list(self.series):
                self._flush(entity)
            self.rec.send_blueprint(self._blueprint(), make_active=True, make_default=True)
            self.rec.flush(timeout_sec=LIVE_FLUSH_TIMEOUT)
        finally:
            with contextlib.suppress(Exception):
                self.rec.disconnect()

    def _send_live(self) -> None:
        """Send every buffered column; the blueprint too once the systems (or the 3D extent
        that places the camera) are first known."""
        for entity in list(self.series):
            self._flush(entity)
        shown = (tuple(st.key for st in self.systems.values()), self.bbox[0] is not None)
        if shown != self._live_blueprint and shown[0]:
            self._live_blueprint = shown
            self.rec.send_blueprint(self._blueprint(), make_active=True, make_default=True)
        self._live_next = time.monotonic() + LIVE_PERIOD

    def _remove_tmp(self) -> None:
        if self._tmpdir is not None:
            shutil.rmtree(self._tmpdir, ignore_errors=True)

    def __enter__(self) -> RerunSink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- systems ------------------------------------------------------------------------------
    def _system(self, ns: str) -> _System:
        st = self.systems.get(ns)
        if st is None:
            st = self.systems[ns] = _System(ns, ns.rpartition("/")[2], self.default_offset_ns)
        return st

    def _t(self, st: _System, stamp: Any) -> int:
        t = _ns(stamp) - st.offset_ns
        if t > st.last_t:
            st.last_t = t
        elif t < st.last_t - 1:  # time went back: the system was reset
            self._rebaseline(st)
            st.last_t = t
        return t

    def _rebaseline(self, st: _System) -> None:
        st.balance0 = None
        st.invariants0.clear()
        st.last_trail.clear()

    def _on_info(self, ns: str, info: Any) -> None:
        import yaml

        st = self._system(ns)
        st.instance = info.instance or st.instance
        st.offset_ns = _ns(info.header.stamp)  # system_info is stamped at simulation time 0
        key = (info.system, info.parameters_yaml, *info.laws)
        if key == st.key:
            return
        first = not st.key
        st.key, st.system = key, info.system
        self._rebaseline(st)
        st.laws = {}
        for law_key in info.laws:
            try:
                law = Law.from_key(law_key)
            except ValueError:
                continue
            if law.stream == "invariants":
                st.laws[law.name] = law
        if first:
            self._label_plots(st, info)
        try:
            from mechsim import load_system

            params = yaml.safe_load(info.parameters_yaml) or {}
            model = load_system(info.system, **params)
        except (MechsimError, yaml.YAMLError, TypeError):
            return  # not a system this mechsim knows: transforms and plots only
        self._log_visuals(st, model)
        self._label_units(st, model)

    def _label_plots(self, st: _System, info: Any) -> None:
        import rerun as rr

        for term in ENERGY_TERMS:
            self.rec.log(_path("plots", st.ns, "energy", term),
                         rr.SeriesLines(names=f"{term} [J]"), static=True)
        self.rec.log(_path("plots", st.ns, "balance_residual"),
                     rr.SeriesLines(names="(E − E₀) − (W_ext − W_diss) [J]"), static=True)
        for name, unit in zip(info.coordinates, info.coordinate_units, strict=False):
            self.rec.log(_path("plots", st.ns, "state", name),
                         rr.SeriesLines(names=f"{name} [{unit}]" if unit else name), static=True)

    def _label_units(self, st: _System, model: Any) -> None:
        """Units of the model's coordinates, invariants (and their drifts) and observables
        (its ``Quantity.unit``): legend names "name [unit]", and ``st.units`` for the
        blueprint. Coordinates are labelled from system_info by :meth:`_label_plots`."""
        import rerun as rr

        st.units.clear()
        for q in model.coordinates:
            st.units[f"state/{q.name}"] = q.unit
        for stream, quantities in (("invariants", model.invariants),
                                   ("drift", model.invariants),
                                   ("observables", model.observables)):
            for q in quantities:
                st.units[f"{stream}/{q.name}"] = q.unit
                law = st.laws.get(q.name) or Law.for_invariant(q.name)
                name = (f"{q.name} − {q.name}₀" if stream == "drift" and not law.is_constraint
                        else q.name)
                self.rec.log(_path("plots", st.ns, stream, q.name), rr.SeriesLines(
                    names=f"{name} [{q.unit}]" if q.unit else name), static=True)

    def _frame_entity(self, st: _System, frame: str) -> str:
        """Entity of a model frame (name without namespace), known from model.frames."""
        fid = "world" if frame == "world" else f"{st.instance}/{frame}"
        fr = self.frames.get(fid)
        return fr.entity if fr is not None else _path("world", fid)

    def _log_visuals(self, st: _System, model: Any) -> None:
        import rerun as rr

        # Entities of the model's frames (parents declared before children).
        for spec in model.frames:
            child = f"{st.instance}/{spec.child}"
            parent = "world" if spec.parent == "world" else f"{st.instance}/{spec.parent}"
            self._declare_frame(child, parent)
        st.links.clear()
        st.trails.clear()
        solid = rr.components.FillMode.Solid
        counts: dict[tuple[str, str], int] = {}
        for vis in model.visuals():
            n = counts[(vis.frame, vis.kind)] = counts.get((vis.frame, vis.kind), 0) + 1
            suffix = "" if n == 1 else f"_{n}"
            base = self._frame_entity(st, vis.frame)
            if vis.frame == "world":
                base = _path("world", st.ns)
            color = list(vis.color)
            if vis.kind == "sphere":
                self.rec.log(f"{base}/sphere{suffix}", rr.Points3D(
                    [[0.0, 0.0, 0.0]], radii=vis.radius, colors=[color]), static=True)
            elif vis.kind == "box":
                self.rec.log(f"{base}/box{suffix}", rr.Boxes3D(
                    half_sizes=[list(vis.size)], colors=[color], fill_mode=solid), static=True)
            elif vis.kind == "polyline":
                if vis.frame == "world" and vis.points:
                    self._extend(tuple(np.min(vis.points, axis=0)))
                    self._extend(tuple(np.max(vis.points, axis=0)))
                self.rec.log(f"{base}/polyline{suffix}", rr.LineStrips3D(
                    [list(vis.points)], radii=vis.radius, colors=[color]), static=True)
            elif vis.kind == "arrow" and vis.points:
                self.rec.log(f"{base}/arrow{suffix}", rr.Arrows3D(
                    vectors=[list(vis.points[0])], origins=[[0.0, 0.0, 0.0]],
                    radii=vis.radius * 0.2, colors=[color]), static=True)
            elif vis.kind == "axes":
                self.rec.log(base, rr.TransformAxes3D(vis.radius), static=True)
            elif vis.kind == "link" and vis.to_frame:
                entity = _path("world", st.ns, "visuals", f"link_{vis.frame}_{vis.to_frame}")
                st.links.append((entity, self._fid(st, vis.frame), self._fid(st, vis.to_frame)))
                self.rec.log(entity, rr.LineStrips3D.from_fields(
                    radii=vis.radius, colors=[color]), static=True)
            elif vis.kind == "trail":
                entity = _path("world", st.ns, "visuals", f"trail_{vis.frame}")
                st.trails.append((entity, self._fid(st, vis.frame)))
                self.rec.log(entity, rr.LineStrips3D.from_fields(
                    radii=min(vis.radius, 0.01), colors=[color]), static=True)

    @staticmethod
    def _fid(st: _System, frame: str) -> str:
        return "world" if frame == "world" else f"{st.instance}/{frame}"

    def _declare_frame(self, child: str, parent: str) -> _Frame:
        fr = self.frames.get(child)
        if fr is not None and fr.parent == parent:
            return fr
        if parent not in self.frames:
            self.frames[parent] = _Frame("world", _path("world", parent))
        parent_entity = self.frames[parent].entity
        local = child.rpartition("/")[2] if parent != "world" else child
        fr = _Frame(parent, f"{parent_entity}/{_path(local)}")
        self.frames[child] = fr
        return fr

    # --- transforms and shapes in world -------------------------------------------------------
    def _world_position(self, fid: str) -> tuple[float, float, float] | None:
        """Origin of frame ``fid`` in world; None until its whole chain has been posed."""
        chain = []
        while fid != "world":
            fr = self.frames.get(fid)
            if fr is None or not fr.known:
                return None
            chain.append(fr)
            fid = fr.parent
        p: tuple[float, float, float] = (0.0, 0.0, 0.0)
        q: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
        for fr in reversed(chain):
            d = _qrot(q, fr.translation)
            p = (p[0] + d[0], p[1] + d[1], p[2] + d[2])
            q = _qmul(q, fr.rotation)
        return p

    def _on_tf(self, msg: Any) -> None:
        touched: dict[str, int] = {}
        for tr in msg.transforms:
            child = tr.child_frame_id.lstrip("/")
            parent = tr.header.frame_id.lstrip("/") or "world"
            fr = self._declare_frame(child, parent)
            a, r = tr.transform.translation, tr.transform.rotation
            fr.translation = (float(a.x), float(a.y), float(a.z))
            fr.rotation = (float(r.x), float(r.y), float(r.z), float(r.w))
            fr.known = True
            ns = child.partition("/")[0]
            st = self._system(ns)
            t = self._t(st, tr.header.stamp)
            touched[ns] = t
            self._append(fr.entity, "transform", t, (fr.translation, fr.rotation))
            if parent == "world":
                self._extend(fr.translation)
        for ns, t in touched.items():
            st = self.systems[ns]
            for entity, a, b in st.links:
                pa, pb = self._world_position(a), self._world_position(b)
                if pa is None or pb is None:
                    continue
                self._extend(pa)
                self._extend(pb)
                self._append(entity, "strip", t, (pa, pb))
            for entity, fid in st.trails:
                p = self._world_position(fid)
                if p is None:
                    continue
                self._extend(p)
                prev = st.last_trail.get(entity, p)
                st.last_trail[entity] = p
                self._append(entity, "strip", t, (prev, p))

    def _extend(self, p: tuple[float, float, float]) -> None:
        """Grow the bounding box of drawn points (it places the default 3D camera)."""
        lo, hi = self.bbox
        if lo is None or hi is None:
            self.bbox = (np.array(p), np.array(p))
        elif not (lo[0] <= p[0] <= hi[0] and lo[1] <= p[1] <= hi[1] and lo[2] <= p[2] <= hi[2]):
            self.bbox = (np.minimum(lo, p), np.maximum(hi, p))

    # --- scalars ------------------------------------------------------------------------------
    def _on_energy(self, st: _System, m: Any) -> None:
        t = self._t(st, m.header.stamp)
        values = (m.kinetic, m.potential, m.total, m.energy_function, m.work_external,
                  m.work_dissipated)
        for term, value in zip(ENERGY_TERMS, values, strict=True):
            self._scalar(_path("plots", st.ns, "energy", term), t, value)
        balance = float(_BALANCE.value(energy=m))
        if st.balance0 is None:
            st.balance0 = balance
        self._scalar(_path("plots", st.ns, "balance_residual"), t,
                     _BALANCE.deviation(balance, st.balance0))

    def _on_invariants(self, st: _System, t: int, m: Any) -> None:
        for scalar in m.scalars:
            name, value = scalar.name, scalar.value
            self._scalar(_path("plots", st.ns, "invariants", name), t, value)
            law = st.laws.get(name) or Law.for_invariant(name)
            v0 = st.invariants0.setdefault(name, float(value))
            self._scalar(_path("plots", st.ns, "drift", name), t, law.deviation(float(value), v0))

    def _on_diagnostics(self, msg: Any) -> None:
        import rerun as rr

        for s in msg.status:
            prefix, _, rest = s.name.partition("/")
            if prefix != "mechsim" or "/" not in rest:
                continue
            ns, _, law = rest.partition("/")
            st = self._system(ns)
            stamp = _ns(msg.header.stamp)
            t = stamp - st.offset_ns if stamp else st.last_t
            level = s.level[0] if isinstance(s.level, bytes | bytearray) else int(s.level)
            entity = _path("plots", ns, "diagnostics", law)
            if entity not in self.series:
                self.rec.log(entity, rr.SeriesLines(
                    names=law, interpolation_mode=rr.components.InterpolationMode.StepAfter),
                    static=True)
            self._scalar(entity, t, level)

    # --- buffering ----------------------------------------------------------------------------
    def _scalar(self, entity: str, t: int, value: float) -> None:
        self._append(entity, "scalar", t, float(value) if math.isfinite(value) else math.nan)

    def _append(self, entity: str, kind: str, t: int, value: Any) -> None:
        s = self.series.get(entity)
        if s is None:
            s = self.series[entity] = _Series(kind)
        s.times.append(t)
        s.values.append(value)
        if len(s.times) >= _FLUSH_ROWS:
            self._flush(entity)
        if self._live_next is not None and time.monotonic() >= self._live_next:
            self._send_live()

    def _flush(self, entity: str) -> None:
        import rerun as rr

        s = self.series[entity]
        if not s.times:
            return
        index = [rr.TimeColumn(TIMELINE, duration=np.asarray(s.times, dtype="timedelta64[ns]"))]
        if s.kind == "scalar":
            values = np.asarray(s.values, dtype=np.float64)
            finite = np.abs(values[np.isfinite(values)])
            if finite.size:
                self.peaks[entity] = max(self.peaks.get(entity, 0.0), float(finite.max()))
            columns: Any = rr.Scalars.columns(scalars=values)
        elif s.kind == "transform":
            columns = rr.Transform3D.columns(
                translation=np.asarray([v[0] for v in s.values], dtype=np.float32),
                quaternion=np.asarray([v[1] for v in s.values], dtype=np.float32))
        else:
            columns = rr.LineStrips3D.columns(strips=np.asarray(s.values, dtype=np.float32))
        self.rec.send_columns(entity, indexes=index, columns=columns)
        s.rows += len(s.times)
        s.times, s.values = [], []

    # --- blueprint ----------------------------------------------------------------------------
    def _blueprint(self) -> Any:
        import rerun as rr
        import rerun.blueprint as rrb

        systems = [st for st in getattr(self, "systems", {}).values() if st.key]
        trails = [e for st in systems for e, _ in st.trails]
        growing = rrb.VisibleTimeRanges([rrb.VisibleTimeRange(
            TIMELINE, start=rrb.TimeRangeBoundary.infinite(),
            end=rrb.TimeRangeBoundary.cursor_relative())])
        eye = None
        lo, hi = getattr(self, "bbox", (None, None))
        if lo is not None and hi is not None:
            center = (lo + hi) / 2
            size = max(float(np.max(hi - lo)), 1.0)
            direction = np.array([1.0, 0.35, 0.45]) / np.linalg.norm([1.0, 0.35, 0.45])
            eye = rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital,
                                    position=(center + 1.5 * size * direction).tolist(),
                                    look_target=center.tolist(), eye_up=[0.0, 0.0, 1.0])
        view3d = rrb.Spatial3DView(name="world", origin="/world", eye_controls=eye,
                                   overrides={f"/{e}": growing for e in trails})
        # Every plot on the same time axis, from simulation time 0 (not from each plot's first
        # sample), one unit per plot, no colour twice in a plot; residuals and drifts say their
        # magnitude in the title (their axis shows round-off around 0 without one).
        axis_x = rrb.TimeAxis(view_range=rrb.TimeRange(
            start=rrb.TimeRangeBoundary.absolute(seconds=0.0),
            end=rrb.TimeRangeBoundary.infinite()))

        def plot(name: str, origin: str, contents: Any = "$origin/**",
                 entities: list[str] | None = None, **kw: Any) -> Any:
            entities = entities or []
            colours = {e: rr.SeriesLines.from_fields(colors=[c])
                       for e, c in zip(entities, _colours(len(entities)), strict=True)}
            return rrb.TimeSeriesView(name=name, origin=origin, contents=contents,
                                      axis_x=axis_x, overrides=colours, **kw)

        def peak(root: str, keys: list[str]) -> str:
            peaks = getattr(self, "peaks", {})
            values = [peaks[e] for e in (f"{root[1:]}/{_path(k)}" for k in keys) if e in peaks]
            return f", max |·| = {max(values):.1e}" if values else ""

        def by_unit(st: _System, root: str, streams: tuple[str, ...], what: str) -> list[Any]:
            groups: dict[str, list[str]] = {}
            for key, unit in st.units.items():
                if key.partition("/")[0] in streams:
                    groups.setdefault(unit, []).append(key)
            views = []
            for unit, keys in groups.items():
                names = [k.partition("/")[2] for k in keys]
                shown = ", ".join(names) if len(names) <= 3 else f"{names[0]}, … ({len(names)})"
                views.append(plot(f"{st.ns}: {what}{shown} [{unit or '1'}]"
                                  f"{peak(root, keys) if what else ''}", root,
                                  [f"$origin/{_path(k)}" for k in keys],
                                  [f"{root}/{_path(k)}" for k in keys]))
            return views

        def row(views: list[Any]) -> Any:
            return views[0] if len(views) == 1 else rrb.Tabs(*views)

        if not systems:
            plots: Any = rrb.TimeSeriesView(name="plots", origin="/plots")
        else:
            tabs = []
            for st in systems:
                root = f"/{_path('plots', st.ns)}"
                residual = plot(f"{st.ns}: balance residual [J]"
                                f"{peak(root, ['balance_residual'])}", root,
                                ["$origin/balance_residual"])
                if st.units:
                    values = by_unit(st, root, ("state", "observables"), "")
                    drifts = by_unit(st, root, ("drift",), "drift of ")
                else:  # units unknown (not a model this mechsim has): by stream
                    values = [plot(f"{st.ns}: coordinates, observables", root,
                                   ["$origin/state/**", "$origin/observables/**"])]
                    drifts = [plot(f"{st.ns}: invariant drifts", root, ["$origin/drift/**"])]
                diagnostics = sorted(f"/{e}" for e in self.series
                                     if f"/{e}".startswith(f"{root}/diagnostics/"))
                tabs.append(rrb.Vertical(
                    plot(f"{st.ns}: energy [J]", f"{root}/energy",
                         entities=[f"{root}/energy/{t}" for t in ENERGY_TERMS]),
                    row([residual, *drifts]),
                    row(values),
                    plot(f"{st.ns}: diagnostics (0 OK … 3 STALE)", f"{root}/diagnostics",
                         entities=diagnostics, axis_y=rrb.ScalarAxis(range=(-0.2, 3.2))),
                    name=st.ns))
            plots = tabs[0] if len(tabs) == 1 else rrb.Tabs(*tabs)
        return rrb.Blueprint(rrb.Horizontal(view3d, plots, column_shares=[3, 2]),
                             rrb.BlueprintPanel(state="collapsed"),
                             rrb.SelectionPanel(state="collapsed"),
                             rrb.TimePanel(state="collapsed", timeline=TIMELINE,
                                           play_state="following"))

    def rows(self, entity: str) -> int:
        """Rows sent or buffered so far for ``entity`` (a path without leading '/')."""
        s = self.series.get(entity)
        return 0 if s is None else s.rows + len(s.times)


# --- bags ---------------------------------------------------------------------------------------
def convert_bag(bag: str | Path, rrd: str | Path, *, replace: bool = False) -> dict[str, int]:
    """Feed every drawable message of a rosbag2 MCAP bag (``mechsim.outputs.bag.read_messages``,
    recording order) through a RerunSink writing ``rrd``: the same recording as a live run.
    Returns the number of messages per topic that were drawn.

    ``rrd`` appears only once the whole bag was read and the recording written; an existing
    ``rrd`` is replaced only with ``replace`` (MechsimError otherwise, before any work), and on
    any error (a corrupt bag, Ctrl-C) it is left as it was."""
    from mechsim.environment import import_rclpy

    import_rclpy()
    from rclpy.serialization import deserialize_message

    from mechsim.outputs.bag import check_bag, message_class, read_messages

    check_bag(bag)  # a clear error (unreadable, being recorded) before any work
    if not replace and os.path.lexists(rrd):
        raise MechsimError(f"rrd {rrd}: exists (not replaced)")
    counts: dict[str, int] = {}
    classes: dict[str, Any] = {}
    sink = RerunSink(rrd, replace=replace)
    try:
        for m in read_messages(bag):
            if m.type_name not in HANDLED_TYPES:
                continue
            cls = classes.get(m.type_name)
            if cls is None:
                cls = classes[m.type_name] = message_class(m.type_name)
            try:
                msg = deserialize_message(m.data, cls)
            except Exception:  # noqa: BLE001 - rclpy raises plain exceptions on bad CDR
                raise MechsimError(f"bag {bag}: a {m.type_name} message on {m.topic} does not "
                                   "deserialize (corrupt bag)") from None
            sink.write(m.topic, m.type_name, msg, None, m.log_time)
            counts[m.topic] = counts.get(m.topic, 0) + 1
    except BaseException:
        sink.discard()
        raise
    sink.close()
    return counts


# --- command line -------------------------------------------------------------------------------
def viewer_command() -> list[str]:
    """The Rerun viewer of this environment (``rerun`` next to the interpreter)."""
    exe = Path(sys.executable).parent / "rerun"
    return [str(exe) if exe.exists() else "rerun"]
