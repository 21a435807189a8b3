"""The simulator node: one system instance, one node (namespace = instance name).

What the system does is its run core's (``mechsim.runcore``: stepping, guards, effort hold,
parameter transactions, lookahead); this node is its ROS face. It declares the ROS parameters,
turns a parameter set into one transaction of the run, publishes what the run releases
(``topics.SystemTopics``, through the node's ``Outlet``), serves ~/reset and ~/pause, hands
effort commands to the run, and paces it with a timer unless a runner steps it.

Topics (stamped with simulation time + ``time_offset``, so /clock never starts at 0):
  <ns>/state        sensor_msgs/JointState   joint-like coordinates (rad, m, ...) and rates
  <ns>/pose         geometry_msgs/PoseStamped   attitude systems: orientation in "world"
  <ns>/twist        geometry_msgs/TwistStamped  attitude systems: angular velocity [rad/s] in
                                                body axes (header.frame_id <ns>/<frame>)
  <ns>/energy       mechsim_msgs/Energy      T, V, T+V, h, work_external, work_dissipated
  <ns>/invariants   mechsim_msgs/NamedScalars   conserved quantities and constraint residuals,
                                                one (name, value, unit) record each
  <ns>/observables  mechsim_msgs/NamedScalars   constraint forces, multipliers, ...
  <ns>/system_info  mechsim_msgs/SystemInfo  (transient local) what runs and which laws hold
  <ns>/curves       visualization_msgs/MarkerArray  (transient local) the model's curves
                                                (U_eff(r), the top's V(θ)) with their levels,
                                                once per parameter set (``Model.curves``)
  /tf, /tf_static   tf2_msgs/TFMessage       frames <ns>/<frame>, root "world"
  /clock            rosgraph_msgs/Clock      only when this node owns the clock
  /diagnostics      diagnostic_msgs/DiagnosticArray  a failed integration, a dropped effort
Energy, invariants, observables and frames are computed only while something consumes them.
Parameters: every model parameter (same names as scenes and --set), plus method, tolerance,
publish_rate, real_time_factor (0: stepped by the caller, as fast as possible; then read-only),
constraint_limit, effort_timeout, effort_wait and effort_limit; their ranges are the ones of
``mechsim.params`` (shared with the CLI and scene files), in the descriptors. A set is
validated completely and then applied as a whole, or refused with its reason
(``mechsim.runcore.change``); epochs, guards: ``mechsim.runcore``.
Services: ~/reset (std_srvs/Trigger), ~/pause (std_srvs/SetBool).
Effort input: ``<ns>/effort`` (std_msgs/Float64MultiArray, one generalized force per
coordinate; semantics and what no peer can do with it in ``mechsim.runcore.effort``); a refused
command is ignored with a one-line warning (throttled), a dropped effort or a silent controller
is a WARN on /diagnostics (``mechsim/<ns>/effort``). Each change of the applied effort goes to
the sinks (a recording) as a message on ``<ns>/effort`` stamped with the sample from which it
applies.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from operator import attrgetter
from typing import Any

import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter as RosParameter
from rclpy.parameter_service import ParameterService
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool, Trigger

from mechsim.errors import MechsimError, ParameterError
from mechsim.outputs import messages
from mechsim.outputs.sink import Sink
from mechsim.params import CONSTRAINT_LIMIT
from mechsim.ros.outlet import STATE_QOS, Outlet
from mechsim.ros.simulator_parameters import declare, start_values, with_changes
from mechsim.ros.topics import SystemTopics
from mechsim.runcore.change import Change, Settings, reason
from mechsim.runcore.equations import PREPARE_TIMEOUT
from mechsim.runcore.pacing import Pacing
from mechsim.runcore.run import SystemRun
from mechsim.runcore.stops import raise_if_stop
from mechsim.scene import Instance, instance_name
from mechsim_msgs.srv import Step

CONSTRAINT_LIMIT_DEFAULT = float(CONSTRAINT_LIMIT.default)
#: The simulator node's name (in its instance's namespace).
NODE_NAME = "simulator"
#: Wall seconds between two warnings of the same kind about refused effort commands.
_EFFORT_LOG_PERIOD = 5.0


def _key(params: list[RosParameter]) -> tuple[tuple[str, str], ...]:
    return tuple((p.name, repr(p.value)) for p in params)


class _OfRun:
    """A read-only attribute of the node's run (``SimulatorNode.run``), by the same name or
    the path given."""

    def __init__(self, path: str | None = None) -> None:
        self.path = path

    def __set_name__(self, owner: type, name: str) -> None:
        self.get = attrgetter(f"run.{self.path or name}")

    def __get__(self, node: Any, owner: type | None = None) -> Any:
        return self if node is None else self.get(node)


class SimulatorNode(Node):
    t = _OfRun()
    epoch = _OfRun()
    model = _OfRun()
    stepper = _OfRun()
    failed = _OfRun()
    finished = _OfRun()
    paused = _OfRun()
    stepped = _OfRun()
    samples_published = _OfRun()
    computed = _OfRun()
    publish_rate = _OfRun("settings.publish_rate")
    constraint_limit = _OfRun("settings.constraint_limit")
    effort_received = _OfRun("effort.received")
    effort_rejected = _OfRun("effort.rejected")

    def __init__(self, instance: Instance, *, context: Context | None = None,
                 publish_rate: float = 100.0, real_time_factor: float = 1.0,
                 publish_clock: bool = False, sinks: list[Sink] | None = None,
                 time_offset: float = messages.DEFAULT_TIME_OFFSET,
                 constraint_limit: float = CONSTRAINT_LIMIT_DEFAULT,
                 end_time: float | None = None,
                 prepare_timeout: float = PREPARE_TIMEOUT,
                 before_first_message: Callable[[SimulatorNode], None] | None = None,
                 lossless: bool = False, stepped: bool | None = None,
                 node_name: str = NODE_NAME, deferred: bool = False,
                 parameter_services: bool = True) -> None:
        """``stepped`` (default: ``real_time_factor`` 0): the caller steps the node
        (``advance_to``), which then never paces itself; its ``real_time_factor`` (the
        caller's pace, 0: as fast as possible) is read-only. ``end_time``: the node never
        integrates past this simulation time (a scene's duration), whatever its pacing.
        ``before_first_message``: called once the publishers exist, before anything is
        published (a runner of separate processes waits there for its consumers).
        ``lossless``: every reliable subscriber receives every sample (``Outlet``).
        ``deferred``: the node is made (its parameters, services and endpoints) but publishes
        nothing until :meth:`begin` (a start whose graph check runs meanwhile).
        ``parameter_services`` False: the node's parameters are declared (overrides applied)
        but the services that serve them to other processes (``ros2 param``) are made later,
        by :meth:`serve_parameters` (a scene of many nodes makes them once its samples flow:
        they are most of a node's endpoints, and their cost grows with the endpoints a
        process already has).
        The values given to the node from outside (``--ros-args``, a params file, a launch
        file) take precedence over the arguments (``simulator_parameters``); its namespace,
        remapped or not, is the instance's name."""
        stepped = real_time_factor == 0 if stepped is None else stepped
        # Same ranges as the CLI and scenes: a bad value is a ParameterError, before ROS.
        # (the instance's own settings, e.g. a scene's effort_timeout, over the defaults)
        settings = Settings(**{"tolerance": instance.tolerance, "publish_rate": publish_rate,
                               "real_time_factor": real_time_factor,
                               "constraint_limit": constraint_limit,
                               **instance.settings}).checked()
        instance_name("instance", instance.name)
        super().__init__(node_name, namespace=instance.name, context=context,
                         start_parameter_services=parameter_services)
        self._serves_parameters = parameter_services
        try:
            start = start_values(self, with_changes(instance, name=self._instance_name()),
                                 settings, stepped=stepped, time_offset=time_offset,
                                 end_time=end_time, publish_clock=publish_clock)
        except BaseException:
            super().destroy_node()  # a node that never started leaves nothing in the graph
            raise
        self.start = start
        instance = self.instance = start.instance
        self.time_offset = start.time_offset
        self._pending: tuple[tuple[tuple[str, str], ...], Change] | None = None
        self._effort_logged: dict[str, float] = {}
        self.outlet = Outlet(self, sinks, lossless=lossless)
        self._effort_sub = self.create_subscription(
            Float64MultiArray, "effort", self._on_effort, STATE_QOS,
            callback_group=MutuallyExclusiveCallbackGroup())
        self.topics = SystemTopics(self, self.outlet, instance, start.time_offset,
                                   start.publish_clock, self._effort_sub.get_publisher_count)
        model = instance.build()
        self.run = SystemRun(model, instance.method, start.settings, self.topics,
                             stepped=stepped, end_time=start.end_time,
                             prepare_timeout=prepare_timeout)
        self.topics.run = self.run
        declare(self, start, self.run.values, self.run.method)
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self.create_service(Trigger, "~/reset", self._on_reset)
        self.create_service(SetBool, "~/pause", self._on_pause)
        self.create_service(Step, "~/step", self._on_step)
        self.topics.model_channels(model)
        self._before_first_message = before_first_message
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timer: Any = None
        if not deferred:
            self.begin()

    def begin(self) -> None:
        """Release the first sample (``before_first_message`` called first) and start the
        pacing: done by the constructor unless the node was made ``deferred``."""
        if self._before_first_message is not None:
            self._before_first_message(self)
        self.run.start()
        self._start_realtime()

    def serve_parameters(self) -> None:
        """Make the services that serve the node's parameters (``ros2 param``), if the node
        was made without them."""
        if not self._serves_parameters:
            ParameterService(self)  # (its services are the node's: the node keeps them)
            self._serves_parameters = True

    def _instance_name(self) -> str:
        """The instance name: this node's namespace (as remapped, if it was), one level."""
        ns = self.get_namespace().strip("/")
        if "/" in ns or not ns:
            raise ParameterError("namespace", f"{self.get_namespace()!r}: a simulator's "
                                 "namespace is one name, its instance's (e.g. -r __ns:=/demo)")
        return instance_name("namespace", ns)

    @property
    def costs(self) -> dict[str, float]:
        """Wall seconds per stage of the sample pipeline: integrate, evaluate, encode,
        publish (``mechsim bench --streaming``)."""
        return {**self.run.costs, **self.topics.costs}

    def advance_to(self, t_target: float) -> int:
        """Integrate to ``t_target`` and publish every sample on the way (``SystemRun``)."""
        return self.run.advance_to(t_target)

    def destroy_node(self) -> None:
        self.outlet.hand_over()  # what was published reaches the sinks
        super().destroy_node()

    # --- real-time pacing (only when not stepped by the caller) ---------------------------
    def _start_realtime(self) -> None:
        """(Re)start the one pacing timer from the current state."""
        if self._timer is not None:
            self.destroy_timer(self._timer)
            self._timer = None
        s = self.run.settings
        if self.run.stepped or s.real_time_factor <= 0:
            return
        pacing = self.run.pacing = Pacing(s.real_time_factor, s.publish_rate, time.monotonic(),
                                          self.run.t)
        self.run.lookahead = pacing.lookahead
        self._timer = self.create_timer(pacing.period, self._on_tick, clock=self._steady)

    @property
    def pacing(self) -> Pacing | None:
        """How this node's run follows the wall clock (None: stepped by its caller)."""
        return self.run.pacing

    def _on_tick(self) -> None:
        pacing = self.run.pacing
        if pacing is not None:
            self.run.advance_to(pacing.due(time.monotonic(), self.run.t))

    # --- services -------------------------------------------------------------------------
    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        try:
            self.run.reset()
            self._start_realtime()
        except Exception as e:  # noqa: BLE001 - answered, never raised into the executor
            raise_if_stop(e)
            response.success = False
            response.message = f"{self.instance.name}: reset failed: {reason(e)}"
            return response
        response.success = True
        response.message = f"{self.instance.name} reset to t = 0"
        return response

    def set_paused(self, paused: bool) -> None:
        """Pause or resume (pacing restarts from the current state, so no catching up)."""
        self.run.set_paused(paused)
        self.outlet.hand_over()
        if not paused:
            self._start_realtime()

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response) -> Any:
        self.set_paused(bool(request.data))
        response.success = True
        # Where the run stands: a resumed run goes on from this sample, paced from now.
        response.message = (f"paused at t = {self.run.t:.12g} s" if self.run.paused
                            else f"running from t = {self.run.t:.12g} s")
        return response

    def _on_step(self, request: Step.Request, response: Step.Response) -> Any:
        """Advance the paused system by ``request.samples`` samples (``SystemRun.step``) and
        report the last one."""
        try:
            taken = self.run.step(int(request.samples))
        except Exception as e:  # noqa: BLE001 - answered, never raised into the executor
            raise_if_stop(e)
            response.success = False
            response.message = f"{self.instance.name}: step refused: " + (
                str(e) if isinstance(e, MechsimError) else reason(e))
            return response
        self.outlet.hand_over()
        run, at = self.run, self.run.model.layout
        response.success = True
        response.samples = taken
        response.time = run.t
        response.stamp = messages.to_time(messages.stamp_ns(run.t, self.time_offset))
        response.name = [c.name for c in run.model.coordinates]
        response.position = run.y[at.q].tolist()
        response.velocity = run.model.rates(np.array([run.t]), run.y, run.p).tolist()
        response.message = f"{taken} samples to t = {run.t:.9g} s"
        return response

    # --- parameters: one transaction of the run per set -----------------------------------
    def _validate_parameters(self, params: list[RosParameter]) -> SetParametersResult:
        try:
            change = self.run.plan([(p.name, p.value) for p in params])
        except MechsimError as e:
            return SetParametersResult(successful=False, reason=str(e))
        self._pending = (_key(params), change)
        return SetParametersResult(successful=True)

    def _apply_parameters(self, params: list[RosParameter]) -> None:
        pending, self._pending = self._pending, None
        if pending is None or pending[0] != _key(params):
            return  # not the set just validated (cannot happen with rclpy's order)
        if self.run.apply(pending[1]):
            self._start_realtime()

    # --- effort input ---------------------------------------------------------------------
    def _on_effort(self, msg: Float64MultiArray) -> None:
        refusal = self.run.offer(np.asarray(msg.data, dtype=np.float64))
        if refusal is not None:
            kind, why = refusal
            now = time.monotonic()
            if now - self._effort_logged.get(kind, -math.inf) >= _EFFORT_LOG_PERIOD:
                self._effort_logged[kind] = now
                self.get_logger().warning(f"{self.topics.t_effort}: command ignored: {why}")
