"""The diagnostics node: checks every system's conservation laws live, on /diagnostics.

It discovers systems by their ``<ns>/system_info`` topics (any process), learns from each which
laws hold (energy, energy function h, work balance, invariants, constraints) and their scales,
and follows ``<ns>/energy`` and ``<ns>/invariants``. One DiagnosticStatus per law per system,
named ``mechsim/<ns>/<law>``, hardware_id ``<ns>``; level from the relative drift against the
``warn_drift`` / ``error_drift`` parameters (the worst drift seen so far sets the level, so an
ERROR stays visible); a system silent for ``stale_timeout`` wall seconds is STALE. Published
every ``period`` seconds of wall time, and on demand with :meth:`publish_now`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from rclpy.context import Context
from rclpy.node import Node
from rclpy.qos import QoSProfile
from std_msgs.msg import Header

from mechsim.outputs.sink import Sink
from mechsim.ros.outlet import DIAGNOSTICS_QOS, LATCHED_QOS, Outlet
from mechsim_msgs.msg import Energy, NamedScalars, SystemInfo

LEVEL_NAMES = {0: "OK", 1: "WARN", 2: "ERROR", 3: "STALE"}
_SUB_QOS = QoSProfile(depth=1000)


@dataclass
class LawState:
    key: str
    scale: float
    initial: float | None = None
    current: float = 0.0
    drift: float = 0.0
    max_drift: float = 0.0
    samples: int = 0


@dataclass
class SystemState:
    name: str
    info: SystemInfo
    laws: dict[str, LawState] = field(default_factory=dict)
    last_seen: float = field(default_factory=time.monotonic)
    last_stamp: Header | None = None


def relative_drift(law: LawState, value: float, is_constraint: bool = False) -> float:
    if is_constraint:
        return abs(value) / law.scale
    assert law.initial is not None
    return abs(value - law.initial) / law.scale


class DiagnosticsNode(Node):
    def __init__(self, *, context: Context | None = None, warn_drift: float = 1e-6,
                 error_drift: float = 1e-3, period: float = 1.0, stale_timeout: float = 5.0,
                 sinks: list[Sink] | None = None, discover: bool = True) -> None:
        """``discover=False``: follow only systems fed to it in-process (scene runner)."""
        super().__init__("diagnostics", namespace="mechsim", context=context)
        rng = [FloatingPointRange(from_value=0.0, to_value=1.0)]
        self.declare_parameter("warn_drift", float(warn_drift), ParameterDescriptor(
            description="relative drift of a conservation law that gives WARN",
            floating_point_range=rng))
        self.declare_parameter("error_drift", float(error_drift), ParameterDescriptor(
            description="relative drift of a conservation law that gives ERROR",
            floating_point_range=rng))
        self.declare_parameter("period", float(period), ParameterDescriptor(
            description="publication period of /diagnostics [s, wall time]",
            floating_point_range=[FloatingPointRange(from_value=0.01, to_value=86400.0)]))
        self.declare_parameter("stale_timeout", float(stale_timeout), ParameterDescriptor(
            description="a system silent this long (wall time) is STALE [s]",
            floating_point_range=[FloatingPointRange(from_value=0.1, to_value=3600.0)]))
        self.add_on_set_parameters_callback(self._check_thresholds)
        self.systems: dict[str, SystemState] = {}
        self._subs: dict[str, list] = {}
        self.outlet = Outlet(self, sinks)
        self.t_diag = self.outlet.channel("/diagnostics", DiagnosticArray, DIAGNOSTICS_QOS)
        self.published = 0
        if discover:
            self._discover()
            self.create_timer(0.5, self._discover)
        self.create_timer(period, self.publish_now)

    def _check_thresholds(self, params: list) -> SetParametersResult:
        warn = self.get_parameter("warn_drift").value
        err = self.get_parameter("error_drift").value
        for p in params:
            if p.name == "warn_drift":
                warn = p.value
            if p.name == "error_drift":
                err = p.value
        if warn >= err:
            return SetParametersResult(successful=False,
                                       reason="warn_drift must be smaller than error_drift")
        return SetParametersResult(successful=True)

    # --- discovery ------------------------------------------------------------------------
    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic.endswith("/system_info") and "mechsim_msgs/msg/SystemInfo" in types:
                ns = topic[: -len("/system_info")]
                if ns not in self._subs:
                    self.watch(ns)

    def watch(self, ns: str) -> None:
        """Follow the system whose topics live under namespace ``ns`` (e.g. "/pendulum")."""
        if ns in self._subs:
            return
        self._subs[ns] = [
            self.create_subscription(SystemInfo, f"{ns}/system_info",
                                     lambda m, ns=ns: self._on_info(ns, m), LATCHED_QOS),
            self.create_subscription(Energy, f"{ns}/energy",
                                     lambda m, ns=ns: self._on_energy(ns, m), _SUB_QOS),
            self.create_subscription(NamedScalars, f"{ns}/invariants",
                                     lambda m, ns=ns: self._on_invariants(ns, m), _SUB_QOS),
        ]

    def _on_info(self, ns: str, info: SystemInfo) -> None:
        old = self.systems.get(ns)
        same = old is not None and list(old.info.laws) == list(info.laws) and \
            old.info.parameters_yaml == info.parameters_yaml
        if same:
            return
        st = SystemState(info.instance or ns.strip("/"), info)
        for key, scale in zip(info.laws, info.law_scales, strict=False):
            st.laws[key] = LawState(key, scale if scale > 0 else 1.0)
        self.systems[ns] = st

    def _update(self, st: SystemState, key: str, value: float) -> None:
        law = st.laws.get(key)
        if law is None:
            return
        is_constraint = key.startswith("constraint:")
        if law.initial is None:
            law.initial = value
        law.current = value
        law.drift = relative_drift(law, value, is_constraint) if math.isfinite(value) else \
            math.inf
        law.max_drift = max(law.max_drift, law.drift)
        law.samples += 1

    def _on_energy(self, ns: str, m: Energy) -> None:
        st = self.systems.get(ns)
        if st is None:
            return
        st.last_seen = time.monotonic()
        st.last_stamp = m.header
        self._update(st, "energy", m.total)
        self._update(st, "energy_function", m.energy_function)
        # Balance: total − total₀ − (W_ext − W_diss); its "initial" is total₀ at W = 0.
        self._update(st, "work_balance", m.total - (m.work_external - m.work_dissipated))

    def _on_invariants(self, ns: str, m: NamedScalars) -> None:
        st = self.systems.get(ns)
        if st is None:
            return
        st.last_seen = time.monotonic()
        for name, value in zip(m.names, m.values, strict=False):
            key = f"constraint:{name}" if name.startswith("constraint_") else f"invariant:{name}"
            self._update(st, key, value)

    # --- output ---------------------------------------------------------------------------
    def level(self, law: LawState, stale: bool) -> int:
        if law.samples == 0 or stale:
            return 3
        if not math.isfinite(law.max_drift):
            return 2
        if law.max_drift >= self.get_parameter("error_drift").value:
            return 2
        if law.max_drift >= self.get_parameter("warn_drift").value:
            return 1
        return 0

    def statuses(self) -> list[DiagnosticStatus]:
        out = []
        timeout = self.get_parameter("stale_timeout").value
        now = time.monotonic()
        for st in self.systems.values():
            stale = now - st.last_seen > timeout
            for key, law in st.laws.items():
                level = self.level(law, stale)
                if law.samples == 0:
                    text = "no samples yet"
                elif stale:
                    text = f"stale: no data for {now - st.last_seen:.1f} s"
                else:
                    text = (f"{LEVEL_NAMES[level]}: relative drift {law.drift:.3g}, "
                            f"max {law.max_drift:.3g}")
                label = key.replace(":", "/")
                out.append(DiagnosticStatus(
                    level=bytes([level]), name=f"mechsim/{st.name}/{label}", message=text,
                    hardware_id=st.name, values=[
                        KeyValue(key="drift", value=f"{law.drift:.6e}"),
                        KeyValue(key="max_drift", value=f"{law.max_drift:.6e}"),
                        KeyValue(key="initial", value=f"{law.initial!r}"),
                        KeyValue(key="current", value=f"{law.current!r}"),
                        KeyValue(key="scale", value=f"{law.scale!r}"),
                        KeyValue(key="samples", value=str(law.samples)),
                        KeyValue(key="system", value=st.info.system),
                        KeyValue(key="integrator", value=st.info.integrator)]))
        return out

    def publish_now(self) -> None:
        if not self.systems:
            return
        last = max((s.last_stamp for s in self.systems.values() if s.last_stamp is not None),
                   key=lambda h: (h.stamp.sec, h.stamp.nanosec), default=None)
        header = Header(frame_id="")
        if last is not None:
            header.stamp = last.stamp
        msg = DiagnosticArray(header=header, status=self.statuses())
        ns = header.stamp.sec * 1_000_000_000 + header.stamp.nanosec
        self.outlet.publish(self.t_diag, msg, ns)
        self.published += 1

    def summary(self) -> list[tuple[str, str, float, int]]:
        """(system, law, max relative drift, level) for every law, for tables."""
        rows = []
        for st in self.systems.values():
            for key, law in st.laws.items():
                rows.append((st.name, key, law.max_drift, self.level(law, False)))
        return rows
