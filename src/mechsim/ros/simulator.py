"""The simulator node: one system instance, one node (namespace = instance name).

Topics (stamped with simulation time + ``time_offset``, so /clock never starts at 0):
  <ns>/state        sensor_msgs/JointState   coordinates and their rates
  <ns>/energy       mechsim_msgs/Energy      T, V, T+V, h, work_external, work_dissipated
  <ns>/invariants   mechsim_msgs/NamedScalars   conserved quantities and constraint residuals
  <ns>/observables  mechsim_msgs/NamedScalars   constraint forces, multipliers, ...
  <ns>/system_info  mechsim_msgs/SystemInfo  (transient local) what runs and which laws hold
  /tf, /tf_static   tf2_msgs/TFMessage       frames <ns>/<frame>, root "world"
  /clock            rosgraph_msgs/Clock      only when this node owns the clock
  /diagnostics      diagnostic_msgs/DiagnosticArray  only if integration fails
Parameters: every model parameter (same names as scenes and --set), plus method, tolerance,
publish_rate, real_time_factor (0: stepped by the caller, as fast as possible), and
constraint_limit (hard limit on enforced constraint residuals, relative to max(1, max|q|)).
Guards: a non-finite state, a failed step or an enforced constraint residual past the hard
limit stops this system only (``_fail``): last good state kept, ERROR on /diagnostics.
Services: ~/reset (std_srvs/Trigger), ~/pause (std_srvs/SetBool).
Energy, invariants, observables and frames are computed only while something consumes them.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (
    FloatingPointRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.clock import Clock, ClockType
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter as RosParameter
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_srvs.srv import SetBool, Trigger

from mechsim.errors import IntegrationError, MechsimError, ParameterError
from mechsim.integrators import METHODS, Stepper, make_stepper
from mechsim.outputs import messages
from mechsim.outputs.messages import MessageFactory, Sample
from mechsim.outputs.sink import Sink
from mechsim.params import Parameter
from mechsim.ros.outlet import (
    CLOCK_QOS,
    DIAGNOSTICS_QOS,
    LATCHED_QOS,
    STATE_QOS,
    TF_QOS,
    Outlet,
)
from mechsim.scene import Instance
from mechsim.systems import system_class
from mechsim.systems.base import Model
from mechsim_msgs.msg import Energy, NamedScalars, SystemInfo
from tf2_msgs.msg import TFMessage

_NODE_PARAMS = ("method", "tolerance", "publish_rate", "real_time_factor", "constraint_limit")
# Projection keeps enforced constraint residuals at round-off, diagnostics says ERROR at
# 1e-3: a residual of 1 % of the configuration's size means the state is garbage.
CONSTRAINT_LIMIT = 1e-2


def _descriptor(p: Parameter) -> ParameterDescriptor:
    text = p.description + (f" [{p.unit}]" if p.unit else "")
    if p.choices:
        text += f" (one of: {', '.join(p.choices)})"
    d = ParameterDescriptor(description=text)
    if p.kind is float and p.minimum is not None and p.maximum is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(p.minimum),
                                                     to_value=float(p.maximum), step=0.0)]
    return d


class SimulatorNode(Node):
    def __init__(self, instance: Instance, *, context: Context | None = None,
                 publish_rate: float = 100.0, real_time_factor: float = 1.0,
                 publish_clock: bool = False, sinks: list[Sink] | None = None,
                 time_offset: float = messages.DEFAULT_TIME_OFFSET,
                 constraint_limit: float = CONSTRAINT_LIMIT) -> None:
        super().__init__("simulator", namespace=instance.name, context=context)
        self.instance = instance
        self.cls: type[Model] = system_class(instance.system)
        self.spec = {p.name: p for p in self.cls.parameter_spec()}
        self.values: dict[str, Any] = dict(self.cls(**instance.parameters).values)
        self.method = instance.method
        self.tolerance = instance.tolerance
        self.publish_rate = publish_rate
        self.real_time_factor = real_time_factor
        self.publish_clock = publish_clock
        self.time_offset = time_offset
        self.constraint_limit = float(constraint_limit)
        self.failed: str | None = None
        self.paused = False
        self.samples_published = 0
        self.computed = {"energy": 0, "invariants": 0, "observables": 0, "frames": 0}

        self.declare_parameter("system", instance.system, ParameterDescriptor(
            description="system id (see `mechsim systems`)", read_only=True))
        for name, p in self.spec.items():
            self.declare_parameter(name, self.values[name], _descriptor(p))
        self.declare_parameter("method", self.method, ParameterDescriptor(
            description=f"integrator ({', '.join(METHODS)})"))
        self.declare_parameter("tolerance", float(self.tolerance), ParameterDescriptor(
            description="integrator tolerance (relative and absolute)",
            floating_point_range=[FloatingPointRange(from_value=1e-15, to_value=0.99)]))
        self.declare_parameter("publish_rate", float(publish_rate), ParameterDescriptor(
            description="samples per second of simulation time [Hz]",
            floating_point_range=[FloatingPointRange(from_value=0.01, to_value=10000.0)]))
        self.declare_parameter("real_time_factor", float(real_time_factor), ParameterDescriptor(
            description="simulated seconds per wall second; 0 = stepped by the caller",
            floating_point_range=[FloatingPointRange(from_value=0.0, to_value=1e6)]))
        self.declare_parameter("time_offset", float(time_offset), ParameterDescriptor(
            description="stamp of simulation time 0 [s] (ROS time 0 means uninitialised)",
            read_only=True))
        self.declare_parameter("constraint_limit", self.constraint_limit, ParameterDescriptor(
            description="hard limit on an enforced constraint residual, relative to "
            "max(1, max|q|); past it the system stops",
            floating_point_range=[FloatingPointRange(from_value=1e-12, to_value=1e6)]))
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)

        self.outlet = Outlet(self, sinks)
        o = self.outlet
        self.t_state = o.channel("state", JointState, STATE_QOS)
        self.t_energy = o.channel("energy", Energy, STATE_QOS)
        self.t_inv = o.channel("invariants", NamedScalars, STATE_QOS)
        self.t_obs = o.channel("observables", NamedScalars, STATE_QOS)
        self.t_info = o.channel("system_info", SystemInfo, LATCHED_QOS)
        self.t_tf = o.channel("/tf", TFMessage, TF_QOS)
        self.t_tf_static = o.channel("/tf_static", TFMessage, LATCHED_QOS)
        self.t_diag = o.channel("/diagnostics", DiagnosticArray, DIAGNOSTICS_QOS)
        if publish_clock:
            self.t_clock = o.channel("/clock", ClockMsg, CLOCK_QOS)

        self.create_service(Trigger, "~/reset", self._on_reset)
        self.create_service(SetBool, "~/pause", self._on_pause)
        self._start()
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timer = None
        if real_time_factor > 0:
            self._start_realtime()

    # --- run state ------------------------------------------------------------------------
    def _start(self) -> None:
        """(Re)build the model and stepper from the current parameters, at t = 0."""
        self.model: Model = self.cls(**self.values)
        self.stepper: Stepper = make_stepper(self.model, self.method, self.tolerance)
        self.factory = MessageFactory(self.model, self.instance.name, self.instance.origin,
                                      self.time_offset)
        self.p = self.model.parameter_vector()
        # Residuals the stepper enforces (projection): the hard-limit guard watches them.
        self._constraints = [i for i, q in enumerate(self.model.invariants)
                             if q.name.startswith("constraint_")] \
            if self.model.structure.n_constraints > 0 else []
        self.t = 0.0
        self.failed = None
        n_y = self.stepper.y.size
        self._last_y = self.stepper.y.copy().reshape(1, n_y)
        self._publish_static()
        self._publish_sample(0.0, self.stepper.y)

    def _publish_static(self) -> None:
        ns0 = messages.stamp_ns(0.0, self.time_offset)
        laws = self.model.laws()
        scales = self.model.law_scales()
        info = self.factory.system_info(ns0, self.stepper.method, self.tolerance,
                                        [law.key for law in laws],
                                        [scales[law.key] for law in laws])
        self.outlet.publish(self.t_info, info, ns0)
        if any(f.static for f in self.model.frames):
            fr = np.zeros((len(self.model.frames), 7))
            self.model.kernels.frames(0.0, self.stepper.y, self.p, fr)
            msg = TFMessage(transforms=self.factory.transforms(fr, ns0, static=True))
            self.outlet.publish(self.t_tf_static, msg, ns0)

    def _publish_sample(self, t: float, y: np.ndarray) -> None:
        o, k, m, f = self.outlet, self.model.kernels, self.model, self.factory
        n = len(m.coordinates)
        ns = messages.stamp_ns(t, self.time_offset)
        if self.publish_clock:
            o.publish(self.t_clock, messages.clock(ns), ns)
        s = Sample(t, y[:n], y[n:2 * n], float(y[2 * n]), float(y[2 * n + 1]))
        o.publish(self.t_state, f.state(s, ns), ns)
        if o.wanted(self.t_energy):
            s.energy = np.zeros(3)
            k.energy(t, y, self.p, s.energy)
            self.computed["energy"] += 1
            o.publish(self.t_energy, f.energy(s, ns), ns)
        if m.invariants and o.wanted(self.t_inv):
            s.invariants = np.zeros(len(m.invariants))
            k.invariants(t, y, self.p, s.invariants)
            self.computed["invariants"] += 1
            o.publish(self.t_inv, f.invariants(s, ns), ns)
        if m.observables and o.wanted(self.t_obs):
            s.observables = np.zeros(len(m.observables))
            k.observables(t, y, self.p, s.observables)
            self.computed["observables"] += 1
            o.publish(self.t_obs, f.observables(s, ns), ns)
        if any(not fr.static for fr in m.frames) and o.wanted(self.t_tf):
            s.frames = np.zeros((len(m.frames), 7))
            k.frames(t, y, self.p, s.frames)
            self.computed["frames"] += 1
            o.publish(self.t_tf, f.tf(s, ns), ns)
        self.samples_published += 1

    def advance_to(self, t_target: float) -> int:
        """Integrate to ``t_target`` (simulation time), publishing every sample on the way.
        Returns the number of samples published. A failed or paused system publishes none."""
        if self.failed or self.paused:
            return 0
        dt = 1.0 / self.publish_rate
        n = int(math.floor((t_target - self.t) / dt + 1e-9))
        if n <= 0:
            return 0
        times = self.t + dt * np.arange(1, n + 1)
        try:
            Y = self.stepper.advance(times)
        except IntegrationError as e:
            self._fail(str(e))
            return 0
        for i in range(n):
            if not np.all(np.isfinite(Y[i])):
                self._fail(f"non-finite state at t = {times[i]:.6g}")
                return i
            if self._constraints:
                violation = self._constraint_violation(float(times[i]), Y[i])
                if violation:
                    self._fail(violation)
                    return i
            self._publish_sample(float(times[i]), Y[i])
            self.t = float(times[i])
        return n

    def _constraint_violation(self, t: float, y: np.ndarray) -> str | None:
        """Why ``y`` is off its constraint manifold past the hard limit, or None."""
        inv = np.zeros(len(self.model.invariants))
        self.model.kernels.invariants(t, y, self.p, inv)
        n = len(self.model.coordinates)
        limit = self.constraint_limit * max(1.0, float(np.max(np.abs(y[:n]))))
        for i in self._constraints:
            r = float(inv[i])
            if not (math.isfinite(r) and abs(r) <= limit):
                name = self.model.invariants[i].name
                return (f"constraint residual {name} = {r:.3g} past the hard limit {limit:.3g} "
                        f"at t = {t:.6g} (projection cannot restore the constraint)")
        return None

    def _fail(self, reason: str) -> None:
        """Stop this system cleanly: last good state kept, ERROR on /diagnostics, one log line."""
        self.failed = reason
        self.get_logger().error(f"{self.instance.name}: integration stopped: {reason}")
        ns = messages.stamp_ns(self.t, self.time_offset)
        status = DiagnosticStatus(level=DiagnosticStatus.ERROR,
                                  name=f"mechsim/{self.instance.name}/integration",
                                  message=f"stopped: {reason}", hardware_id=self.instance.name,
                                  values=[KeyValue(key="t", value=f"{self.t:.9g}")])
        msg = DiagnosticArray(header=self.factory.header(ns), status=[status])
        self.outlet.publish(self.t_diag, msg, ns)

    # --- real-time pacing -----------------------------------------------------------------
    def _start_realtime(self) -> None:
        self._wall0 = time.monotonic()
        self._sim0 = self.t
        period = max(1.0 / (self.publish_rate * self.real_time_factor), 0.005)
        if self._timer is not None:
            self.destroy_timer(self._timer)
        self._timer = self.create_timer(period, self._on_tick, clock=self._steady)

    def _on_tick(self) -> None:
        target = self._sim0 + self.real_time_factor * (time.monotonic() - self._wall0)
        self.advance_to(target)

    # --- services -------------------------------------------------------------------------
    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        self._restart()
        response.success = True
        response.message = f"{self.instance.name} reset to t = 0"
        return response

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response) -> Any:
        self.paused = bool(request.data)
        if not self.paused and self.real_time_factor > 0:
            self._start_realtime()
        response.success = True
        response.message = "paused" if self.paused else "running"
        return response

    def _restart(self) -> None:
        self._start()
        if self.real_time_factor > 0:
            self._start_realtime()

    # --- parameters -----------------------------------------------------------------------
    def _validate_parameters(self, params: list[RosParameter]) -> SetParametersResult:
        candidate = dict(self.values)
        for prm in params:
            name, value = prm.name, prm.value
            try:
                if name in self.spec:
                    candidate[name] = self.spec[name].validate(value)
                elif name == "method" and value not in METHODS:
                    raise ParameterError(name, f"must be one of {', '.join(METHODS)}")
                elif name in ("tolerance", "publish_rate", "constraint_limit") and not (
                        isinstance(value, float) and math.isfinite(value) and value > 0):
                    raise ParameterError(name, "must be a finite positive number")
            except ParameterError as e:
                return SetParametersResult(successful=False, reason=str(e))
        if any(p.name in self.spec for p in params):
            try:
                model = self.cls(**candidate)
                method = next((p.value for p in params if p.name == "method"), self.method)
                if method != "auto":
                    from mechsim.integrators import choose_method
                    choose_method(model, method)
            except MechsimError as e:
                return SetParametersResult(successful=False, reason=str(e))
        return SetParametersResult(successful=True)

    def _apply_parameters(self, params: list[RosParameter]) -> None:
        restart = False
        changed_model = False
        new_stepper = False
        for prm in params:
            if prm.name in self.spec:
                self.values[prm.name] = self.spec[prm.name].validate(prm.value)
                changed_model = True
                if self.spec[prm.name].kind is str or prm.name.startswith("initial"):
                    restart = prm.name == "formulation" or restart
            elif prm.name == "method":
                self.method = prm.value
                new_stepper = True
            elif prm.name == "tolerance":
                self.tolerance = prm.value
                new_stepper = True
            elif prm.name == "constraint_limit":
                self.constraint_limit = prm.value
            elif prm.name == "publish_rate":
                self.publish_rate = prm.value
                if self.real_time_factor > 0:
                    self._start_realtime()
            elif prm.name == "real_time_factor":
                self.real_time_factor = prm.value
                if prm.value > 0:
                    self._start_realtime()
                elif self._timer is not None:
                    self.destroy_timer(self._timer)
                    self._timer = None
        if restart:
            self._restart()
        elif changed_model:
            # Same structure: keep the state, swap the parameter vector. Initial values take
            # effect at the next reset.
            self.model = self.cls(**self.values)
            self.factory.model = self.model
            self.p = self.model.parameter_vector()
            self.stepper.set_model(self.model)
            self._publish_static()
            self._publish_sample(self.t, self.stepper.y)  # same stamp: diagnostics' new epoch
        if new_stepper and not restart:
            # Continue from the current state with the new method or tolerance.
            self.stepper = make_stepper(self.model, self.method, self.tolerance, t0=self.t,
                                        y0=self.stepper.y.copy())
            self._publish_static()
