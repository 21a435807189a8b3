"""The topics of one simulated system: how its run's samples become messages on an Outlet.

:class:`SystemTopics` is the observer of a node's ``SystemRun`` (``mechsim.runcore.run``): it
says which outputs something consumes (a subscriber or a sink), encodes each block of samples
for every topic at once (``ChunkEncoder``: CDR rows only where someone reads bytes, values as
columns only for a sink that takes them), publishes the samples as the run releases them,
publishes system_info and /tf_static when what runs changes, records each applied effort, and
reports a stopped system on /diagnostics. Stamps are simulation time + ``time_offset``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, TwistStamped
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from visualization_msgs.msg import MarkerArray

from mechsim.outputs import batch, messages
from mechsim.outputs.markers import MarkerEncoder, cleared, drawn, topics_of
from mechsim.outputs.messages import Chunk, ChunkEncoder, MessageFactory, Sample
from mechsim.ros.outlet import (
    CLOCK_QOS,
    DIAGNOSTICS_QOS,
    LATCHED_QOS,
    STATE_QOS,
    TF_QOS,
    Outlet,
)
from mechsim.runcore.run import Block, SystemRun
from mechsim.scene import Instance
from mechsim.systems.base import Model
from mechsim_msgs.msg import Energy, NamedScalars, SampleBatch, SystemInfo
from tf2_msgs.msg import TFMessage

#: Wall seconds between two effort notices (WARN on /diagnostics and a log line) of a node.
EFFORT_NOTICE_PERIOD = 5.0

#: (topic, CDR rows or None, message of sample i): one topic of an encoded block.
Topic = tuple[str, np.ndarray | None, Callable[[int], Any]]
#: (topic, what makes its messages of samples i to j as (sample, CDR bytes)): a topic of an
#: encoded block with messages at some samples only (``Outlet.publish_chunk``).
Sparse = tuple[str, Callable[[int, int], list[tuple[int, bytes]]]]


class Encoded(NamedTuple):
    """A block of samples ready for the Outlet (``Outlet.publish_chunk``); ``sparse``: the
    topics with messages at some of its samples only (the batch topic, where something takes
    it; the trail bodies)."""

    ns: np.ndarray
    topics: list[Topic]
    columns: dict[str, Any]
    sparse: list[Sparse]


def _builder(build: Callable[[Sample, int], Any], sample: Callable[[int], Sample],
             ns: np.ndarray) -> Callable[[int], Any]:
    """The message of sample i, built only for a sink that takes messages."""
    return lambda i: build(sample(i), int(ns[i]))


def _sampler(times: np.ndarray, c: Chunk) -> Callable[[int], Sample]:
    def sample(i: int) -> Sample:
        return Sample(float(times[i]), c.q[i], c.v[i], float(c.work[i, 0]),
                      float(c.work[i, 1]),
                      None if c.energy is None else c.energy[i],
                      None if c.invariants is None else c.invariants[i],
                      None if c.observables is None else c.observables[i],
                      None if c.frames is None else c.frames[i])
    return sample


class SystemTopics:
    """The publishers of one system's node and what its run releases on them."""

    def __init__(self, node: Node, outlet: Outlet, instance: Instance, time_offset: float,
                 publish_clock: bool, effort_publishers: Callable[[], int]) -> None:
        """``effort_publishers``: how many publishers the node's effort subscription has."""
        self.node, self.outlet, self.instance = node, outlet, instance
        self.time_offset = time_offset
        self.publish_clock = publish_clock
        self.effort_publishers = effort_publishers
        self.run: SystemRun  # set once the run exists (it observes through this object)
        o = outlet
        self.t_energy = o.channel("energy", Energy, STATE_QOS)
        self.t_info = o.channel("system_info", SystemInfo, LATCHED_QOS)
        self.t_diag = o.channel("/diagnostics", DiagnosticArray, DIAGNOSTICS_QOS)
        self.t_batch = o.channel(batch.TOPIC, SampleBatch, STATE_QOS)
        if publish_clock:
            self.t_clock = o.channel("/clock", ClockMsg, CLOCK_QOS)
        self.t_effort = node.resolve_topic_name("effort")
        #: The topics only some models have (``model_channels``): "" until one has them.
        self.t_state = self.t_pose = self.t_twist = self.t_inv = self.t_obs = ""
        self.t_tf = self.t_tf_static = self.t_markers = self.t_markers_static = ""
        self.t_trails = self.t_curves = ""
        #: Wall seconds spent encoding and publishing.
        self.costs = {"encode": 0.0, "publish": 0.0}
        self._dynamic_frames = False
        self._effort_noticed = -math.inf
        #: What the block being made carries: /tf (moving frames), markers, a batch.
        self._moved = self._drawn = self._batched = False
        self.markers: MarkerEncoder | None = None
        #: The look last published on markers_static (``MarkerEncoder.look``), and what a new
        #: model's look asks for at its first sample: (markers_static, clear <ns>/markers).
        self._look: bytes | None = None
        self._redraw = (False, False)

    def model_channels(self, model: Model) -> None:
        """The topics of what ``model`` has, each advertised once one has it (kept if a later
        formulation has none): state (joint-like coordinates), pose and twist (an attitude),
        invariants, observables, /tf (moving frames), /tf_static (fixed frames), markers
        (links and trails: ``Model.visuals``, per sample), markers_static (the frame-locked
        visuals, latched: once per look), markers_trails (the trails' older points, latched:
        where they change), curves (``Model.curves``, latched: once per
        parameter set, with system_info). A topic nothing is ever published on is never
        advertised."""
        o, frames = self.outlet, model.frames
        fixed, moving = topics_of(model)
        trails = any(v.kind == "trail" for v in drawn(model)) if moving else False
        quaternion = set(model.attitude.quaternion) if model.attitude is not None else set()
        wanted = (
            ("t_state", "state", JointState, STATE_QOS,
             len(model.coordinates) > len(quaternion)),
            ("t_pose", "pose", PoseStamped, STATE_QOS, model.attitude is not None),
            ("t_twist", "twist", TwistStamped, STATE_QOS, model.attitude is not None),
            ("t_inv", "invariants", NamedScalars, STATE_QOS, bool(model.invariants)),
            ("t_obs", "observables", NamedScalars, STATE_QOS, bool(model.observables)),
            ("t_tf", "/tf", TFMessage, TF_QOS, any(not f.static for f in frames)),
            ("t_tf_static", "/tf_static", TFMessage, LATCHED_QOS, any(f.static for f in frames)),
            ("t_markers", "markers", MarkerArray, STATE_QOS, moving),
            ("t_markers_static", "markers_static", MarkerArray, LATCHED_QOS, fixed),
            ("t_trails", "markers_trails", MarkerArray, LATCHED_QOS, trails),
            ("t_curves", "curves", MarkerArray, LATCHED_QOS, bool(model.curves())))
        for attr, topic, msg_type, qos, has in wanted:
            if has and not getattr(self, attr):
                setattr(self, attr, o.channel(topic, msg_type, qos))

    # --- the run's observer -------------------------------------------------------------------
    def model_changed(self, model: Model, structural: bool) -> None:
        if structural:
            self.factory = MessageFactory(model, self.instance.name, self.instance.origin,
                                          self.time_offset)
            self.model_channels(model)
        else:
            self.factory.model = model
        self.encoder = ChunkEncoder(self.factory)
        self.batches = batch.BatchEncoder(self.factory)
        self._dynamic_frames = any(not fr.static for fr in model.frames)
        previous, self.markers = self.markers, None
        if (self.t_markers or self.t_markers_static) and model.frames and model.visuals():
            self.markers = MarkerEncoder(model, self.instance.name, self.instance.origin)
            if previous is not None and not structural:
                self.markers.take_trails(previous)
        self._redraw = self._look_changes(previous)

    def _look_changes(self, previous: MarkerEncoder | None) -> tuple[bool, bool]:
        """What the new model's look asks for: its frame-locked markers published (a look
        not published yet: the first, or one a parameter changed), and the moving markers
        cleared (an earlier model drew some this one does not replace)."""
        new = self.markers
        look = new.look if new is not None else None
        fixed = bool(self.t_markers_static) and look != self._look
        self._look = look
        before = previous.moving_ids if previous is not None else []
        clear = bool(self.t_markers and before) \
            and (new is None or new.moving_ids[:len(before)] != before)
        return fixed, clear

    def _publish_look(self) -> None:
        """The look's markers due since the model changed (``_look_changes``), stamped
        with the current sample: a bag then draws each look from where it applies."""
        fixed, clear = self._redraw
        self._redraw = (False, False)
        ns = messages.stamp_ns(self.run.t, self.time_offset)
        if clear:
            self.outlet.publish(self.t_markers, cleared(self.instance.name, ns), ns)
        if fixed:
            msg = self.markers.fixed(ns) if self.markers is not None \
                else cleared(self.instance.name, ns)
            self.outlet.publish(self.t_markers_static, msg, ns)

    def laws_changed(self) -> None:
        """system_info (what runs, the laws that hold and their scales) and /tf_static."""
        run = self.run
        model = run.model
        ns0 = messages.stamp_ns(0.0, self.time_offset)
        laws = model.laws_under_effort() if run.effort.acted else model.laws()
        scales = model.law_scales()
        info = self.factory.system_info(ns0, run.stepper.method, run.settings.tolerance,
                                        [law.key for law in laws],
                                        [scales[law.key] for law in laws])
        self.outlet.publish(self.t_info, info, ns0)
        if self.t_curves:
            self.outlet.publish(self.t_curves, self.factory.curves(ns0), ns0)
        if any(f.static for f in model.frames):
            msg = TFMessage(transforms=self.factory.transforms(run.static_frames(), ns0,
                                                                 static=True))
            self.outlet.publish(self.t_tf_static, msg, ns0)
        self._publish_look()

    def wanted(self) -> tuple[str, ...]:
        """The outputs something consumes now (subscribers counted again)."""
        o, shape = self.outlet, self.run.shape
        o.refresh()
        want = []
        # A batch carries every named value the model has.
        self._batched = every = o.wanted(self.t_batch)
        if every or o.wanted(self.t_energy):
            want.append("energy")
        if shape.invariants and (every or o.wanted(self.t_inv)):
            want.append("invariants")
        if shape.observables and (every or o.wanted(self.t_obs)):
            want.append("observables")
        self._moved = self._dynamic_frames and o.wanted(self.t_tf)
        self._drawn = self.markers is not None and self.markers.layout is not None \
            and (o.wanted(self.t_markers) or bool(self.t_trails) and o.wanted(self.t_trails))
        if self._moved or self._drawn:
            want.append("frames")
        return tuple(want)

    def encode(self, block: Block) -> None:
        """Every topic of the block's samples, each encoded for the whole block at once."""
        t0 = time.perf_counter()
        at = self.run.model.layout
        Y, out = block.Y, block.outputs
        ns = messages.stamps_ns(block.times, self.time_offset)
        c = Chunk(ns, Y[:, at.q], block.rates,
                  Y[:, [at.work_external, at.work_dissipated]],
                  out.get("energy"), out.get("invariants"), out.get("observables"),
                  out.get("frames"))
        columns: dict[str, Any] = {}
        topics: list[Topic] = []
        sparse: list[Sparse] = []
        if block.times.size:
            columns = self._columns(c)
            topics = self._topics(c, _sampler(block.times, c), block.times)
            if self._drawn and self.t_trails and self.markers is not None \
                    and self.markers.trails and c.frames is not None:
                sparse.append((self.t_trails, self.markers.bodies()))
            if self._batched:
                times, make = block.times, self.batches.encode
                sparse.append((self.t_batch, lambda a, b: [
                    (k, make(times, c, k, min(k + batch.MAX_SAMPLES, b)))
                    for k in range(a, b, batch.MAX_SAMPLES)]))
        block.encoded = Encoded(ns, topics, columns, sparse)
        self.costs["encode"] += time.perf_counter() - t0

    def _columns(self, c: Chunk) -> dict[str, Any]:
        """The values as columns, only for a sink that takes them (``needs_columns``)."""
        f, needs = self.factory, self.outlet.needs_columns
        columns: dict[str, Any] = {}
        if c.energy is not None and needs(self.t_energy):
            columns[self.t_energy] = messages.EnergyColumns.of(c)
        if c.invariants is not None and needs(self.t_inv):
            columns[self.t_inv] = {name: c.invariants[:, j]
                                   for j, name in enumerate(self.run.shape.invariants)}
        if c.observables is not None and needs(self.t_obs):
            columns[self.t_obs] = {name: c.observables[:, j]
                                   for j, name in enumerate(f.observable_names)}
        if c.frames is not None and self._moved and needs(self.t_tf):
            columns[self.t_tf] = f.transform_columns(c.frames, c.placed_frames(f))
        if f.joints and needs(self.t_state):
            columns[self.t_state] = {f.coordinate_names[j]: c.q[:, j] for j in f.joints}
        return columns

    def _topics(self, c: Chunk, sample: Callable[[int], Sample],
                times: np.ndarray) -> list[Topic]:
        """Each topic's CDR rows (only where someone reads bytes) and message builder."""
        f, enc, ns = self.factory, self.encoder, c.ns
        needs_rows = self.outlet.needs_rows

        def rows(key: str, topic: str) -> np.ndarray | None:
            return enc.encode(key, c) if needs_rows(topic) else None

        topics: list[Topic] = []
        if self.publish_clock:
            topics.append((self.t_clock, rows("clock", self.t_clock),
                           lambda i: messages.clock(int(ns[i]))))
        if f.joints:
            topics.append((self.t_state, rows("state", self.t_state),
                           _builder(f.state, sample, ns)))
        if f.attitude is not None:
            topics.append((self.t_pose, rows("pose", self.t_pose), _builder(f.pose, sample, ns)))
            topics.append((self.t_twist, rows("twist", self.t_twist),
                           _builder(f.twist, sample, ns)))
        for key, topic, build, values in (("energy", self.t_energy, f.energy, c.energy),
                                          ("invariants", self.t_inv, f.invariants,
                                           c.invariants),
                                          ("observables", self.t_obs, f.observables,
                                           c.observables),
                                          ("tf", self.t_tf, f.tf, c.frames)):
            if values is not None and (key != "tf" or self._moved):
                topics.append((topic, rows(key, topic), _builder(build, sample, ns)))
        if self._drawn and c.frames is not None:
            assert self.markers is not None
            drawn = self.markers.encode(times, ns, c.placed_frames(f),
                                        self.run.settings.publish_rate,
                                        c.time_rows() if ns.shape[0] > 1 else None)
            markers = self.markers

            def marker_message(i: int, d: np.ndarray = drawn) -> MarkerArray:
                return markers.message(d[i])

            topics.append((self.t_markers, drawn, marker_message))
        return topics

    def release(self, block: Block, a: int, b: int) -> None:
        t0 = time.perf_counter()
        ns, topics, columns, sparse = block.encoded
        size = block.times.size
        self.outlet.publish_chunk(ns, topics, columns,
                                  None if a == 0 and b == size else slice(a, b), sparse)
        if b == size:
            self.outlet.hand_over()  # the block's samples to the sinks, at once
        self.costs["publish"] += time.perf_counter() - t0

    def flush(self) -> None:
        self.outlet.hand_over()

    def effort_applied(self, u: np.ndarray) -> None:
        """The applied effort to the sinks, stamped with the sample from which it applies."""
        ns = messages.stamp_ns(self.run.t, self.time_offset)
        self.outlet.record(self.t_effort, Float64MultiArray(data=u.tolist()), STATE_QOS, ns)

    def stopped(self, reason: str) -> None:
        """ERROR on /diagnostics, one log line."""
        name, t = self.instance.name, self.run.t
        self.node.get_logger().error(f"{name}: integration stopped: {reason}")
        ns = messages.stamp_ns(t, self.time_offset)
        status = DiagnosticStatus(level=DiagnosticStatus.ERROR,
                                  name=f"mechsim/{name}/integration",
                                  message=f"stopped: {reason}", hardware_id=name,
                                  values=[KeyValue(key="t", value=f"{t:.9g}")])
        msg = DiagnosticArray(header=self.factory.header(ns), status=[status])
        self.outlet.publish(self.t_diag, msg, ns)

    def effort_notice(self, message: str) -> None:
        """WARN on /diagnostics (``mechsim/<ns>/effort``) and one log line, at most one of
        each every ``EFFORT_NOTICE_PERIOD`` wall seconds (a peer can cause many)."""
        now = time.monotonic()
        if now - self._effort_noticed < EFFORT_NOTICE_PERIOD:
            return
        self._effort_noticed = now
        name, t = self.instance.name, self.run.t
        self.node.get_logger().warning(f"{name}: {message}")
        ns = messages.stamp_ns(t, self.time_offset)
        status = DiagnosticStatus(level=DiagnosticStatus.WARN, name=f"mechsim/{name}/effort",
                                  message=message, hardware_id=name,
                                  values=[KeyValue(key="t", value=f"{t:.9g}")])
        self.outlet.publish(self.t_diag, DiagnosticArray(header=self.factory.header(ns),
                                                         status=[status]), ns)

    def controller_present(self) -> bool:
        """A publisher matched with the effort subscription (asked of the subscription, not
        of the graph: a scene's graph holds dozens of nodes)."""
        return self.effort_publishers() > 0
