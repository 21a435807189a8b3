"""Samples of a run turned into standard ROS messages (and back): the one place message fields
are filled, used by the simulator node, the recorder and the Rerun converter alike."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import yaml
from builtin_interfaces.msg import Time
from geometry_msgs.msg import TransformStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Header

from mechsim import __version__
from mechsim.systems.base import Model
from mechsim_msgs.msg import Energy, NamedScalars, SystemInfo
from tf2_msgs.msg import TFMessage

#: Simulation time t = 0 is stamped this many seconds: /clock never starts at 0 (a zero ROS
#: time means "uninitialised" to rclcpp, rosbag2 and tf2).
DEFAULT_TIME_OFFSET = 1.0


def stamp_ns(t: float, offset: float) -> int:
    return int(round((t + offset) * 1e9))


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
        self.invariant_names = [q.name for q in model.invariants]
        self.invariant_units = [q.unit for q in model.invariants]
        self.observable_names = [q.name for q in model.observables]
        self.observable_units = [q.unit for q in model.observables]

    def frame_id(self, frame: str) -> str:
        return "world" if frame == "world" else f"{self.name}/{frame}"

    def header(self, ns: int, frame: str = "world") -> Header:
        return Header(stamp=to_time(ns), frame_id=frame)

    def state(self, s: Sample, ns: int) -> JointState:
        return JointState(header=self.header(ns, self.frame_id(self._root_frame())),
                          name=list(self.coordinate_names), position=s.q.tolist(),
                          velocity=s.v.tolist(), effort=[])

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
        return NamedScalars(header=self.header(ns), names=list(self.invariant_names),
                            units=list(self.invariant_units),
                            values=[float(x) for x in s.invariants])

    def observables(self, s: Sample, ns: int) -> NamedScalars:
        assert s.observables is not None
        return NamedScalars(header=self.header(ns), names=list(self.observable_names),
                            units=list(self.observable_units),
                            values=[float(x) for x in s.observables])

    def transforms(self, frames: np.ndarray, ns: int, static: bool) -> list[TransformStamped]:
        out = []
        for k, spec in enumerate(self.model.frames):
            if spec.static != static:
                continue
            x, y, z, qx, qy, qz, qw = (float(c) for c in frames[k])
            if spec.parent == "world":
                x, y, z = x + self.origin[0], y + self.origin[1], z + self.origin[2]
            norm = (qx * qx + qy * qy + qz * qz + qw * qw) ** 0.5 or 1.0
            t = TransformStamped()
            t.header = self.header(ns, self.frame_id(spec.parent))
            t.child_frame_id = self.frame_id(spec.child)
            t.transform.translation.x, t.transform.translation.y = x, y
            t.transform.translation.z = z
            t.transform.rotation.x, t.transform.rotation.y = qx / norm, qy / norm
            t.transform.rotation.z, t.transform.rotation.w = qz / norm, qw / norm
            out.append(t)
        return out

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
            formulation=m.formulation, source=m.source,
            coordinates=list(self.coordinate_names),
            coordinate_units=[c.unit for c in m.coordinates],
            parameters_yaml=yaml.safe_dump(params, sort_keys=True, allow_unicode=True),
            integrator=integrator, tolerance=float(tolerance), laws=list(laws),
            law_scales=[float(x) for x in scales], mechsim_version=__version__)


def clock(ns: int) -> Clock:
    return Clock(clock=to_time(ns))
