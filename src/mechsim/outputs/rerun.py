"""Rerun recordings of a run: the same ROS messages a run publishes (or a bag holds), drawn.

``RerunSink(path)`` is an Outlet sink (see ``mechsim.ros.outlet``): a run hands it each chunk
of samples as evaluated values (``write_columns(topic, ns, values)``: energy terms, /tf
transforms, state positions, invariants, observables) and the other messages one by one
(``write``); ``convert_bag(bag, path)`` feeds a rosbag2 MCAP bag's messages through ``write``,
which turns a sample's message into one-row columns: both are drawn by the same code, so a
recording made live and one converted from the run's bag are the same, row for row.

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
which is always simulation time 0 (``DEFAULT_TIME_OFFSET`` until one arrives).

Samples are gathered per stream (a topic; for /tf, the frames of one message) as they come and
drawn in blocks of rows with numpy: scalars, drifts (each epoch's first value taken per stream:
a time going back by more than 1 ns is a reset), frame chains composed row by row with
vectorised quaternion products, trail segments. Whatever changes how later samples are drawn
(system_info, /tf_static) draws what was gathered first. A frame's chain takes the frames of its
own block row by row and any other frame at its latest pose (mechsim's frames: the one /tf
message of a system, and /tf_static). Time series and moving transforms are then buffered and
sent as columns (``send_columns``), a few thousand rows at a time: no per-message logging cost
and no ``log_time`` timeline.
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
from typing import TYPE_CHECKING, Any

import numpy as np

from mechsim.errors import MechsimError
from mechsim.files import publish
from mechsim.systems.base import Law

if TYPE_CHECKING:
    from mechsim.outputs.messages import Columns, EnergyColumns, TransformColumns

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
#: A stream's gathered samples are drawn once this many have come (and before anything that
#: changes how they are drawn: a system_info, /tf_static, a live send, the end).
_DRAW_ROWS = 1024
#: Topics published with every sample whose types nothing here draws: their messages are not
#: made for this sink (``wants``). (markers: the recording draws the model's look itself.)
_NOT_DRAWN = ("clock", "pose", "twist", "markers")
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
    """Buffered rows of one entity: times [ns of sim time] and values, in pieces of rows."""

    kind: str  # "scalar" | "transform" (rows x y z qx qy qz qw) | "strip" (rows (2, 3))
    times: list[np.ndarray] = field(default_factory=list)
    values: list[np.ndarray] = field(default_factory=list)
    buffered: int = 0
    rows: int = 0


@dataclass
class _Stream:
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

#: Recordings whose file writer stopped or hung (a full disk): kept referenced, since dropping
#: one flushes it again without a bound, and Rerun's exit hook is unregistered for the same
#: reason; a command that saw one ends its process with ``os._exit`` (``writer_stuck``).
_STUCK: list[Any] = []


def writer_stuck() -> bool:
    """Whether a recording's file writer failed in this process: exiting normally would wait
    on it without a bound (Rerun's exit hook flushes every recording)."""
    return bool(_STUCK)


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
        #: Samples gathered and not drawn yet: by topic (for transforms: topic and frames)
        self.streams: dict[Any, _Stream] = {}
        self._wanted: dict[str, bool] = {}
        self.bbox: tuple[np.ndarray | None, np.ndarray | None] = (None, None)
        self.messages = 0
        self.closed = False
        self.peaks: dict[str, float] = {}  # entity -> largest |value| sent (scalars)
        self._live_next: float | None = time.monotonic() + LIVE_PERIOD if live else None
        #: A live stream gets each sample as it is published (``Outlet.hand_over``).
        self.immediate = live
        self._live_blueprint: tuple[Any, ...] = ()

    # --- sink protocol ------------------------------------------------------------------------
    def wants(self, topic: str) -> bool:
        """Every topic but those of types never drawn (clock, pose, twist, markers)."""
        wanted = self._wanted.get(topic)
        if wanted is None:
            wanted = self._wanted[topic] = topic.rpartition("/")[2] not in _NOT_DRAWN
        return wanted

    def write_columns(self, topic: str, ns: np.ndarray, values: Columns) -> None:
        """A chunk of samples stamped ``ns`` as evaluated values (see ``Outlet.publish_chunk``):
        energy terms, /tf transforms, or name -> values (state positions, invariants,
        observables). Gathered per stream and drawn in blocks of rows."""
        self.messages += len(ns)
        self._gather(topic, ns, values)
        if self._live_next is not None and time.monotonic() >= self._live_next:
            self._send_live()

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        """One message. Samples (energy, state, invariants, observables, transforms) become
        one-row columns, drawn by the code :meth:`write_columns` uses; system_info,
        /tf_static and diagnostics apply to what follows them, so what was gathered before
        is drawn first."""
        if type_name not in HANDLED_TYPES:
            return
        self.messages += 1
        base, _, leaf = topic.rpartition("/")
        if type_name == "tf2_msgs/msg/TFMessage":
            latched = leaf == "tf_static"
            if latched:
                self._settle()
            for stamp, columns in _transform_columns(msg):
                stream = self._gather(topic, np.array([stamp], dtype=np.int64), columns)
                if latched:
                    self._draw(stream)
        elif type_name == "diagnostic_msgs/msg/DiagnosticArray":
            if not _ns(msg.header.stamp):  # drawn at the latest sample time: known once drawn
                self._settle()
            self._on_diagnostics(msg)
        elif type_name == "mechsim_msgs/msg/SystemInfo":
            self._settle()
            self._on_info(base.strip("/"), msg)
        else:
            stamp = np.array([_ns(msg.header.stamp)], dtype=np.int64)
            if type_name == "mechsim_msgs/msg/Energy":
                from mechsim.outputs.messages import EnergyColumns

                self._gather(topic, stamp, EnergyColumns(**{
                    name: np.array([float(getattr(msg, name))]) for name in ENERGY_TERMS}))
            elif type_name == "mechsim_msgs/msg/NamedScalars":
                self._gather(topic, stamp, {s.name: np.array([float(s.value)])
                                            for s in msg.scalars})
            elif leaf == "state":  # JointState
                self._gather(topic, stamp, {name: np.array([float(value)]) for name, value
                                            in zip(msg.name, msg.position, strict=False)})
        if self._live_next is not None and time.monotonic() >= self._live_next:
            self._send_live()

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
            self._send_buffered()
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
            import rerun as rr

            _STUCK.append(self.rec)
            with contextlib.suppress(Exception):
                rr.unregister_shutdown()
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
            self._send_buffered()
            self.rec.send_blueprint(self._blueprint(), make_active=True, make_default=True)
            self.rec.flush(timeout_sec=LIVE_FLUSH_TIMEOUT)
        finally:
            with contextlib.suppress(Exception):
                self.rec.disconnect()

    def _send_live(self) -> None:
        """Send every buffered column; the blueprint too once the systems (or the 3D extent
        that places the camera) are first known."""
        self._send_buffered()
        shown = (tuple(st.key for st in self.systems.values()), self.bbox[0] is not None)
        if shown != self._live_blueprint and shown[0]:
            self._live_blueprint = shown
            self.rec.send_blueprint(self._blueprint(), make_active=True, make_default=True)
        self._live_next = time.monotonic() + LIVE_PERIOD

    def _send_buffered(self) -> None:
        """Draw everything gathered and send every entity's buffered columns."""
        self._settle()
        for entity in list(self.series):
            self._flush(entity)

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

    # --- gathering and drawing samples --------------------------------------------------------
    def _gather(self, topic: str, ns: np.ndarray, values: Columns) -> _Stream:
        """Keep a piece of a stream's samples; draw the stream once it holds ``_DRAW_ROWS``.
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
            s = self.streams[key] = _Stream(topic, shape)
        elif s.shape != shape:  # other names or parents: what came before is drawn as it was
            self._draw(s)
            s.shape = shape
        s.ns.append(ns)
        s.values.append(values)
        s.rows += len(ns)
        if s.rows >= _DRAW_ROWS:
            self._draw(s)
        return s

    def _settle(self) -> None:
        """Draw everything gathered."""
        for s in self.streams.values():
            self._draw(s)

    def _draw(self, s: _Stream) -> None:
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
        st = self._system(base.strip("/"))
        t = ns - st.offset_ns
        starts = self._epochs(s, st, t)
        if isinstance(values, dict):
            for name, v in values.items():
                v = np.asarray(v, dtype=np.float64)
                self._scalars(_path("plots", st.ns, leaf, name), t, v)
                if leaf == "invariants":
                    self._draw_drift(st, name, t, v, starts)
        else:
            self._draw_energy(st, t, values, starts)  # type: ignore[arg-type]

    def _epochs(self, s: _Stream, st: _System, t: np.ndarray) -> list[int]:
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

    @staticmethod
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

    def _draw_energy(self, st: _System, t: np.ndarray, e: EnergyColumns,
                     starts: list[int]) -> None:
        for term in ENERGY_TERMS:
            self._scalars(_path("plots", st.ns, "energy", term), t,
                          np.asarray(getattr(e, term), dtype=np.float64))
        balance = np.asarray(_BALANCE.value(energy=e), dtype=np.float64)
        initial, st.balance0 = self._initials(balance, starts, st.balance0)
        self._scalars(_path("plots", st.ns, "balance_residual"), t,
                      _BALANCE.deviation(balance, initial))

    def _draw_drift(self, st: _System, name: str, t: np.ndarray, v: np.ndarray,
                    starts: list[int]) -> None:
        """Drift of invariant ``name``: its law's deviation from the epoch's first value."""
        law = st.laws.get(name) or Law.for_invariant(name)
        initial, st.invariants0[name] = self._initials(v, starts, st.invariants0.get(name))
        self._scalars(_path("plots", st.ns, "drift", name), t, law.deviation(v, initial))

    # --- transforms and shapes in world -------------------------------------------------------
    def _draw_transforms(self, s: _Stream, ns: np.ndarray, tc: TransformColumns) -> None:
        """Transforms of each frame relative to its parent entity; then, per system, its links
        and trail segments between frame origins in world, at every row."""
        values = np.asarray(tc.values, dtype=np.float64)
        columns: dict[str, int] = {}  # frame -> its transform in this block
        systems: dict[str, tuple[_System, np.ndarray, list[int]]] = {}
        for k, (parent_id, child_id) in enumerate(zip(tc.parents, tc.children, strict=True)):
            child = child_id.lstrip("/")
            parent = parent_id.lstrip("/") or "world"
            fr = self._declare_frame(child, parent)
            fr.translation = tuple(float(x) for x in values[-1, k, :3])  # type: ignore[assignment]
            fr.rotation = tuple(float(x) for x in values[-1, k, 3:])  # type: ignore[assignment]
            fr.known = True
            columns[child] = k
            sys_ns = child.partition("/")[0]
            if sys_ns not in systems:
                st = self._system(sys_ns)
                t = ns - st.offset_ns
                starts = self._epochs(s, st, t)
                systems[sys_ns] = (st, t, starts)
            self._append(fr.entity, "transform", systems[sys_ns][1], values[:, k, :])
            if parent == "world":
                self._extend(values[:, k, :3])
        world: dict[str, np.ndarray | None] = {}

        def position(fid: str) -> np.ndarray | None:
            if fid not in world:
                world[fid] = self._world_positions(fid, columns, values)
            return world[fid]

        for st, t, starts in systems.values():
            for entity, a, b in st.links:
                pa, pb = position(a), position(b)
                if pa is None or pb is None:
                    continue
                self._extend(pa)
                self._extend(pb)
                self._append(entity, "strip", t, np.stack([pa, pb], axis=1))
            for entity, fid in st.trails:
                p = position(fid)
                if p is None:
                    if starts:
                        st.last_trail.pop(entity, None)
                    continue
                self._extend(p)
                # Segments from the previous origin (none before an epoch's first sample).
                prev = np.empty_like(p)
                prev[1:] = p[:-1]
                last = None if starts[:1] == [0] else st.last_trail.get(entity)
                prev[0] = p[0] if last is None else last
                prev[starts] = p[starts]
                st.last_trail[entity] = tuple(float(x) for x in p[-1])  # type: ignore[assignment]
                self._append(entity, "strip", t, np.stack([prev, p], axis=1))

    def _world_positions(self, fid: str, columns: dict[str, int],
                         values: np.ndarray) -> np.ndarray | None:
        """Origin of frame ``fid`` in world at each row of a block of transforms (``values``,
        frame -> index ``columns``; a frame not in the block at its latest pose), composed
        along its chain; None until the whole chain has been posed."""
        chain = []
        while fid != "world":
            fr = self.frames.get(fid)
            if fr is None or not (fr.known or fid in columns):
                return None
            chain.append((fid, fr))
            fid = fr.parent
        p: tuple[Any, Any, Any] = (0.0, 0.0, 0.0)
        q: tuple[Any, ...] = (0.0, 0.0, 0.0, 1.0)
        for fid, fr in reversed(chain):
            k = columns.get(fid)
            if k is None:
                translation, rotation = fr.translation, fr.rotation
            else:
                translation = tuple(values[:, k, j] for j in range(3))  # type: ignore[assignment]
                rotation = tuple(values[:, k, j] for j in range(3, 7))  # type: ignore[assignment]
            d = _qrot(q, translation)
            p = (p[0] + d[0], p[1] + d[1], p[2] + d[2])
            q = _qmul(q, rotation)
        out = np.empty((values.shape[0], 3))
        out[:] = np.stack(np.broadcast_arrays(*p), axis=-1)
        return out

    def _extend(self, points: Any) -> None:
        """Grow the bounding box of drawn points (rows of x y z; it places the default 3D
        camera)."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        lo, hi = self.bbox
        if lo is None or hi is None:
            self.bbox = (points.min(axis=0), points.max(axis=0))
        else:
            self.bbox = (np.minimum(lo, points.min(axis=0)), np.maximum(hi, points.max(axis=0)))

    # --- diagnostics --------------------------------------------------------------------------
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
            self._scalars(entity, np.array([t], dtype=np.int64),
                          np.array([level], dtype=np.float64))

    # --- buffering ----------------------------------------------------------------------------
    def _scalars(self, entity: str, t: np.ndarray, values: np.ndarray) -> None:
        """Rows of a scalar entity (anything not finite drawn as NaN)."""
        self._append(entity, "scalar", t, np.where(np.isfinite(values), values, math.nan))

    def _append(self, entity: str, kind: str, t: np.ndarray, values: np.ndarray) -> None:
        s = self.series.get(entity)
        if s is None:
            s = self.series[entity] = _Series(kind)
        s.times.append(t)
        s.values.append(values)
        s.buffered += len(t)
        if s.buffered >= _FLUSH_ROWS:
            self._flush(entity)

    def _flush(self, entity: str) -> None:
        import rerun as rr

        s = self.series[entity]
        if not s.buffered:
            return
        times = np.concatenate(s.times)
        values = np.concatenate(s.values)
        index = [rr.TimeColumn(TIMELINE, duration=times.astype("timedelta64[ns]"))]
        if s.kind == "scalar":
            finite = np.abs(values[np.isfinite(values)])
            if finite.size:
                self.peaks[entity] = max(self.peaks.get(entity, 0.0), float(finite.max()))
            columns: Any = rr.Scalars.columns(scalars=values)
        elif s.kind == "transform":
            columns = rr.Transform3D.columns(translation=values[:, :3].astype(np.float32),
                                             quaternion=values[:, 3:].astype(np.float32))
        else:
            columns = rr.LineStrips3D.columns(strips=values.astype(np.float32))
        self.rec.send_columns(entity, indexes=index, columns=columns)
        s.rows += s.buffered
        s.times, s.values, s.buffered = [], [], 0

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
        self._settle()
        s = self.series.get(entity)
        return 0 if s is None else s.rows + s.buffered


@functools.cache
def _transform_columns_type() -> type:
    from mechsim.outputs.messages import TransformColumns

    return TransformColumns


def _transform_columns(msg: Any) -> list[tuple[int, TransformColumns]]:
    """A TFMessage as one-row transform columns, one per run of transforms with one stamp."""
    from mechsim.outputs.messages import TransformColumns

    runs: list[tuple[int, list[str], list[str], list[list[float]]]] = []
    for tr in msg.transforms:
        stamp = _ns(tr.header.stamp)
        if not runs or runs[-1][0] != stamp:
            runs.append((stamp, [], [], []))
        a, r = tr.transform.translation, tr.transform.rotation
        runs[-1][1].append(tr.header.frame_id)
        runs[-1][2].append(tr.child_frame_id)
        runs[-1][3].append([a.x, a.y, a.z, r.x, r.y, r.z, r.w])
    return [(stamp, TransformColumns(parents, children, np.array([rows], dtype=np.float64)))
            for stamp, parents, children, rows in runs]


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
