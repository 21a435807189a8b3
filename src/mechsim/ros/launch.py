"""A scene in one process: every simulator node and the diagnostics node, stepped in lockstep
by one loop. Used by ``mechsim run`` and ``mechsim record`` (one process per node:
``mechsim.ros.processes``; the graph check before a start: ``mechsim.ros.graph_check``).

The loop steps every node's run to the same simulated time: a chunk of ``FAST_CHUNK`` samples
per step as fast as possible (several for a scene of few nodes, ``FAST_CHUNKS``), or, paced,
the samples the wall clock has made due (each node computing ahead and releasing them as they
become due, ``mechsim.runcore.pacing``). Services, parameter sets and subscriptions are served
from a thread of their own between steps (``serving``). The diagnostics node is fed in-process
(``feed``: lossless) and reports once per ``diagnostics_period`` of simulated time. Ctrl-C /
SIGTERM stop the run cleanly; every published sample reaches the sinks however it ends.
"""

from __future__ import annotations

import contextlib
import gc
import math
import signal
import threading
import time
import warnings
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from mechsim.ros.feed import DiagnosticsFeed
from mechsim.ros.graph_check import GraphCheck, discovery_window, joined_context, window_setting
from mechsim.runcore.stops import held_signals

if TYPE_CHECKING:
    from mechsim.scene import Scene

#: Samples per chunk in fast mode (each node steps, evaluates and encodes them in blocks of
#: ``pacing.BLOCK``). A service or parameter request waits one chunk at most.
FAST_CHUNK = 1000
#: A scene of fewer nodes than this steps each of them by this many chunks at a time divided
#: by the number of nodes (so its chunk holds no more samples than a four-node scene's): a
#: run releases several blocks in one go (``SystemRun.advance_to``), fewer trips through the
#: loop and its serving.
FAST_CHUNKS = 4
#: Nodes whose parameter services a paced scene makes per tick once its samples flow (a
#: scene as fast as possible makes every node's after its first chunk).
PARAMETER_SERVICES_PER_CHUNK = 10
#: Longest wall wait [s] of a paced scene between two looks at its nodes (all paused: how
#: soon a resume is seen; otherwise the next sample due wakes it earlier).
_IDLE_WAIT = 0.1


@dataclass
class SceneRun:
    """What a finished run reports."""

    scene: Scene
    sim_time: float
    wall_time: float  # stepping and publishing, after start-up
    startup_time: float  # building the nodes (kernel loading or compilation)
    samples: dict[str, int]
    messages: dict[str, int]
    summary: list[tuple[str, str, float, int]] = field(default_factory=list)
    failures: dict[str, str] = field(default_factory=dict)
    interrupted: bool = False
    #: The instances an effort acted on: from then on only the laws that hold under an
    #: outside force were checked (``Model.laws_under_effort``).
    efforts: list[str] = field(default_factory=list)
    #: Wall seconds per stage of the sample pipeline, all nodes together: integrate,
    #: evaluate, encode, publish (including the hand-off to sinks), diagnostics (the
    #: in-process law tracking and reports); a recording adds write (the bag writer thread).
    costs: dict[str, float] = field(default_factory=dict)
    #: Seconds from the start to every node serving its parameters (``ros2 param``): a
    #: scene's nodes make those services once the samples flow; None if the run ended first.
    parameters_served_time: float | None = None


class _Stop(BaseException):
    """SIGTERM during a run: a stop, like KeyboardInterrupt, never taken for an error."""


def _warm(scene: Scene) -> None:
    """Load every instance's kernels now (its model, built once when the scene was parsed,
    keeps them for its node), while discovery runs."""
    for inst in scene.systems:
        _ = inst.build().kernels


def _answers_to_the_check_unheard() -> None:
    """A node of ours shares its name with a node the check asked (one that did not answer:
    a killed process's entry): the check's requests reached our node too, which answers them
    once it is served, to a client gone with the check. rclpy warns of every such answer;
    they are ours to drop, not the user's to read."""
    warnings.filterwarnings("ignore", message="failed to send response",
                            category=RuntimeWarning, module="rclpy.service")


def run_scene(scene: Scene, *, fast: bool | None = None, duration: float | None = None,
              sinks: list[Any] | None = None, context: Any = None,
              progress: Callable[[float, float], None] | None = None,
              diagnostics_period: float = 1.0, graph_wait: float | None = None,
              lossless: bool = False,
              before_first_message: Callable[[Any], None] | None = None) -> SceneRun:
    """Run every system of ``scene`` in this process until ``duration`` (simulated seconds)
    or Ctrl-C / SIGTERM. ``fast``: as fast as possible instead of the scene's pacing.
    ``graph_wait``: discovery seconds before the graph check (0: no check); by default
    ``discovery_window()`` when this call makes its own context (a command), none with a caller's
    context (the caller, e.g. a test or a host application, owns its graph).
    ``lossless``: every reliable subscriber gets every sample (the run waits for the slowest);
    ``before_first_message``: called with each simulator node before it publishes."""
    from mechsim.environment import import_rclpy

    import_rclpy()  # the ROS environment set before rclpy is imported
    own_context = context is None
    # Before this call makes a context: a refused window must not leave one behind.
    if graph_wait is None:
        graph_wait = discovery_window() if own_context else 0.0
    else:
        graph_wait = window_setting(graph_wait, "graph_wait")
    joined_at = None
    if own_context:
        context, joined_at = joined_context()  # joined already by the command, if it did
    loop = _SceneLoop(scene, context, sinks, diagnostics_period, lossless,
                      fast=(scene.pacing == "fast" or scene.real_time_factor == 0)
                      if fast is None else fast,
                      duration=duration if duration is not None else scene.duration)
    main_thread = threading.current_thread() is threading.main_thread()
    previous_term = signal.getsignal(signal.SIGTERM)

    def on_term(signum: int, frame: Any) -> None:
        raise _Stop()

    interrupted = False
    try:
        if main_thread:
            signal.signal(signal.SIGTERM, on_term)
        loop.start(graph_wait, joined_at, before_first_message)
        loop.run(progress)
    except (KeyboardInterrupt, _Stop):
        interrupted = True
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, previous_term)
        run = loop.finish(interrupted)
        if own_context:
            context.try_shutdown()
    return run


def check_given(nodes: list[Any], *others: Any) -> None:
    """The nodes of one process: no two of the same name (a ``-r __ns:=`` remap of a scene of
    several systems), and every value given from outside (``--ros-args``) a parameter of one
    of them (ParameterError naming it otherwise: a typo would silently do nothing)."""
    from mechsim.errors import ParameterError

    names = [n.get_fully_qualified_name() for n in nodes]
    for name in names:
        if names.count(name) > 1:
            raise ParameterError("--ros-args", f"two simulator nodes named {name}: remap "
                                 "the namespace only for a scene of one system")
    unused = set.intersection(*(set(n.start.unused) for n in nodes)) if nodes else set()
    for other in others:
        unused = {name for name in unused if not other.has_parameter(name)}
    if unused:
        raise ParameterError(sorted(unused)[0], "not a parameter of any node of the scene")


@contextlib.contextmanager
def _start_frozen() -> Iterator[None]:
    """The objects alive as the loop starts (modules, nodes, kernels, the caller's own: most
    outlive the run) left out of the garbage collector's passes until it ends
    (``gc.freeze``), so a full collection during the run traverses only what the run made
    since instead of the whole heap (``gc.get_objects()`` does not list them meanwhile).
    Undone after; left alone if the caller froze objects of its own."""
    if gc.get_freeze_count():
        yield
        return
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


class _SceneLoop:
    """The nodes of one in-process scene and the loop that steps them."""

    #: The graph check's discovery window runs while the nodes are made (False: the window
    #: elapses before the first node is made; ``mechsim bench --streaming`` compares both).
    overlap_window = True
    #: The nodes' parameter services (``ros2 param``) made once the samples flow
    #: (``_serve_parameters``; False: each node makes them as it is made; ``mechsim bench
    #: --streaming`` compares both).
    parameter_services_later = True

    def __init__(self, scene: Scene, context: Any, sinks: list[Any] | None,
                 diagnostics_period: float, lossless: bool, *, fast: bool,
                 duration: float | None) -> None:
        from rclpy.executors import SingleThreadedExecutor

        from mechsim.ros.diagnostics import DiagnosticsNode

        self.scene, self.context, self.fast, self.duration = scene, context, fast, duration
        self.lossless = lossless
        self.sinks = list(sinks or [])
        self.period = diagnostics_period
        self.nodes: list[Any] = []
        self.executor = SingleThreadedExecutor(context=context)
        self.diag = DiagnosticsNode(context=context, warn_drift=scene.warn_drift,
                                    error_drift=scene.error_drift, period=3600.0,
                                    sinks=self.sinks, discover=False)
        self.feed = DiagnosticsFeed(self.diag)
        self.t = 0.0
        self.k = 0  # samples of the scene's rate stepped (as fast as possible)
        self.started = time.monotonic()
        self.startup = 0.0
        self.diag_cost = 0.0
        self._unserved = 0  # nodes before this one serve their parameters
        self.parameters_served: float | None = None  # seconds from the start

    def start(self, graph_wait: float, joined_at: float | None,
              before_first_message: Callable[[Any], None] | None) -> None:
        """The simulator nodes made while the graph check's discovery window runs (kernels
        loaded first), each stepped by this loop (real_time_factor 0: the node never paces
        itself) and never past the duration. Until the check has passed, the nodes publish
        no sample and nothing serves their services or parameters (nothing spins them: a
        refused start destroys them unanswered); our own nodes are not in the way."""
        from mechsim.ros.simulator import SimulatorNode

        scene = self.scene
        names = [i.name for i in scene.systems]
        graph = GraphCheck(self.context, joined_at) if graph_wait > 0 else None
        try:
            _warm(scene)
            if graph is not None and not self.overlap_window:
                graph.check(names, True, graph_wait)
            for i, inst in enumerate(scene.systems):
                if graph is not None:
                    graph.look(names, True, self.nodes)  # a conflict seen refuses at once
                self.nodes.append(SimulatorNode(
                    inst, context=self.context, publish_rate=scene.publish_rate,
                    real_time_factor=0.0 if self.fast else scene.real_time_factor,
                    stepped=True, publish_clock=(i == 0),
                    sinks=[*self.sinks, self.feed], end_time=self.duration,
                    lossless=self.lossless, before_first_message=before_first_message,
                    deferred=True, parameter_services=not self.parameter_services_later))
            check_given(self.nodes, self.diag)
            if graph is not None:
                graph.check(names, True, graph_wait, own=self.nodes)
        finally:
            if graph is not None:
                graph.close()
        if graph is not None and graph.asked & {n.get_fully_qualified_name() for n in self.nodes}:
            _answers_to_the_check_unheard()
        for n in self.nodes:
            n.begin()
        self.executor.add_node(self.diag)
        for n in self.nodes:
            self.executor.add_node(n)

    def run(self, progress: Callable[[float, float], None] | None) -> None:
        from mechsim.ros.serving import Serving
        from mechsim.runcore.pacing import Pacing, paced_lookahead

        scene, nodes = self.scene, self.nodes
        serving = Serving(self.executor)
        for i, n in enumerate(nodes):
            # A node stepping a closed loop waits for its controller's commands in between.
            n.run.serve = serving.wait
            if not self.fast:  # computed ahead, released as the wall clock makes them due
                n.run.lookahead = paced_lookahead(scene.publish_rate, scene.real_time_factor)
                # Each tick computes the blocks of a few nodes, not every node's at once.
                n.run.stagger = i * n.run.lookahead // len(nodes)
        self.startup = time.monotonic() - self.started
        self.started = time.monotonic()
        if not self.parameter_services_later:
            self.parameters_served = self.startup  # (every node made them as it was made)
        if not self.fast:
            for n in nodes:  # each run paced on its own: a reset or a pause restarts its own
                n.run.pacing = Pacing(scene.real_time_factor, n.publish_rate, self.started,
                                      n.t)
        next_diag = self.period
        with serving, _start_frozen():
            while not self._done():
                due = None if self.fast else self._wait_due(serving)
                with held_signals():
                    if due is None:
                        self._fast_chunk()
                    else:
                        self._advance_due(due)
                if all(n.failed for n in nodes):
                    break  # every system stopped with an error: nothing left to run
                if self.parameters_served is None:
                    with serving.paused():
                        self._serve_parameters()
                serving.let_in()  # a service or parameter request waits one chunk at most
                next_diag = self._report(next_diag)
                if progress is not None and self.duration is not None:
                    progress(min(self.t, self.duration), self.duration)
            self._hand_over()

    def _serve_parameters(self) -> None:
        """The parameter services of the nodes made without them: all of them after a fast
        scene's first chunk, ``PARAMETER_SERVICES_PER_CHUNK`` nodes a tick of a paced one (a
        tick's delay stays short); none left after that."""
        step = len(self.nodes) if self.fast else PARAMETER_SERVICES_PER_CHUNK
        end = min(self._unserved + step, len(self.nodes))
        for n in self.nodes[self._unserved:end]:
            n.serve_parameters()
        self._unserved = end
        if end == len(self.nodes):
            self.parameters_served = self.startup + time.monotonic() - self.started

    def _done(self) -> bool:
        """The duration reached: in simulated time of the scene (as fast as possible), by every
        node (paced: a node reset restarts its count)."""
        if self.duration is None:
            return False
        if self.fast:
            return self.t >= self.duration - 1e-12
        return all(n.finished for n in self.nodes)

    def _fast_chunk(self) -> None:
        """As fast as possible: every node to the end of the next chunk of the scene."""
        dt = 1.0 / self.scene.publish_rate
        self.k += FAST_CHUNK * max(1, FAST_CHUNKS // max(1, len(self.nodes)))
        t_next = self.k * dt if self.duration is None else min(self.k * dt, self.duration)
        for n in self.nodes:
            n.advance_to(t_next)
        self.t = t_next

    def _wait_due(self, serving: Any) -> list[Any]:
        """Paced: wait (callbacks served meanwhile) until a sample of some node is due; the
        nodes to advance then (none if all are paused: the loop serves and looks again)."""
        while True:
            active = [n for n in self.nodes
                      if not (n.failed or n.paused or n.finished) and n.run.pacing is not None]
            wake = min((n.run.pacing.next_due(n.t) for n in active), default=math.inf)
            wait = wake - time.monotonic()
            if wait <= 0:
                return active
            serving.wait(min(wait, _IDLE_WAIT))
            if not active:
                return []

    def _advance_due(self, nodes: list[Any]) -> None:
        """Paced: each node to the time its own pacing made due (``SystemRun.pacing``):
        latency within one sample period, and a node reset or resumed goes on from its current
        sample, never catching up on the time it did not run."""
        now = time.monotonic()
        for n in nodes:
            n.advance_to(n.run.pacing.due(now, n.t))
        self.t = max(self.t, *(n.t for n in self.nodes))

    def _hand_over(self) -> None:
        with held_signals():
            for n in self.nodes:
                n.outlet.hand_over()  # the samples published up to now

    def _report(self, next_diag: float) -> float:
        """A diagnostics report per period of simulated time, on the samples up to it.
        Returns when the next one is due."""
        from mechsim.outputs.messages import stamp_ns
        from mechsim.ros.outlet import DIAGNOSTICS_QOS

        t0 = time.perf_counter()
        if self.t >= next_diag - 1e-12:
            self._hand_over()
        offset = self.nodes[0].time_offset if self.nodes else 0.0
        stamps = []
        while self.t >= next_diag - 1e-12:
            stamps.append(stamp_ns(next_diag, offset))
            next_diag += self.period
        depth = DIAGNOSTICS_QOS.depth
        for i, _ in enumerate(self.feed.reports(stamps) if stamps else ()):
            if self.lossless and i % depth == 0:
                # A chunk's reports come at once: no more than the history holds in flight.
                self.diag.outlet.acknowledged(self.diag.t_diag)
            self.diag.publish_now()
        self.diag_cost += time.perf_counter() - t0
        return next_diag

    def finish(self, interrupted: bool) -> SceneRun:
        """Every published sample to the sinks (a sink's own error is raised by its close),
        the last report, the nodes destroyed; what the run did."""
        nodes, diag = self.nodes, self.diag
        with held_signals():
            for n in nodes:
                with contextlib.suppress(Exception):
                    n.outlet.hand_over()
                with contextlib.suppress(Exception):
                    n.outlet.settle()  # a lossless run's last slice acknowledged
        try:
            self.feed.deliver()
            diag.publish_now()
            if self.lossless:  # the last report acknowledged before the node goes
                diag.outlet.acknowledged(diag.t_diag)
        except Exception:  # noqa: BLE001 - shutting down: the run's data matters more
            pass
        # The time of the last published sample (a stop may land inside a chunk).
        reached = max([self.t, *(n.t for n in nodes if not n.failed)])
        run = SceneRun(scene=self.scene, sim_time=reached,
                       wall_time=time.monotonic() - self.started, startup_time=self.startup,
                       parameters_served_time=self.parameters_served,
                       samples={n.instance.name: n.samples_published for n in nodes},
                       messages={}, summary=diag.summary(),
                       failures={n.instance.name: n.failed for n in nodes if n.failed},
                       interrupted=interrupted,
                       efforts=[n.instance.name for n in nodes if n.run.effort.acted])
        for n in [*nodes, diag]:
            for topic, count in n.outlet.counts.items():
                run.messages[topic] = run.messages.get(topic, 0) + count
        for n in nodes:
            for stage, seconds in n.costs.items():
                run.costs[stage] = run.costs.get(stage, 0.0) + seconds
        run.costs["diagnostics"] = self.diag_cost
        self.executor.shutdown()
        for n in [*nodes, diag]:
            n.destroy_node()
        return run
