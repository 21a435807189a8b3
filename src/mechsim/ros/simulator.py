"""The simulator node: one system instance, one node (namespace = instance name).

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
  /tf, /tf_static   tf2_msgs/TFMessage       frames <ns>/<frame>, root "world"
  /clock            rosgraph_msgs/Clock      only when this node owns the clock
  /diagnostics      diagnostic_msgs/DiagnosticArray  only if integration fails
Parameters: every model parameter (same names as scenes and --set), plus method, tolerance,
publish_rate, real_time_factor (0: stepped by the caller, as fast as possible; then read-only),
and constraint_limit (hard limit on enforced constraint residuals, relative to max(1, max|q|)).
Their ranges are the ones of ``mechsim.params`` (shared with the CLI and scene files).

Runtime changes are transactions. A parameter set is validated completely before it is accepted:
every value, the whole model built with the new values (its own checks), the method's
compatibility with it (``choose_method``) and the new stepper; a structural change (a
formulation, the bead's shape or curve, a number of masses: anything that changes the equations
of motion) is first derived and compiled in a child process with a time limit
(``mechsim.ros.prepare``). Any failure rejects the whole set with its reason
(``SetParametersResult(successful=False)``) and nothing changes; an accepted set changes the
model, stepper, kernels and outputs together. When each change takes effect:
- a structural change restarts the system at t = 0 from the initial state of the new values;
- another model parameter takes effect at once, from the current state; ``initial.*`` and
  ``initial_rate.*`` are stored and take effect at the next reset (or structural change);
- method and tolerance: a new stepper continues from the current state.
Epochs: ``epoch`` counts the runs with one fixed model; a reset or an accepted model change
starts a new one, so a consumer re-bases its reference values. On the topics a new epoch is a
sample whose stamp is not later than the previous one: a reset restarts at t = 0, and after a
model change that keeps the state the current sample is published again (same stamp, new
parameters); system_info is republished with the new laws and scales.
Guards: a non-finite state, a failed step (also an error from an extreme parameter value) or an
enforced constraint residual past the hard limit stops this system only (``_fail``): last good
state kept, ERROR on /diagnostics.
Services: ~/reset (std_srvs/Trigger), ~/pause (std_srvs/SetBool).
Effort input (``<ns>/effort``, std_msgs/Float64MultiArray, one generalized force per coordinate
in the order of ``state``: N for a length, N·m for an angle): a command takes effect at the next
sample and is held over each sample period (zero-order hold) for ``effort_timeout`` simulated
seconds, then the effort returns to zero; its work is part of ``work_external``, and from the
first nonzero effort of an epoch system_info lists only the laws that still hold
(``Model.laws_under_effort``). Every node subscribes; a command of the wrong length, with a
non-finite value, to a system whose kernels take none (not Lagrangian: rigid_body,
moving_frames, the quaternion top) or under a method that integrates without it (exact,
yoshida*, verlet, gauss6) is ignored with a one-line warning (throttled). While a command
publisher is present (or an effort is held) the node steps sample by sample; stepped by a
runner (fast mode), it then waits after each sample up to ``effort_wait`` wall seconds for the
controller's next command. Each change of the applied effort goes to the sinks (a recording)
as a message on ``<ns>/effort`` stamped with the sample from which it applies.
Energy, invariants, observables and frames are computed only while something consumes them,
in one call of the API's output evaluation (``mechsim.simulate.evaluate``) per block of samples.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, TwistStamped
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter as RosParameter
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool, Trigger

from mechsim.errors import IntegrationError, MechsimError, ParameterError, one_line
from mechsim.integrators import METHODS, Stepper, make_stepper
from mechsim.outputs import messages
from mechsim.outputs.messages import Chunk, ChunkEncoder, MessageFactory, Sample
from mechsim.outputs.sink import Sink
from mechsim.params import (
    CONSTRAINT_LIMIT,
    EFFORT_TIMEOUT,
    EFFORT_WAIT,
    PUBLISH_RATE,
    REAL_TIME_FACTOR,
    TOLERANCE,
    Parameter,
    shown,
)
from mechsim.ros.outlet import (
    CLOCK_QOS,
    DIAGNOSTICS_QOS,
    LATCHED_QOS,
    STATE_QOS,
    TF_QOS,
    Outlet,
)
from mechsim.ros.parameters import descriptor
from mechsim.ros.prepare import PREPARE_TIMEOUT, prepare_model
from mechsim.ros.process import held_signals, raise_if_stop
from mechsim.scene import Instance, instance_name
from mechsim.simulate import OutputShape, evaluate, evaluate_arrays
from mechsim.systems import system_class
from mechsim.systems.base import Model
from mechsim_msgs.msg import Energy, NamedScalars, SystemInfo
from tf2_msgs.msg import TFMessage

#: Run settings a node exposes as ROS parameters, each with its one range.
SETTINGS: dict[str, Parameter] = {p.name: p for p in (TOLERANCE, PUBLISH_RATE, REAL_TIME_FACTOR,
                                                       CONSTRAINT_LIMIT, EFFORT_TIMEOUT,
                                                       EFFORT_WAIT)}
# Projection keeps enforced constraint residuals at round-off, diagnostics says ERROR at
# 1e-3: a residual of 1 % of the configuration's size means the state is garbage.
CONSTRAINT_LIMIT_DEFAULT = float(CONSTRAINT_LIMIT.default)
#: Samples integrated per call of the kernels (bounds the memory of a long advance).
_BLOCK = 1000
#: Wall seconds of samples a paced node computes ahead (published when due): the cost of a
#: call into the kernels, and of a hand-off to the sinks, is shared by that many samples.
#: A new subscriber gets the outputs nobody consumed before within this time. (All systems
#: in real time, 10 s, 3 interleaved runs: 0.25 s gave 0.11-0.16 of a core, 0.19-0.25 with
#: a bag and .rrd; 1 s gave 0.09-0.12 and 0.14-0.16.)
LOOKAHEAD = 1.0
#: Wall seconds between two warnings of the same kind about rejected effort commands.
_EFFORT_LOG_PERIOD = 5.0


def _reason(e: BaseException) -> str:
    """One line for an unexpected error (its type and first line, bounded)."""
    first = (str(e).splitlines() or [""])[0]
    return one_line(f"{type(e).__name__}: {first}")[:300]


def _builder(build: Callable[[Sample, int], Any], sample: Callable[[int], Sample],
             ns: np.ndarray) -> Callable[[int], Any]:
    """The message of sample i, built only for a sink that takes messages."""
    return lambda i: build(sample(i), int(ns[i]))


def paced_lookahead(publish_rate: float, real_time_factor: float) -> int:
    """Samples a paced node computes ahead (``LOOKAHEAD`` wall seconds of them)."""
    return max(1, min(_BLOCK, int(LOOKAHEAD * publish_rate * real_time_factor)))


@dataclass
class _Change:
    """A validated parameter set, ready to commit (nothing in it can fail any more)."""

    key: tuple[tuple[str, str], ...]
    values: dict[str, Any]
    method: str
    tolerance: float
    publish_rate: float
    real_time_factor: float
    constraint_limit: float
    effort_timeout: float
    effort_wait: float
    model: Model | None = None  # new model (values changed)
    structural: bool = False  # new equations of motion: restart at t = 0
    stepper: Stepper | None = None  # new stepper (method, tolerance or structure changed)


@dataclass
class _Block:
    """Consecutive samples checked, evaluated and encoded, released to the topics and sinks in
    order (``_release``), all at once or, computed ahead in a paced run, as the wall clock makes
    them due."""

    times: np.ndarray
    Y: np.ndarray  # rows that passed the guards
    ns: np.ndarray
    topics: list[tuple[str, np.ndarray | None, Callable[[int], Any]]]  # rows: see Outlet
    columns: dict[str, Any]
    reason: str | None  # why the system stops after the last row (a guard), if it does
    released: int = 0

    @property
    def left(self) -> int:
        return self.times.size - self.released


def _key(params: list[RosParameter]) -> tuple[tuple[str, str], ...]:
    return tuple((p.name, repr(p.value)) for p in params)


class SimulatorNode(Node):
    def __init__(self, instance: Instance, *, context: Context | None = None,
                 publish_rate: float = 100.0, real_time_factor: float = 1.0,
                 publish_clock: bool = False, sinks: list[Sink] | None = None,
                 time_offset: float = messages.DEFAULT_TIME_OFFSET,
                 constraint_limit: float = CONSTRAINT_LIMIT_DEFAULT,
                 end_time: float | None = None,
                 prepare_timeout: float = PREPARE_TIMEOUT,
                 before_first_message: Callable[[SimulatorNode], None] | None = None,
                 lossless: bool = False) -> None:
        """``real_time_factor`` 0: the caller steps the node (``advance_to``), which then never
        paces itself (the parameter is read-only). ``end_time``: the node never integrates
        past this simulation time (a scene's duration), whatever its pacing.
        ``before_first_message``: called once the publishers exist, before anything is
        published (a runner of separate processes waits there for its consumers).
        ``lossless``: every reliable subscriber receives every sample (``Outlet``)."""
        # Same ranges as the CLI and scenes: a bad value is a ParameterError, before ROS.
        publish_rate = float(PUBLISH_RATE.check(publish_rate, "publish_rate"))
        real_time_factor = float(REAL_TIME_FACTOR.check(real_time_factor, "real_time_factor"))
        constraint_limit = float(CONSTRAINT_LIMIT.check(constraint_limit, "constraint_limit"))
        tolerance = float(TOLERANCE.check(instance.tolerance, "tolerance"))
        instance_name("instance", instance.name)
        super().__init__("simulator", namespace=instance.name, context=context)
        self.instance = instance
        self.cls: type[Model] = system_class(instance.system)
        self.spec = {p.name: p for p in self.cls.parameter_spec()}
        self.values: dict[str, Any] = dict(self.cls(**instance.parameters).values)
        self.method = instance.method
        self.tolerance = tolerance
        self.publish_rate = publish_rate
        self.real_time_factor = real_time_factor
        self.stepped = real_time_factor == 0
        self.publish_clock = publish_clock
        self.time_offset = time_offset
        self.constraint_limit = constraint_limit
        self.effort_timeout = float(EFFORT_TIMEOUT.default)
        self.effort_wait = float(EFFORT_WAIT.default)
        self.end_time = end_time
        self.prepare_timeout = prepare_timeout
        self.failed: str | None = None
        self.paused = False
        self.samples_published = 0
        self.epoch = 0
        self.computed = {"energy": 0, "invariants": 0, "observables": 0, "frames": 0}
        #: Wall seconds spent per stage of the sample pipeline (``mechsim bench --streaming``).
        self.costs = {"integrate": 0.0, "evaluate": 0.0, "encode": 0.0, "publish": 0.0}
        self._pending: _Change | None = None
        #: Samples computed ahead of the wall clock by a paced run (0: only the due ones).
        self.lookahead = 0
        #: Samples by which this node's blocks computed ahead are shifted (a paced scene
        #: spreads its nodes' blocks over the ticks instead of computing them all in one).
        self.stagger = 0
        self._ahead: _Block | None = None
        self._ahead_failed = False

        self.declare_parameter("system", instance.system, ParameterDescriptor(
            description="system id (see `mechsim systems`)", read_only=True))
        for name, p in self.spec.items():
            later = " (takes effect at the next reset)" if name.startswith("initial") else ""
            self.declare_parameter(name, self.values[name],
                                   descriptor(p, description=p.description + later))
        self.declare_parameter("method", self.method, ParameterDescriptor(
            description=f"integrator ({', '.join(METHODS)})"))
        for name, p in SETTINGS.items():
            ro = name == "real_time_factor" and self.stepped
            text = "0: stepped by the scene runner (read-only)" if ro else None
            self.declare_parameter(name, float(getattr(self, name)),
                                   descriptor(p, read_only=ro, description=text))
        self.declare_parameter("time_offset", float(time_offset), ParameterDescriptor(
            description="stamp of simulation time 0 [s] (ROS time 0 means uninitialised)",
            read_only=True))
        self.add_on_set_parameters_callback(self._validate_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)

        self.outlet = Outlet(self, sinks, lossless=lossless)
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
        self._setup_effort()
        model = self.cls(**self.values)
        self._attitude_channels(model)
        if before_first_message is not None:
            before_first_message(self)
        self._install(model, make_stepper(model, self.method, self.tolerance))
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._timer = None
        if not self.stepped:
            self._start_realtime()

    # --- run state ------------------------------------------------------------------------
    def _install(self, model: Model, stepper: Stepper) -> None:
        """Run ``model`` with ``stepper`` (at its initial state, t = 0)."""
        self.model = model
        self.stepper = stepper
        self.factory = MessageFactory(model, self.instance.name, self.instance.origin,
                                      self.time_offset)
        self.encoder = ChunkEncoder(self.factory)
        self._attitude_channels(model)
        self.p = model.parameter_vector()
        self._shape = OutputShape.of(model)
        self._dynamic_frames = any(not fr.static for fr in model.frames)
        self._set_constraints()
        self.t = 0.0
        self._y = stepper.y.copy()
        self.failed = None
        self._ahead, self._ahead_failed = None, False
        self._effort_reset(new_epoch=True)
        self._publish_static()
        self._emit(np.zeros(1), stepper.y.copy()[None, :])

    def _attitude_channels(self, model: Model) -> None:
        """pose and twist for a model with an attitude (made once, kept if a later
        formulation has none)."""
        if model.attitude is not None:
            self.t_pose = self.outlet.channel("pose", PoseStamped, STATE_QOS)
            self.t_twist = self.outlet.channel("twist", TwistStamped, STATE_QOS)

    def _set_constraints(self) -> None:
        """Indices (among the invariants) of the residuals the stepper enforces: the
        hard-limit guard watches them."""
        names = [q.name for q in self.model.invariants]
        self._constraints = [names.index(law.name) for law in self.model.laws()
                             if law.is_constraint and law.name in names] \
            if self.model.structure.n_constraints > 0 else []

    def _start(self) -> None:
        """(Re)build the model and stepper from the current parameters, at t = 0."""
        model = self.cls(**self.values)
        stepper = make_stepper(model, self.method, self.tolerance)
        self.epoch += 1
        self._install(model, stepper)

    def _publish_static(self) -> None:
        ns0 = messages.stamp_ns(0.0, self.time_offset)
        laws = self.model.laws_under_effort() if self._effort_acted else self.model.laws()
        scales = self.model.law_scales()
        info = self.factory.system_info(ns0, self.stepper.method, self.tolerance,
                                        [law.key for law in laws],
                                        [scales[law.key] for law in laws])
        self.outlet.publish(self.t_info, info, ns0)
        if any(f.static for f in self.model.frames):
            out = evaluate(self.model, np.zeros(1), self.stepper.y[None, :], self.p,
                           ("frames",))
            assert out.frames is not None
            msg = TFMessage(transforms=self.factory.transforms(out.frames[0], ns0,
                                                                 static=True))
            self.outlet.publish(self.t_tf_static, msg, ns0)

    def _wanted(self) -> tuple[str, ...]:
        """The outputs something consumes now (asked once per block of samples)."""
        o, shape = self.outlet, self._shape
        want = []
        if o.wanted(self.t_energy):
            want.append("energy")
        if shape.invariants and o.wanted(self.t_inv):
            want.append("invariants")
        if shape.observables and o.wanted(self.t_obs):
            want.append("observables")
        if self._dynamic_frames and o.wanted(self.t_tf):
            want.append("frames")
        return tuple(want)

    def _emit(self, times: np.ndarray, Y: np.ndarray) -> int:
        """Check the rows of ``Y`` against the guards and publish them, in order, up to the
        first bad one (which stops the system). Returns the number of rows published."""
        block = self._prepare(times, Y)
        return self._release(block, block.left)

    def _prepare(self, times: np.ndarray, Y: np.ndarray) -> _Block:
        """The rows of ``Y`` up to the first that fails a guard, evaluated (only the outputs
        something consumes) and encoded for every topic, not yet published."""
        at = self.model.layout
        t0 = time.perf_counter()
        good = times.size
        if not np.isfinite(Y).all():
            good = int(np.argmin(np.all(np.isfinite(Y), axis=1)))
        reason = None if good == times.size else f"non-finite state at t = {times[good]:.6g}"
        self.outlet.refresh()
        want = self._wanted()
        which = want + (("invariants",) if self._constraints and "invariants" not in want
                        else ())
        out = evaluate_arrays(self.model, self._shape, times[:good], Y[:good], self.p, which) \
            if good and which else None
        inv = out[1] if out is not None and "invariants" in which else None
        if self._constraints and good and inv is not None:
            r = inv[:, self._constraints]
            limit = self.constraint_limit * np.maximum(1.0, np.max(np.abs(Y[:good, at.q]),
                                                                   axis=1))
            bad = ~np.all(np.isfinite(r) & (np.abs(r) <= limit[:, None]), axis=1)
            if bad.any():
                good = int(np.argmax(bad))
                j = self._constraints[int(np.argmax(~(np.isfinite(r[good]) & (
                    np.abs(r[good]) <= limit[good]))))]
                name = self._shape.invariants[j]
                reason = (f"constraint residual {name} = {inv[good, j]:.3g} past the hard "
                          f"limit {limit[good]:.3g} at t = {times[good]:.6g} (projection "
                          "cannot restore the constraint)")
        self.costs["evaluate"] += time.perf_counter() - t0
        if out is not None and good < times.size:
            out = tuple(a[:good] for a in out)
            inv = inv[:good] if inv is not None else None
        return self._encode(times[:good], Y[:good], out, inv, want, reason)

    def _encode(self, times: np.ndarray, Y: np.ndarray, out: tuple[np.ndarray, ...] | None,
                inv: np.ndarray | None, want: tuple[str, ...], reason: str | None) -> _Block:
        """Every topic of the samples ``times`` (rows of ``Y``), each encoded for the whole
        block at once (``ChunkEncoder``)."""
        f, at = self.factory, self.model.layout
        t0 = time.perf_counter()
        n = times.size
        ns = messages.stamps_ns(times, self.time_offset)
        c = Chunk(ns, Y[:, at.q], Y[:, at.v], Y[:, [at.work_external, at.work_dissipated]])
        if out is not None:
            if "energy" in want:
                c.energy = out[0]
            if "invariants" in want:
                c.invariants = inv
            if "observables" in want:
                c.observables = out[2]
            if "frames" in want:
                c.frames = out[3]

        def sample(i: int) -> Sample:
            return Sample(float(times[i]), c.q[i], c.v[i], float(c.work[i, 0]),
                          float(c.work[i, 1]),
                          None if c.energy is None else c.energy[i],
                          None if c.invariants is None else c.invariants[i],
                          None if c.observables is None else c.observables[i],
                          None if c.frames is None else c.frames[i])

        enc = self.encoder
        needs_rows = self.outlet.needs_rows

        def encode(key: str, topic: str) -> np.ndarray | None:
            """The topic's CDR rows, only where someone reads bytes."""
            return enc.encode(key, c) if needs_rows(topic) else None

        columns: dict[str, Any] = {}
        topics: list[tuple[str, np.ndarray | None, Callable[[int], Any]]] = []
        # The values as columns only for a sink that takes them (``needs_columns``).
        needs_columns = self.outlet.needs_columns
        if n:
            if c.energy is not None and needs_columns(self.t_energy):
                columns[self.t_energy] = messages.EnergyColumns.of(c)
            if c.invariants is not None and needs_columns(self.t_inv):
                columns[self.t_inv] = {name: c.invariants[:, j]
                                       for j, name in enumerate(self._shape.invariants)}
            if c.observables is not None and needs_columns(self.t_obs):
                columns[self.t_obs] = {name: c.observables[:, j]
                                       for j, name in enumerate(f.observable_names)}
            if c.frames is not None and needs_columns(self.t_tf):
                columns[self.t_tf] = f.transform_columns(c.frames, c.placed_frames(f))
            if self.publish_clock:
                topics.append((self.t_clock, encode("clock", self.t_clock),
                               lambda i: messages.clock(int(ns[i]))))
            if f.joints and needs_columns(self.t_state):
                columns[self.t_state] = {f.coordinate_names[j]: c.q[:, j] for j in f.joints}
            if f.joints:
                topics.append((self.t_state, encode("state", self.t_state),
                               _builder(f.state, sample, ns)))
            if f.attitude is not None:
                topics.append((self.t_pose, encode("pose", self.t_pose),
                               _builder(f.pose, sample, ns)))
                topics.append((self.t_twist, encode("twist", self.t_twist),
                               _builder(f.twist, sample, ns)))
            for key, topic, build in (("energy", self.t_energy, f.energy),
                                      ("invariants", self.t_inv, f.invariants),
                                      ("observables", self.t_obs, f.observables),
                                      ("tf", self.t_tf, f.tf)):
                if getattr(c, "frames" if key == "tf" else key) is None:
                    continue
                self.computed["frames" if key == "tf" else key] += n
                topics.append((topic, encode(key, topic), _builder(build, sample, ns)))
        self.costs["encode"] += time.perf_counter() - t0
        return _Block(times, Y, ns, topics, columns, reason)

    def _release(self, block: _Block, k: int) -> int:
        """Publish and record the next ``k`` samples of ``block``; after its last one, stop
        the system if a guard failed there. Returns ``k``."""
        a, b = block.released, block.released + k
        if k:
            t0 = time.perf_counter()
            part = None if a == 0 and b == block.times.size else slice(a, b)
            # A stop waits for the samples: what was published and self.t agree.
            with held_signals():
                self.outlet.publish_chunk(block.ns, block.topics, block.columns, part)
                block.released = b
                self.samples_published += k
                self.t = float(block.times[b - 1])
                self._y = block.Y[b - 1].copy()
                if block.left == 0:
                    self.outlet.hand_over()  # the block's samples to the sinks, at once
            self.costs["publish"] += time.perf_counter() - t0
        if block.left == 0 and block.reason is not None:
            self._fail(block.reason)
        return k

    def _drop_ahead(self) -> None:
        """Forget the samples computed ahead and not published (a change applies from the
        next sample)."""
        block, self._ahead = self._ahead, None
        self.outlet.hand_over()
        if block is not None and block.left and not self.failed:
            self._rewind()

    def _rewind(self) -> None:
        """The stepper, which ran ahead, goes on from the last published sample."""
        if self.stepper.method in Stepper.TAKES_INPUTS:
            self.stepper.restart(self.t, self._y, self.p)
        else:
            self.stepper = make_stepper(self.model, self.method, self.tolerance, t0=self.t,
                                        y0=self._y.copy())

    def advance_to(self, t_target: float) -> int:
        """Integrate to ``t_target`` (simulation time; never past ``end_time``), publishing
        every sample on the way. Returns the number of samples published. A failed or paused
        system publishes none. With ``lookahead`` > 0 (a paced run) up to that many samples
        are computed in one go and published as they become due; any change (a parameter
        set, a reset, an effort command) drops the ones not yet published."""
        if self.end_time is not None:
            t_target = min(t_target, self.end_time)
        published = 0
        while not (self.failed or self.paused):
            dt = 1.0 / self.publish_rate
            due = min(int(math.floor((t_target - self.t) / dt + 1e-9)), _BLOCK)
            if due <= 0:
                break
            ahead = self._ahead
            if ahead is not None and ahead.left:
                if self._inbox is None:
                    published += self._release(ahead, min(due, ahead.left))
                    continue
                self._drop_ahead()  # a command applies from the next sample
            n = due
            if self._effort_step():
                n = 1
            elif self.lookahead > due and not self._ahead_failed:
                last = _BLOCK if self.end_time is None else int(math.floor(
                    (self.end_time - self.t) / dt + 1e-9))
                # To the next block boundary (every lookahead samples, shifted by stagger).
                ahead_n = self.lookahead - (self.samples_published + self.stagger) \
                    % self.lookahead
                n = max(due, min(ahead_n, last, _BLOCK))
            times = self.t + dt * np.arange(1, n + 1)
            try:
                t0 = time.perf_counter()
                Y = self.stepper.advance(times)
                # (the events' record is simulate()'s result; a node, running for ever,
                # keeps none: memory stays flat however many bounces)
                self.stepper.events.clear()
                self.costs["integrate"] += time.perf_counter() - t0
            except Exception as e:  # noqa: BLE001 - e.g. numba errors from extreme values:
                raise_if_stop(e)
                if n > due:
                    # Computing ahead failed: go on with the due samples only, from the last
                    # published one, so the failure stops the system where it would anyway.
                    self._ahead_failed = True
                    try:
                        self._rewind()
                        continue
                    except Exception as again:  # noqa: BLE001 - as above
                        raise_if_stop(again)
                        e = again
                self._fail(str(e) if isinstance(e, IntegrationError)
                           else f"integration failed: {_reason(e)}")  # this system only
                break
            block = self._prepare(times, Y)
            if n > due:
                self._ahead = block
            published += self._release(block, min(due, block.left))
        return published

    @property
    def finished(self) -> bool:
        """No sample left before ``end_time``, or stopped by a failure."""
        return bool(self.failed) or (self.end_time is not None and math.floor(
            (self.end_time - self.t) * self.publish_rate + 1e-9) <= 0)

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

    def destroy_node(self) -> None:
        self.outlet.hand_over()  # what was published reaches the sinks
        super().destroy_node()

    # --- real-time pacing (only when not stepped by the caller) ---------------------------
    def _start_realtime(self) -> None:
        """(Re)start the one pacing timer from the current state."""
        if self._timer is not None:
            self.destroy_timer(self._timer)
            self._timer = None
        if self.stepped or self.real_time_factor <= 0:
            return
        self._wall0 = time.monotonic()
        self._sim0 = self.t
        self.lookahead = paced_lookahead(self.publish_rate, self.real_time_factor)
        period = max(1.0 / (self.publish_rate * self.real_time_factor), 0.005)
        self._timer = self.create_timer(period, self._on_tick, clock=self._steady)

    def _on_tick(self) -> None:
        target = self._sim0 + self.real_time_factor * (time.monotonic() - self._wall0)
        # At most one block per tick, so services and parameters are served in between.
        self.advance_to(min(target, self.t + _BLOCK / self.publish_rate))

    # --- services -------------------------------------------------------------------------
    def _on_reset(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        try:
            self._restart()
        except Exception as e:  # noqa: BLE001 - answered, never raised into the executor
            raise_if_stop(e)
            response.success = False
            response.message = f"{self.instance.name}: reset failed: {_reason(e)}"
            return response
        response.success = True
        response.message = f"{self.instance.name} reset to t = 0"
        return response

    def set_paused(self, paused: bool) -> None:
        """Pause or resume (pacing restarts from the current state, so no catching up)."""
        self.paused = paused
        self.outlet.hand_over()
        if not paused:
            self._start_realtime()

    def _on_pause(self, request: SetBool.Request, response: SetBool.Response) -> Any:
        self.set_paused(bool(request.data))
        response.success = True
        response.message = "paused" if self.paused else "running"
        return response

    def _restart(self) -> None:
        self._start()
        self._start_realtime()

    # --- parameters: validate completely, then commit -----------------------------------
    def _validate_parameters(self, params: list[RosParameter]) -> SetParametersResult:
        try:
            change = self._plan(params)
        except MechsimError as e:
            return SetParametersResult(successful=False, reason=str(e))
        except Exception as e:  # noqa: BLE001 - a rejected set, never an executor error
            raise_if_stop(e)
            names = ", ".join(p.name for p in params)
            return SetParametersResult(successful=False, reason=f"{names}: {_reason(e)}")
        self._pending = change
        return SetParametersResult(successful=True)

    def _plan(self, params: list[RosParameter]) -> _Change:
        """Everything the set would do, built and checked; raises MechsimError otherwise."""
        values = dict(self.values)
        settings = {name: float(getattr(self, name)) for name in SETTINGS}
        method = self.method
        for prm in params:
            name, value = prm.name, prm.value
            if name in self.spec:
                values[name] = self.spec[name].validate(value)
            elif name == "method":
                if not isinstance(value, str) or value not in METHODS:
                    raise ParameterError(name, f"must be one of {', '.join(METHODS)} (got "
                                         f"{shown(value)})")
                method = value
            elif name in SETTINGS:
                settings[name] = float(SETTINGS[name].validate(value))
                if name == "real_time_factor" and settings[name] == 0:
                    raise ParameterError(name, "must be > 0 for a node that paces itself "
                                         "(0 means stepped by a runner; ~/pause stops it)")
        change = _Change(_key(params), values, method, settings["tolerance"],
                         settings["publish_rate"], settings["real_time_factor"],
                         settings["constraint_limit"], settings["effort_timeout"],
                         settings["effort_wait"])
        model = self.model
        if values != self.values:
            model = self.cls(**values)  # every check of the model (cheap: no derivation yet)
            if any(self.spec[k].kind is not float and values[k] != self.values[k]
                   for k in values):
                # New equations of motion, possibly: derived and compiled in a child process
                # with a time limit, never unbounded in this executor.
                prepare_model(self.instance.system, values, method, change.tolerance,
                              self.prepare_timeout)
            change.model = model
            change.structural = (model.kernels is not self.model.kernels
                                  or model.initial_y().size != self.stepper.y.size)
        try:
            if change.structural:
                change.stepper = make_stepper(model, method, change.tolerance)
            elif change.model is not None or method != self.method \
                    or change.tolerance != self.tolerance:
                # Continues from the current state (an initial value waits for a reset).
                change.stepper = make_stepper(model, method, change.tolerance, t0=self.t,
                                              y0=self._y.copy())
        except MechsimError:
            raise
        except Exception as e:  # noqa: BLE001 - e.g. a division by zero at extreme values
            raise_if_stop(e)
            names = ", ".join(p.name for p in params)
            raise MechsimError(f"{names}: cannot integrate with these values "
                               f"({_reason(e)})") from None
        return change

    def _apply_parameters(self, params: list[RosParameter]) -> None:
        change, self._pending = self._pending, None
        if change is None or change.key != _key(params):
            return  # not the set just validated (cannot happen with rclpy's order)
        try:
            self._commit(change)
        except Exception as e:  # noqa: BLE001 - never out of the executor: this system stops
            raise_if_stop(e)
            self._fail(f"applying {', '.join(p.name for p in params)} failed: {_reason(e)}")

    def _commit(self, c: _Change) -> None:
        self._drop_ahead()  # every change applies from the next sample
        repace = (c.publish_rate != self.publish_rate
                  or c.real_time_factor != self.real_time_factor)
        self.values, self.method, self.tolerance = c.values, c.method, c.tolerance
        self.publish_rate, self.real_time_factor = c.publish_rate, c.real_time_factor
        self.constraint_limit = c.constraint_limit
        self.effort_timeout, self.effort_wait = c.effort_timeout, c.effort_wait
        if c.structural:
            assert c.model is not None and c.stepper is not None
            self.epoch += 1
            self._install(c.model, c.stepper)
            self._start_realtime()
            return
        if c.model is not None:
            self.model = c.model
            self.factory.model = c.model
            self.encoder = ChunkEncoder(self.factory)
            self.p = c.model.parameter_vector()
            self._set_constraints()
            self.epoch += 1
        if c.stepper is not None:
            self.stepper = c.stepper
        if c.model is not None or c.stepper is not None:
            self._effort_reset(new_epoch=c.model is not None)
        if c.model is not None or c.stepper is not None:
            self._publish_static()
        if c.model is not None:
            # The current sample again, with the new parameters and the same stamp: a stamp
            # not later than the previous one is the diagnostics node's signal of a new epoch.
            self._emit(np.array([self.t]), self._y.copy()[None, :])
        if repace:
            self._start_realtime()

    # --- effort input: generalized forces from a controller (see the module docstring) ----
    def _setup_effort(self) -> None:
        self.effort_received = 0  # commands accepted
        self.effort_rejected = 0  # commands ignored (each with a throttled warning)
        #: Set by a runner that steps this node (fast mode): serve its executor once, waiting
        #: up to the given wall seconds (``_await_command``).
        self.serve: Callable[[float], None] | None = None
        self._effort_lock = threading.Lock()
        self._effort_logged: dict[str, float] = {}
        self._effort_topic = self.resolve_topic_name("effort")
        self._inbox: np.ndarray | None = None  # newest accepted command, not applied yet
        self._answered = -1  # samples_published when the latest command arrived
        self._effort_sub = self.create_subscription(
            Float64MultiArray, "effort", self._on_effort, STATE_QOS,
            callback_group=MutuallyExclusiveCallbackGroup())

    def _effort_reset(self, new_epoch: bool) -> None:
        """A new model or stepper starts without effort (as its parameter vector); the next
        command applies again. A new epoch also restores the full set of laws."""
        with self._effort_lock:
            self._inbox = None
        #: Where the effort sits in the parameter vector (None: the model takes none).
        self._effort_at = at = self.model.effort_slice()
        if at is not None:
            self.p[at] = 0.0
        self._held_until: float | None = None  # effort held (nonzero) until this sim time
        if new_epoch:
            self._effort_acted = False

    def _on_effort(self, msg: Float64MultiArray) -> None:
        u = np.asarray(msg.data, dtype=np.float64)
        at, names = self._effort_at, [c.name for c in self.model.coordinates]
        if at is None:
            self._reject("system", f"{self.model.id} ({self.model.formulation}) takes no "
                         "effort (its kernels are not derived from a Lagrangian)")
        elif self.stepper.method not in Stepper.TAKES_INPUTS:
            self._reject("method", f"method {self.stepper.method} integrates without the "
                         "effort: use dop853, dopri5, radau15 or auto")
        elif u.size != len(names):
            self._reject("length", f"{u.size} values, expected {len(names)} (one per "
                         f"coordinate: {', '.join(names)})")
        elif not np.isfinite(u).all():
            i = int(np.argmin(np.isfinite(u)))
            self._reject("finite", f"value {i} ({names[i]}) is {u[i]}, not finite")
        else:
            with self._effort_lock:
                self._inbox = u
            self.effort_received += 1
        self._answered = self.samples_published

    def _reject(self, kind: str, reason: str) -> None:
        self.effort_rejected += 1
        now = time.monotonic()
        if now - self._effort_logged.get(kind, -math.inf) >= _EFFORT_LOG_PERIOD:
            self._effort_logged[kind] = now
            self.get_logger().warning(f"{self._effort_topic}: command ignored: {reason}")

    def _closed_loop(self) -> bool:
        """Something publishes commands to a system that takes them (a publisher matched
        with the effort subscription: asked of the subscription, ~1 µs, not of the graph,
        ~20 µs with a scene's 36 nodes in it)."""
        return self._effort_at is not None and self._effort_sub.get_publisher_count() > 0

    def _effort_step(self) -> bool:
        """Before the next sample period (from ``self.t``): apply the newest command, or zero
        once the held effort has timed out. True when the node must step sample by sample: an
        effort is held (its timeout falls on a sample) or a controller is present."""
        at = self._effort_at
        if at is None:
            return False
        closed = self._closed_loop()
        if closed:
            self._await_command()
        with self._effort_lock:
            u, self._inbox = self._inbox, None
        if u is not None:
            self._held_until = self.t + self.effort_timeout if u.any() else None
        elif self._held_until is not None and self.t >= self._held_until - 1e-9 / \
                self.publish_rate:
            u, self._held_until = np.zeros(at.stop - at.start), None
        if u is not None and u.size == at.stop - at.start and not np.array_equal(u, self.p[at]):
            self._apply_effort(at, u)
        return self._held_until is not None or closed

    def _apply_effort(self, at: slice, u: np.ndarray) -> None:
        """The effort ``u`` from the current sample on: the stepper restarts there with it
        (no step crosses a change of the held value); the change goes to the sinks."""
        if self.stepper.method not in Stepper.TAKES_INPUTS:
            return  # the method changed after the command was accepted: dropped with it
        p = self.p.copy()
        p[at] = u
        self.stepper.restart(self.t, self._y, p)
        self.p = p
        ns = messages.stamp_ns(self.t, self.time_offset)
        self.outlet.record(self._effort_topic, Float64MultiArray(data=u.tolist()), STATE_QOS,
                           ns)
        if u.any() and not self._effort_acted:
            self._effort_acted = True
            self._publish_static()  # system_info: only the laws that hold under an effort

    def _await_command(self) -> None:
        """Stepped closed loop: unless a command arrived since the last sample was published,
        serve the executor until one does (the controller's answer to that sample, applied
        from it on), at most ``effort_wait`` wall seconds."""
        if self.serve is None or self.effort_wait <= 0:
            return
        end = time.monotonic() + self.effort_wait
        while self._answered < self.samples_published:
            left = end - time.monotonic()
            if left <= 0 or self.failed:
                break
            self.serve(min(left, 0.05))
