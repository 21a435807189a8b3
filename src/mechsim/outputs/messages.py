"""Samples of a run turned into standard ROS messages (and back): the one place message fields
are filled, used by the simulator node, the recorder and the Rerun converter alike.

Coordinates go to ``sensor_msgs/JointState`` only when they are joint-like (angles in rad,
lengths in m, ...); a quaternion attitude (``Model.attitude``) is published instead as
``geometry_msgs/PoseStamped`` (orientation of the attitude frame in "world") and
``geometry_msgs/TwistStamped`` (its angular velocity in rad/s, in body axes: header.frame_id
is the attitude frame itself, as REP-103 asks a twist to state its frame; linear velocity
zero, the frame's origin being fixed). Invariants and observables are ``NamedScalars``: one
(name, value, unit) record per quantity, so that plotting tools select them by name."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import yaml
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, PoseStamped, TransformStamped, TwistStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Header
from visualization_msgs.msg import Marker, MarkerArray

from mechsim import __version__
from mechsim.systems.base import Model
from mechsim_msgs.msg import Energy, NamedScalar, NamedScalars, SystemInfo
from tf2_msgs.msg import TFMessage

#: Simulation time t = 0 is stamped this many seconds: /clock never starts at 0 (a zero ROS
#: time means "uninitialised" to rclcpp, rosbag2 and tf2).
DEFAULT_TIME_OFFSET = 1.0


def stamps_ns(t: np.ndarray, offset: float) -> np.ndarray:
    """Stamps (int64 nanoseconds, rounded half to even) of simulation times ``t``."""
    return np.rint((np.asarray(t, dtype=float) + offset) * 1e9).astype(np.int64)


def stamp_ns(t: float, offset: float) -> int:
    return int(stamps_ns(np.array([t]), offset)[0])


def to_time(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


@dataclass
class Sample:
    """Everything a system publishes at one instant (None where nobody asked for it)."""

    t: float
    q: np.ndarray
    v: np.ndarray
    work_external: float
    work_dissipated: float
    energy: np.ndarray | None = None  # kinetic, potential, energy_function
    invariants: np.ndarray | None = None
    observables: np.ndarray | None = None
    frames: np.ndarray | None = None  # (n_frames, 7)


class MessageFactory:
    """Builds the messages of one system instance (namespace ``name``)."""

    def __init__(self, model: Model, name: str, origin: tuple[float, float, float] = (0, 0, 0),
                 time_offset: float = DEFAULT_TIME_OFFSET) -> None:
        self.model = model
        self.name = name
        self.origin = origin
        self.time_offset = time_offset
        self.coordinate_names = [c.name for c in model.coordinates]
        self.attitude = model.attitude
        quaternion = set(self.attitude.quaternion) if self.attitude else set()
        #: Indices of the joint-like coordinates (the ones JointState carries).
        self.joints = [i for i in range(len(model.coordinates)) if i not in quaternion]
        self.invariant_names = [q.name for q in model.invariants]
        self.invariant_units = [q.unit for q in model.invariants]
        self.observable_names = [q.name for q in model.observables]
        self.observable_units = [q.unit for q in model.observables]
        #: The frames whose parent is the world (moved by the origin), and the others.
        self._world = [k for k, f in enumerate(model.frames) if f.parent == "world"]
        self._origin = np.asarray(origin, dtype=float)

    def frame_id(self, frame: str) -> str:
        return "world" if frame == "world" else f"{self.name}/{frame}"

    def header(self, ns: int, frame: str = "world") -> Header:
        return Header(stamp=to_time(ns), frame_id=frame)

    def curves(self, ns: int) -> MarkerArray:
        """The model's curves (``Model.curves``) as line strips in the plane z = 0 of a
        diagram, points (abscissa, ordinate, 0) in the units the marker's ``text`` names
        ("U_eff [J] against r [m]"), ``ns`` "<instance>/<curve>": id 0 the curve, id k its
        k-th level as a horizontal line over the curve's range, ``text`` "E = <value> [J]"
        and the abscissae where the curve meets it."""
        markers = []
        for curve in self.model.curves():
            x, y = np.asarray(curve.x, dtype=float), np.asarray(curve.y, dtype=float)
            keep = np.isfinite(x) & np.isfinite(y)
            lines = [(f"{curve.y_label} [{curve.y_unit}] against {curve.x_label} "
                      f"[{curve.x_unit}]", x[keep], y[keep], (0.2, 0.6, 1.0))]
            for level in curve.levels:
                at = ", ".join(f"{c:.6g}" for c in level.crossings)
                lines.append((f"{level.label} = {level.value:.9g} [{curve.y_unit}]"
                              + (f" at {curve.x_label} = {at} [{curve.x_unit}]" if at else ""),
                              x[keep][[0, -1]] if keep.any() else x[:0],
                              np.full(2 if keep.any() else 0, level.value), (1.0, 0.5, 0.1)))
            for k, (text, xs, ys, rgb) in enumerate(lines):
                m = Marker(header=self.header(ns), ns=f"{self.name}/{curve.name}", id=k,
                           type=Marker.LINE_STRIP, action=Marker.ADD, text=text,
                           points=[Point(x=float(a), y=float(b), z=0.0)
                                   for a, b in zip(xs, ys, strict=True)])
                m.pose.orientation.w = 1.0
                m.scale.x = 0.01
                m.color.r, m.color.g, m.color.b, m.color.a = (*rgb, 1.0)
                markers.append(m)
        return MarkerArray(markers=markers)

    def state(self, s: Sample, ns: int) -> JointState:
        j = self.joints
        return JointState(header=self.header(ns, self.frame_id(self._root_frame())),
                          name=[self.coordinate_names[i] for i in j],
                          position=s.q[j].tolist(), velocity=s.v[j].tolist(), effort=[])

    def pose(self, s: Sample, ns: int) -> PoseStamped:
        """The attitude frame's pose in "world" (origin moved by the instance's origin)."""
        assert self.attitude is not None
        m = PoseStamped(header=self.header(ns))
        x, y, z = (float(c) for c in self.origin)
        m.pose.position.x, m.pose.position.y, m.pose.position.z = x, y, z
        qx, qy, qz, qw = (float(c) for c in self.attitude.orientation(s.q))
        o = m.pose.orientation
        o.x, o.y, o.z, o.w = qx, qy, qz, qw
        return m

    def twist(self, s: Sample, ns: int) -> TwistStamped:
        """The attitude frame's angular velocity (rad/s) in its own axes."""
        assert self.attitude is not None
        m = TwistStamped(header=self.header(ns, self.frame_id(self.attitude.frame)))
        wx, wy, wz = (float(c) for c in self.attitude.angular_velocity(s.q, s.v))
        m.twist.angular.x, m.twist.angular.y, m.twist.angular.z = wx, wy, wz
        return m

    def _root_frame(self) -> str:
        for f in self.model.frames:
            if f.parent == "world":
                return f.child
        return "world"

    def energy(self, s: Sample, ns: int) -> Energy:
        assert s.energy is not None
        T, V, h = (float(x) for x in s.energy)
        return Energy(header=self.header(ns), kinetic=T, potential=V, total=T + V,
                      energy_function=h, work_external=float(s.work_external),
                      work_dissipated=float(s.work_dissipated))

    def invariants(self, s: Sample, ns: int) -> NamedScalars:
        assert s.invariants is not None
        return self._named(ns, self.invariant_names, self.invariant_units, s.invariants)

    def observables(self, s: Sample, ns: int) -> NamedScalars:
        assert s.observables is not None
        return self._named(ns, self.observable_names, self.observable_units, s.observables)

    def _named(self, ns: int, names: list[str], units: list[str],
               values: np.ndarray) -> NamedScalars:
        return NamedScalars(header=self.header(ns), scalars=[
            NamedScalar(name=n, value=float(v), unit=u)
            for n, u, v in zip(names, units, values, strict=True)])

    def placed(self, frames: np.ndarray) -> np.ndarray:
        """Frames as published, for one sample (frames, 7) or many (samples, frames, 7):
        frames whose parent is the world moved by the instance's origin, quaternions
        normalised (a zero quaternion left as it is)."""
        out = np.array(frames, dtype=float)
        out[..., self._world, :3] += self._origin
        x, y, z, w = (out[..., k] for k in range(3, 7))
        norm = np.sqrt(x * x + y * y + z * z + w * w)  # (summed in np.sum's order)
        norm[norm == 0.0] = 1.0
        out[..., 3:] /= norm[..., None]
        return out

    def transforms(self, frames: np.ndarray, ns: int, static: bool) -> list[TransformStamped]:
        out = []
        placed = self.placed(frames)
        for k, spec in enumerate(self.model.frames):
            if spec.static != static:
                continue
            x, y, z, qx, qy, qz, qw = (float(c) for c in placed[k])
            t = TransformStamped()
            t.header = self.header(ns, self.frame_id(spec.parent))
            t.child_frame_id = self.frame_id(spec.child)
            t.transform.translation.x, t.transform.translation.y = x, y
            t.transform.translation.z = z
            t.transform.rotation.x, t.transform.rotation.y = qx, qy
            t.transform.rotation.z, t.transform.rotation.w = qz, qw
            out.append(t)
        return out

    def transform_columns(self, frames: np.ndarray,
                          placed: np.ndarray | None = None) -> TransformColumns:
        """The /tf transforms of a chunk (``frames``: (samples, frames, 7) as the model
        computes them; ``placed``: ``placed(frames)`` if already made)."""
        dynamic = [spec for spec in self.model.frames if not spec.static]
        keep = [k for k, spec in enumerate(self.model.frames) if not spec.static]
        placed = self.placed(frames) if placed is None else placed
        return TransformColumns([self.frame_id(f.parent) for f in dynamic],
                                [self.frame_id(f.child) for f in dynamic], placed[:, keep, :])

    def tf(self, s: Sample, ns: int) -> TFMessage:
        assert s.frames is not None
        return TFMessage(transforms=self.transforms(s.frames, ns, static=False))

    def system_info(self, ns: int, integrator: str, tolerance: float,
                    laws: list[str], scales: list[float]) -> SystemInfo:
        m = self.model
        params = {k: (float(v) if isinstance(v, int) and not isinstance(v, bool) else v)
                  for k, v in m.values.items()}
        return SystemInfo(
            header=self.header(ns), instance=self.name, system=m.id,
            formulation=m.chosen_formulation, source=m.source,
            coordinates=list(self.coordinate_names),
            coordinate_units=[c.unit for c in m.coordinates],
            parameters_yaml=yaml.safe_dump(params, sort_keys=True, allow_unicode=True),
            integrator=integrator, tolerance=float(tolerance), laws=list(laws),
            law_scales=[float(x) for x in scales], mechsim_version=__version__)


def clock(ns: int) -> Clock:
    return Clock(clock=to_time(ns))


@dataclass
class Chunk:
    """Consecutive samples of one system: row i of every array is sample i (arrays None where
    nobody asked for them)."""

    ns: np.ndarray  # int64 stamps
    q: np.ndarray  # (N, n)
    v: np.ndarray  # (N, n)
    work: np.ndarray  # (N, 2): work_external, work_dissipated
    energy: np.ndarray | None = None  # (N, 3): kinetic, potential, energy_function
    invariants: np.ndarray | None = None  # (N, invariants)
    observables: np.ndarray | None = None  # (N, observables)
    frames: np.ndarray | None = None  # (N, frames, 7), as the model computes them
    #: ``frames`` as published (``MessageFactory.placed``), made once for the chunk's /tf
    #: rows and columns (see :meth:`placed_frames`).
    placed: np.ndarray | None = None
    _time_rows: np.ndarray | None = field(default=None, init=False, repr=False)

    def time_rows(self) -> np.ndarray:
        """The Time fields of the chunk's stamps (``wire.time_rows``), made once for all its
        topics."""
        if self._time_rows is None:
            from mechsim.outputs.wire import time_rows

            self._time_rows = time_rows(self.ns)
        return self._time_rows

    def placed_frames(self, factory: MessageFactory) -> np.ndarray:
        """The chunk's frames as ``factory`` publishes them (made at the first call)."""
        assert self.frames is not None
        if self.placed is None:
            self.placed = factory.placed(self.frames)
        return self.placed


@dataclass
class EnergyColumns:
    """The Energy fields of a chunk, one array each (what an energy ``Law`` reads)."""

    kinetic: np.ndarray
    potential: np.ndarray
    total: np.ndarray
    energy_function: np.ndarray
    work_external: np.ndarray
    work_dissipated: np.ndarray

    @classmethod
    def of(cls, c: Chunk) -> EnergyColumns:
        assert c.energy is not None
        e = c.energy
        return cls(e[:, 0], e[:, 1], e[:, 0] + e[:, 1], e[:, 2], c.work[:, 0], c.work[:, 1])

    def rows(self, rows: slice) -> EnergyColumns:
        return EnergyColumns(self.kinetic[rows], self.potential[rows], self.total[rows],
                             self.energy_function[rows], self.work_external[rows],
                             self.work_dissipated[rows])


@dataclass
class TransformColumns:
    """The /tf transforms of a chunk: frame ids as in the messages, and ``values[i, k]`` =
    (x, y, z, qx, qy, qz, qw) of transform k at sample i, as published (placed)."""

    parents: list[str]
    children: list[str]
    values: np.ndarray  # (N, transforms, 7)

    def rows(self, rows: slice) -> TransformColumns:
        return TransformColumns(self.parents, self.children, self.values[rows])


#: What a sink's ``write_columns`` gets per topic: Energy fields (``EnergyColumns``), /tf
#: (``TransformColumns``), or name -> values for JointState positions and NamedScalars.
Columns = EnergyColumns | TransformColumns | dict[str, np.ndarray]


def column_rows(values: Columns, rows: slice) -> Columns:
    """Rows of a chunk's evaluated values."""
    if isinstance(values, dict):
        return {k: v[rows] for k, v in values.items()}
    return values.rows(rows)


def joined_columns(parts: list[Columns]) -> Columns:
    """Consecutive pieces of a chunk's evaluated values as one (see ``column_rows``)."""
    if len(parts) == 1:
        return parts[0]
    first = parts[0]
    if isinstance(first, dict):
        return {k: np.concatenate([p[k] for p in parts]) for k in first}  # type: ignore[index]
    if isinstance(first, TransformColumns):
        return TransformColumns(first.parents, first.children,
                                np.concatenate([p.values for p in parts]))  # type: ignore[union-attr]
    return EnergyColumns(*(np.concatenate([getattr(p, f) for p in parts])
                           for f in ("kinetic", "potential", "total", "energy_function",
                                     "work_external", "work_dissipated")))


class ChunkEncoder:
    """The CDR payloads of a chunk, per topic, as :class:`MessageFactory` would fill the
    messages (see ``mechsim.outputs.wire.rows``): the layouts are made once from the factory's
    own messages of a prototype sample, then only numbers and stamps change."""

    def __init__(self, factory: MessageFactory) -> None:
        from mechsim.outputs.wire import Layout

        self.factory = f = factory
        m = f.model
        n = len(m.coordinates)
        q0 = np.zeros(n)
        if f.attitude is not None:
            q0[f.attitude.quaternion[3]] = 1.0  # a unit quaternion for the prototype
        s = Sample(0.0, q0, np.zeros(n), 0.0, 0.0, np.zeros(3),
                   np.zeros(len(m.invariants)), np.zeros(len(m.observables)),
                   np.tile([0.0, 0, 0, 0, 0, 0, 1], (len(m.frames), 1)))
        self.state = Layout("sensor_msgs/msg/JointState", f.state(s, 0))
        self.q = self.state.block([f"position.{i}" for i in range(len(f.joints))])
        self.v = self.state.block([f"velocity.{i}" for i in range(len(f.joints))])
        if f.attitude is not None:
            self.pose = Layout("geometry_msgs/msg/PoseStamped", f.pose(s, 0))
            self.orientation = self.pose.block(
                [f"pose.orientation.{c}" for c in ("x", "y", "z", "w")])
            self.twist = Layout("geometry_msgs/msg/TwistStamped", f.twist(s, 0))
            self.angular = self.twist.block([f"twist.angular.{c}" for c in ("x", "y", "z")])
        self.energy = Layout("mechsim_msgs/msg/Energy", f.energy(s, 0))
        self.energy_terms = self.energy.block(
            ["kinetic", "potential", "total", "energy_function", "work_external",
             "work_dissipated"])
        self.invariants = Layout("mechsim_msgs/msg/NamedScalars", f.invariants(s, 0))
        self.invariant_values = self.invariants.block(
            [f"scalars.{i}.value" for i in range(len(m.invariants))])
        self.observables = Layout("mechsim_msgs/msg/NamedScalars", f.observables(s, 0))
        self.observable_values = self.observables.block(
            [f"scalars.{i}.value" for i in range(len(m.observables))])
        self.dynamic = [k for k, fr in enumerate(m.frames) if not fr.static]
        self.tf = Layout("tf2_msgs/msg/TFMessage", f.tf(s, 0))
        self.tf_values = self.tf.block(
            [f"transforms.{j}.transform.{part}.{c}" for j in range(len(self.dynamic))
             for part, c in [("translation", "x"), ("translation", "y"),
                             ("translation", "z"), ("rotation", "x"), ("rotation", "y"),
                             ("rotation", "z"), ("rotation", "w")]])
        self.clock = Layout("rosgraph_msgs/msg/Clock", clock(0))

    def encode(self, topic: str, c: Chunk) -> np.ndarray:
        """(N, size) bytes of ``topic`` ("state", "pose", "twist", "energy", "invariants",
        "observables", "tf", "clock") for the chunk ("pose" and "twist" only for a model
        with an attitude)."""
        j = self.factory.joints
        # The Time fields made once for all the topics (one sample: packed with struct).
        times = c.time_rows() if c.ns.shape[0] > 1 else None
        if topic == "state":
            return self.state.encode(c.ns, [(self.q, c.q[:, j]), (self.v, c.v[:, j])],
                                     times)
        if topic == "pose":
            a = self.factory.attitude
            assert a is not None
            return self.pose.encode(c.ns, [(self.orientation, a.orientation(c.q))],
                                    times)
        if topic == "twist":
            a = self.factory.attitude
            assert a is not None
            return self.twist.encode(c.ns, [(self.angular, a.angular_velocity(c.q, c.v))],
                                     times)
        if topic == "energy":
            assert c.energy is not None
            e = EnergyColumns.of(c)
            terms = np.column_stack([e.kinetic, e.potential, e.total, e.energy_function,
                                     e.work_external, e.work_dissipated])
            return self.energy.encode(c.ns, [(self.energy_terms, terms)], times)
        if topic == "invariants":
            assert c.invariants is not None
            return self.invariants.encode(c.ns, [(self.invariant_values, c.invariants)],
                                          times)
        if topic == "observables":
            assert c.observables is not None
            return self.observables.encode(c.ns, [(self.observable_values, c.observables)],
                                           times)
        if topic == "tf":
            assert c.frames is not None
            placed = c.placed_frames(self.factory)[:, self.dynamic, :]
            return self.tf.encode(c.ns, [(self.tf_values, placed.reshape(len(c.ns), -1))],
                                  times)
        if topic == "clock":
            return self.clock.encode(c.ns, (), times)
        raise KeyError(topic)
