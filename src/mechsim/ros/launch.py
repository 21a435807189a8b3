"""Start a scene: all nodes in one process (stepped in lockstep by one loop), or one process
per node (``--processes``). Used by ``mechsim run`` and ``mechsim record``.

Graph hygiene. Before its simulator nodes exist, a scene looks at the graph (after a bounded
discovery wait, ``GRAPH_WAIT`` or ``MECHSIM_GRAPH_WAIT`` seconds, 0 for no check, overlapped
with loading the models; a conflict seen sooner refuses at once): an instance whose node
``/<name>/simulator`` already runs elsewhere on the ROS domain, or a ``/clock`` already
published by another live node, stops the start with one line naming the running node (one
clock per graph: sim-time consumers would see time jump). A name left in the graph by a killed
process (no answer from its parameter service) does not count.

Processes. ``run_processes`` starts ``python -m mechsim.ros.launch`` once per instance and once
for the diagnostics node; each child dies with the parent (``PR_SET_PDEATHSIG``, also after a
SIGKILL of the parent), honours ``--rate``, ``--fast`` and ``--duration``, and the parent's exit
status is the first non-zero status of a child (a refused start: 2; a failed system: 1).

Children run in their own session: a Ctrl-C in the terminal reaches the parent only, which
stops them with SIGTERM (handled from their first line; ROS and the models are imported later,
so a child stopped while starting exits quietly).
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from mechsim.errors import MechsimError, ParameterError
from mechsim.params import DISCOVERY_WINDOW
from mechsim.ros.feed import DiagnosticsFeed
from mechsim.ros.process import (
    NOTHING_PUBLISHED,
    die_with_parent,
    drain,
    exit_process,
    held_signals,
    stop_on_sigterm,
    stopping,
    write_report,
)

if TYPE_CHECKING:
    from mechsim.scene import Scene

#: Seconds of discovery before the graph is checked for duplicate names and /clock. A new
#: participant learns of the running ones from their periodic announcements, every 0.5 s with
#: the project's profile (Fast DDS's default, 3 s, made discovery take 0.1-3.0 s; with 0.5 s a
#: probe found a running node within 0.8 s in 8 of 8 tries on a quiet machine; 2 s leaves
#: room for a loaded one). Its range: ``params.DISCOVERY_WINDOW``.
GRAPH_WAIT = float(DISCOVERY_WINDOW.default)
#: Environment variable that sets the discovery window instead (seconds, 0 … 600): a loaded
#: machine or a slow network may need more. A conflict seen earlier refuses at once, so a long
#: window costs only a start that has none.
GRAPH_WAIT_VARIABLE = "MECHSIM_GRAPH_WAIT"
#: Samples per chunk in fast mode (each node steps, evaluates and encodes them in one go;
#: ``simulator._BLOCK`` at most). Measured on the slowest systems to record: 1000 against 500
#: took the median real-time factor of three runs from 1029 to 1462 (cr3bp), 1270 to 1345
#: (sphere_slide), 1108 to 1173 (two_body_field); a service waits one chunk, ~10 ms.
FAST_CHUNK = 1000
#: Seconds a node found in the graph has to answer before it counts as gone (killed).
LIVENESS_TIMEOUT = 2.0


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
    #: Wall seconds per stage of the sample pipeline, all nodes together: integrate,
    #: evaluate, encode, publish (including the hand-off to sinks), diagnostics (the
    #: in-process law tracking and reports); a recording adds write (the bag writer thread).
    costs: dict[str, float] = field(default_factory=dict)


class _Stop(BaseException):
    """SIGTERM during a run: a stop, like KeyboardInterrupt, never taken for an error."""


# --- graph hygiene ------------------------------------------------------------------------
#: Seconds between requests to a node found in the graph (a request sent the moment its
#: service is discovered can lose its response).
ASK_AGAIN = 0.5


class _Liveness:
    """Does one node found in the graph answer on its parameter service? One client for the
    whole check, asked again every ``ASK_AGAIN`` s, polled without blocking."""

    def __init__(self, node: Any, full_name: str, now: float) -> None:
        from rcl_interfaces.srv import ListParameters

        self.request = ListParameters.Request(depth=1)
        self.client = node.create_client(ListParameters, f"{full_name}/list_parameters")
        self.seen = now
        self.first_asked: float | None = None
        self.last_asked = 0.0
        self.futures: list[Any] = []

    def poll(self, now: float, end: float) -> bool | None:
        """True: it answered. False: gone (asked for ``LIVENESS_TIMEOUT`` s without an
        answer, a frozen node or a killed process's entry; or its service never reachable by
        the end of the window and ``LIVENESS_TIMEOUT`` s after it was seen). None: not known
        yet (its service not discovered yet, or asked less than ``LIVENESS_TIMEOUT`` s ago)."""
        if any(f.done() for f in self.futures):
            return True
        if self.client.service_is_ready():
            if self.first_asked is None:
                self.first_asked = now
            elif now - self.first_asked >= LIVENESS_TIMEOUT:
                return False
            elif now - self.last_asked < ASK_AGAIN:
                return None
            self.futures.append(self.client.call_async(self.request))
            self.last_asked = now
            return None
        return False if now >= max(end, self.seen + LIVENESS_TIMEOUT) else None


def _window(value: Any, field: str) -> float:
    """``value`` (seconds, a number or its text) as a discovery window, else a ParameterError
    naming ``field`` and the range."""
    try:
        return float(DISCOVERY_WINDOW.check(value, field))
    except ParameterError:
        raise ParameterError(field, f"{str(value)[:20]!r} is not a number of seconds in "
                             f"{DISCOVERY_WINDOW.minimum:g} … {DISCOVERY_WINDOW.maximum:g}"
                             ) from None


def discovery_window() -> float:
    """The discovery window of the graph check: ``MECHSIM_GRAPH_WAIT`` seconds if set (a
    ParameterError naming it if it is not a number in 0 … 600), else ``GRAPH_WAIT``."""
    raw = os.environ.get(GRAPH_WAIT_VARIABLE, "").strip()
    return _window(raw, GRAPH_WAIT_VARIABLE) if raw else GRAPH_WAIT


class GraphCheck:
    """Refuse (MechsimError, one line) to start simulator nodes whose names a live node of
    the domain already uses, or a second /clock. Made before the models are built, so that
    discovery (which starts with this probe's participant) runs meanwhile; :meth:`check` waits
    for the rest of the discovery window, refusing as soon as it sees a conflict."""

    def __init__(self, context: Any, started: float | None = None) -> None:
        """``started``: when ``context`` joined the graph (discovery began), if earlier."""
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        self.context = context
        self.started = time.monotonic() if started is None else started
        self.probe = Node(f"graph_check_{os.getpid()}", namespace="/mechsim", context=context,
                          start_parameter_services=False)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.probe)
        self._liveness: dict[str, _Liveness] = {}

    def check(self, names: list[str], clock: bool, wait: float) -> None:
        """Refuse as soon as a node in the way answers; start once ``wait`` seconds (from
        joining) passed and every node found in the way is known to be gone."""
        end = self.started + wait
        while True:
            now = time.monotonic()
            undecided = False
            for full, conflict in self._in_the_way(names, clock):
                liveness = self._liveness.get(full)
                if liveness is None:
                    liveness = self._liveness[full] = _Liveness(self.probe, full, now)
                answer = liveness.poll(now, end)
                if answer:
                    raise MechsimError(conflict)
                undecided = undecided or answer is None
            if now >= end and not undecided:
                return
            self.executor.spin_once(timeout_sec=0.05)

    def _in_the_way(self, names: list[str], clock: bool) -> Iterator[tuple[str, str]]:
        """(full node name, the refusal if it is alive) for every node in the graph now that
        an instance name or the clock would clash with."""
        domain = self.context.get_domain_id()
        present = {(ns, n) for n, ns in self.probe.get_node_names_and_namespaces()}
        for name in names:
            full = f"/{name}/simulator"
            if (f"/{name}", "simulator") in present:
                yield full, (f"instance {name!r}: {full} is already running on ROS domain "
                             f"{domain}; stop it or give this instance another name "
                             "(--name, or `name:` in the scene)")
        if clock:
            for info in self.probe.get_publishers_info_by_topic("/clock"):
                full = f"{info.node_namespace.rstrip('/')}/{info.node_name}"
                yield full, (f"/clock is already published on ROS domain {domain} by {full}: "
                             "one clock per graph (stop that scene, run the systems in one "
                             "scene, or use another ROS_DOMAIN_ID)")

    def close(self) -> None:
        for liveness in self._liveness.values():
            self.probe.destroy_client(liveness.client)
        self.executor.shutdown()
        self.probe.destroy_node()


#: A context that joined the graph early (``join_graph``) and when, for the next run_scene.
_joined: tuple[Any, float] | None = None


def join_graph() -> None:
    """Join the ROS graph now: a command calls this first thing, so that discovery runs while
    it imports the systems and parses its scene (over a second), and its run then waits only
    for what is left of the discovery window. The next ``run_scene`` without a context takes
    it."""
    global _joined
    from mechsim.environment import import_rclpy

    rclpy = import_rclpy()
    from rclpy.signals import SignalHandlerOptions

    if _joined is None:
        context = rclpy.context.Context()
        rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
        _joined = (context, time.monotonic())


def _warm(scene: Scene) -> None:
    """Build every instance's model and kernels now (cached for the nodes), while discovery
    runs."""
    from mechsim.systems import system_class

    for inst in scene.systems:
        _ = system_class(inst.system)(**inst.parameters).kernels


# --- in one process -----------------------------------------------------------------------
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
    from rclpy.executors import SingleThreadedExecutor

    from mechsim.outputs.messages import stamp_ns
    from mechsim.ros.diagnostics import DiagnosticsNode
    from mechsim.ros.serving import Serving
    from mechsim.ros.simulator import SimulatorNode, paced_lookahead

    global _joined
    own_context = context is None
    # Before this call makes a context: a refused window must not leave one behind.
    if graph_wait is None:
        graph_wait = discovery_window() if own_context else 0.0
    else:
        graph_wait = _window(graph_wait, "graph_wait")
    joined_at = None
    if own_context:
        join_graph()  # unless the command already did
        assert _joined is not None
        (context, joined_at), _joined = _joined, None
    fast = (scene.pacing == "fast" or scene.real_time_factor == 0) if fast is None else fast
    duration = duration if duration is not None else scene.duration
    sinks = list(sinks or [])
    nodes: list[Any] = []
    executor = SingleThreadedExecutor(context=context)
    diag = DiagnosticsNode(context=context, warn_drift=scene.warn_drift,
                           error_drift=scene.error_drift, period=3600.0, sinks=sinks,
                           discover=False)
    feed = DiagnosticsFeed(diag)
    diag_sinks = [*sinks, feed]
    main_thread = threading.current_thread() is threading.main_thread()
    previous_term = signal.getsignal(signal.SIGTERM)

    def on_term(signum: int, frame: Any) -> None:
        raise _Stop()

    interrupted = False
    start = time.monotonic()
    startup = 0.0
    diag_cost = 0.0
    t = 0.0
    try:
        if main_thread:
            signal.signal(signal.SIGTERM, on_term)
        graph = GraphCheck(context, joined_at) if graph_wait > 0 else None
        try:
            _warm(scene)
            if graph is not None:
                graph.check([i.name for i in scene.systems], True, graph_wait)
        finally:
            if graph is not None:
                graph.close()
        for i, inst in enumerate(scene.systems):
            # Stepped by this loop (real_time_factor 0: read-only, the node never paces
            # itself) and never past the duration.
            nodes.append(SimulatorNode(inst, context=context, publish_rate=scene.publish_rate,
                                       real_time_factor=0.0, publish_clock=(i == 0),
                                       sinks=diag_sinks, end_time=duration,
                                       lossless=lossless,
                                       before_first_message=before_first_message))
        executor.add_node(diag)
        for n in nodes:
            executor.add_node(n)
        serving = Serving(executor)
        for i, n in enumerate(nodes):
            # A node stepping a closed loop waits for its controller's commands in between.
            n.serve = serving.wait
            if not fast:  # computed ahead, published as the wall clock makes them due
                n.lookahead = paced_lookahead(scene.publish_rate, scene.real_time_factor)
                # Each tick computes the blocks of a few nodes, not every node's at once.
                n.stagger = i * n.lookahead // len(nodes)
        startup = time.monotonic() - start
        start = time.monotonic()
        dt = 1.0 / scene.publish_rate
        next_diag = diagnostics_period
        offset = nodes[0].time_offset if nodes else 0.0
        k = 0
        with serving:
            wall0 = time.monotonic()
            while duration is None or t < duration - 1e-12:
                if fast:
                    # A chunk of samples per call (compiled stepping, evaluation and
                    # encoding of the whole chunk).
                    k_next = k + FAST_CHUNK
                else:
                    # As many samples as the wall clock has made due (at least the next one,
                    # waited for with callbacks served): latency within one sample period.
                    wait = wall0 + (k + 1) * dt / scene.real_time_factor - time.monotonic()
                    while wait > 0:
                        serving.wait(wait)
                        wait = wall0 + (k + 1) * dt / scene.real_time_factor \
                            - time.monotonic()
                    due = (time.monotonic() - wall0) * scene.real_time_factor / dt
                    k_next = max(k + 1, int(math.floor(due + 1e-9)))
                k_next = max(k_next, k + 1)
                t_next = k_next * dt if duration is None else min(k_next * dt, duration)
                with held_signals():
                    for n in nodes:
                        n.advance_to(t_next)
                k, t = k_next, t_next
                if all(n.failed for n in nodes):
                    break  # every system stopped with an error: nothing left to run
                serving.let_in()  # a service or parameter request waits one chunk at most
                # A report per diagnostics period of simulated time, on the samples up to it.
                t0 = time.perf_counter()
                if t >= next_diag - 1e-12:
                    with held_signals():
                        for n in nodes:
                            n.outlet.hand_over()  # the samples published up to now
                stamps = []
                while t >= next_diag - 1e-12:
                    stamps.append(stamp_ns(next_diag, offset))
                    next_diag += diagnostics_period
                for _ in feed.reports(stamps) if stamps else ():
                    diag.publish_now()
                diag_cost += time.perf_counter() - t0
                if progress is not None and duration is not None:
                    progress(t, duration)
            with held_signals():
                for n in nodes:
                    n.outlet.hand_over()
    except (KeyboardInterrupt, _Stop):
        interrupted = True
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, previous_term)
        # Every sample published reaches the sinks, however the run ended (a sink's own
        # error is raised by its close).
        with held_signals():
            for n in nodes:
                with contextlib.suppress(Exception):
                    n.outlet.hand_over()
                with contextlib.suppress(Exception):
                    n.outlet.settle()  # a lossless run's last slice acknowledged
        try:
            feed.deliver()
            diag.publish_now()
        except Exception:  # noqa: BLE001 - shutting down: the run's data matters more
            pass
        # The time of the last published sample (a stop may land inside a chunk).
        reached = max([t, *(n.t for n in nodes if not n.failed)])
        run = SceneRun(scene=scene, sim_time=reached, wall_time=time.monotonic() - start,
                       startup_time=startup,
                       samples={n.instance.name: n.samples_published for n in nodes},
                       messages={}, summary=diag.summary(),
                       failures={n.instance.name: n.failed for n in nodes if n.failed},
                       interrupted=interrupted)
        for n in [*nodes, diag]:
            for topic, count in n.outlet.counts.items():
                run.messages[topic] = run.messages.get(topic, 0) + count
        for n in nodes:
            for stage, seconds in n.costs.items():
                run.costs[stage] = run.costs.get(stage, 0.0) + seconds
        run.costs["diagnostics"] = diag_cost
        executor.shutdown()
        for n in [*nodes, diag]:
            n.destroy_node()
        if own_context:
            context.try_shutdown()
    return run


# --- one process per node -----------------------------------------------------------------
def _published_any(reports: str) -> bool:
    """Did a simulator of a multi-process run publish a sample (its report in ``reports``)?"""
    import json

    for f in os.listdir(reports):
        if f.startswith("system") and f.endswith(".json"):
            try:
                with open(os.path.join(reports, f)) as fh:
                    if json.load(fh).get("samples", 0):
                        return True
            except (OSError, ValueError):
                return True  # unreadable: assume it did, and drain
    return False


def _spawn(args: list[str], module: str = "mechsim.ros.launch") -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, "-m", module, *args],
                            env=dict(os.environ), start_new_session=True)


#: Seconds a simulator process waits for its consumers' subscriptions (diagnostics, recorder)
#: before it steps anyway, with a warning.
CONSUMER_WAIT = 60.0


def run_processes(target: str, scene: Scene, sets: list[str], duration: float | None, *,
                  rate: float | None = None, fast: bool = False, name: str | None = None,
                  bag: str | None = None, rrd: str | None = None,
                  say: Callable[[str], None] | None = None) -> tuple[SceneRun, list[str], int]:
    """Each simulator node, the diagnostics node and (with ``bag`` or ``rrd``) a recorder node
    in its own process. The simulators wait for the diagnostics' and the recorder's
    subscriptions before their first step, stop at ``duration`` by themselves and let every
    reader acknowledge what they sent; then the consumers drain and stop. Ctrl-C / SIGTERM
    stop all. Returns (the run as each process reported it, output lines, exit status: the
    first non-zero status of a child, else 0)."""
    import json
    import tempfile

    common = [target, "--parent", str(os.getpid()), *[a for s in sets for a in ("--set", s)]]
    if rate is not None:
        common += ["--rate", repr(float(rate))]
    if fast:
        common.append("--fast")
    if duration is not None:
        common += ["--duration", repr(float(duration))]
    if name is not None:
        common += ["--name", name]
    recording = bag is not None or rrd is not None
    previous_term = signal.getsignal(signal.SIGTERM)
    stop_on_sigterm()
    sims: dict[str, subprocess.Popen[bytes]] = {}
    consumers: list[subprocess.Popen[bytes]] = []
    status = 0
    interrupted = False
    reports = tempfile.mkdtemp(prefix="mechsim-run-")
    start = time.monotonic()

    def report(role: str) -> list[str]:
        return ["--report", os.path.join(reports, f"{role}.json")]

    try:
        consumers.append(_spawn([*common, "--diagnostics", *report("diagnostics")]))
        if recording:
            outs = [*(["--bag", bag] if bag else []), *(["--rrd", rrd] if rrd else [])]
            consumers.append(_spawn([*common, *outs, *report("recorder")],
                                    "mechsim.ros.recorder"))
        readers = ["--await-readers", str(len(consumers))]
        if recording:
            readers.append("--await-recorder")
        for i, inst in enumerate(scene.systems):
            sims[inst.name] = _spawn([*common, "--node", inst.name, *readers,
                                      *report(f"system{i}")])
        while True:
            running = [p for p in sims.values() if p.poll() is None]
            codes = [p.returncode for p in [*sims.values(), *consumers]
                     if p.returncode not in (None, 0)]
            if codes:
                status = codes[0]
                if status != 1:  # a refused start or an error: stop the rest
                    break
            if not running:
                break
            time.sleep(0.1)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        wall = time.monotonic() - start
        # Simulators first (they let their readers acknowledge), then the consumers drain.
        # (diagnostics before the recorder: its last report is recorded too).
        for group in (list(sims.values()), *([c] for c in consumers)):
            if consumers and group and group[0] is consumers[0] \
                    and not _published_any(reports):  # once, after the simulators ended
                open(os.path.join(reports, NOTHING_PUBLISHED), "x").close()
            for p in group:
                if p.poll() is None:
                    p.send_signal(signal.SIGTERM)
            for p in group:
                try:
                    p.wait(timeout=60)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGTERM, previous_term)
        got: dict[str, Any] = {}
        for f in os.listdir(reports):
            if f == NOTHING_PUBLISHED:
                os.unlink(os.path.join(reports, f))
                continue
            with open(os.path.join(reports, f)) as fh:
                got[f.removesuffix(".json")] = json.load(fh)
            os.unlink(os.path.join(reports, f))
        os.rmdir(reports)
    run = SceneRun(scene=scene, sim_time=0.0, wall_time=wall, startup_time=0.0, samples={},
                   messages={}, interrupted=interrupted or status == 130)
    for i, inst in enumerate(scene.systems):
        r = got.get(f"system{i}")
        if r is None:
            continue
        run.sim_time = max(run.sim_time, r["t"])
        run.startup_time = max(run.startup_time, r["startup"])
        run.samples[inst.name] = r["samples"]
        if r["failed"]:
            run.failures[inst.name] = r["failed"]
        for topic, n in r["messages"].items():
            run.messages[topic] = run.messages.get(topic, 0) + n
    diag = got.get("diagnostics", {})
    run.summary = [tuple(row) for row in diag.get("summary", [])]  # type: ignore[misc]
    for topic, n in diag.get("messages", {}).items():
        run.messages[topic] = run.messages.get(topic, 0) + n
    lines: list[str] = []
    if recording:
        rec = got.get("recorder")
        if rec is None:
            lines.append("the recorder process reported nothing (see its error above)")
        else:
            lines += rec["lines"]
            lost = {t: n - rec["counts"].get(t, 0) for t, n in run.messages.items()
                    if n > rec["counts"].get(t, 0)}
            dropped = {t: n for t, n in lost.items() if t in rec["best_effort"]}
            reliable = {t: n for t, n in lost.items() if t not in dropped}
            total = sum(run.messages.values())
            if reliable:
                lines.append(f"{sum(reliable.values())} of {total} published messages on "
                             f"reliable topics did not reach the recorder "
                             f"({', '.join(sorted(reliable))})")
            else:
                lines.append("every message of the reliable topics recorded")
            for t, n in sorted(dropped.items()):
                lines.append(f"{t}: {run.messages[t] - n} of {run.messages[t]} recorded (best "
                             "effort: a slow reader drops; in-process recording keeps all)")
    return run, lines, status


def _wait_for(ready: Callable[[], bool], spin: Callable[[], None]) -> bool:
    """Poll ``ready`` (spinning in between) for at most ``CONSUMER_WAIT`` s."""
    end = time.monotonic() + CONSUMER_WAIT
    while time.monotonic() < end:
        if ready():
            return True
        spin()
    return False


def _subscribers(node: Any) -> dict[str, int]:
    return {t: ch.publisher.get_subscription_count() for t, ch in node.outlet.channels.items()}


def run_single_node(scene: Scene, which: str | None, *, fast: bool = False,
                    duration: float | None = None, readers: int = 0, recorder: bool = False,
                    report: str | None = None) -> int:
    """Body of one process of ``run_processes``: the simulator of instance ``which`` (or the
    diagnostics node for None), until ``duration`` or SIGINT/SIGTERM. A simulator first waits
    for ``readers`` consumers (and the recorder's subscriptions, with ``recorder``) and lets
    them acknowledge everything before it exits; the diagnostics node drains what is in flight
    after its stop. ``report``: a JSON file of what the process did, for the parent. Exit
    status 1 if the system failed, else 0."""
    from mechsim.environment import import_rclpy

    rclpy = import_rclpy()
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    from mechsim.ros.outlet import wait_acked

    context = rclpy.context.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    node: Any = None
    executor = SingleThreadedExecutor(context=context)
    sim = which is not None
    start = time.monotonic()
    startup = 0.0
    try:
        if which is None:
            from mechsim.ros.diagnostics import DiagnosticsNode
            node = DiagnosticsNode(context=context, warn_drift=scene.warn_drift,
                                   error_drift=scene.error_drift)
        else:
            from mechsim.ros.simulator import SimulatorNode
            names = [i.name for i in scene.systems]
            if which not in names:
                raise ParameterError("--node", f"no instance {which!r} in the scene")
            idx = names.index(which)
            window = discovery_window()
            graph = GraphCheck(context) if window > 0 else None
            try:
                _warm(scene)
                if graph is not None:
                    graph.check([which], idx == 0, window)
            finally:
                if graph is not None:
                    graph.close()
            rtf = 0.0 if fast or scene.pacing == "fast" else scene.real_time_factor
            waits = bool(readers or recorder)
            late: list[str] = []

            def consumers_listen(n: Any) -> None:
                # Before the first message: every consumer reads system_info (the diagnostics
                # node follows a system from it), the recorder every topic.
                if not _wait_for(lambda: _subscribers(n)[n.t_info] >= readers and (
                        not recorder or min(_subscribers(n).values()) >= 1),
                                 lambda: time.sleep(0.05)):
                    late.append("system_info")

            node = SimulatorNode(scene.systems[idx], context=context,
                                 publish_rate=scene.publish_rate, real_time_factor=rtf,
                                 publish_clock=(idx == 0), end_time=duration,
                                 before_first_message=consumers_listen if waits else None)
            node.serve = lambda timeout: executor.spin_once(timeout_sec=timeout)
            if waits:
                node.set_paused(True)  # before the executor first runs its pacing timer
        executor.add_node(node)
        if sim and waits:
            # Then the diagnostics node's sample subscriptions, made once it had system_info.
            if not _wait_for(lambda: _subscribers(node)[node.t_energy] >= readers,
                             lambda: executor.spin_once(timeout_sec=0.05)):
                late.append("energy")
            if late:
                node.get_logger().warning(f"{which}: the diagnostics/recorder processes did "
                                          f"not subscribe within {CONSUMER_WAIT:g} s "
                                          f"({', '.join(late)}); stepping anyway")
            node.set_paused(False)
        startup = time.monotonic() - start
        # Recorded from another process, a stepped node sends no more than its publishers
        # keep (their history depth) before the recorder has acknowledged it: lossless
        # however far the simulator could run ahead.
        chunk = FAST_CHUNK
        if sim and recorder:
            chunk = min(ch.qos.depth for ch in node.outlet.channels.values()
                        if ch.qos.reliability == ReliabilityPolicy.RELIABLE
                        and ch.qos.durability == DurabilityPolicy.VOLATILE)
        while not (sim and node.finished):
            if sim and node.stepped and not node.paused:
                # As fast as possible, serving services and parameters in between.
                node.advance_to(node.t + chunk / node.publish_rate)
                if recorder:
                    wait_acked([ch.publisher for ch in node.outlet.channels.values()],
                               CONSUMER_WAIT)
                executor.spin_once(timeout_sec=0)
            else:
                executor.spin_once(timeout_sec=0.1)
    except KeyboardInterrupt:
        pass
    finally:
        try:
            if node is not None and sim:
                node.outlet.settle()  # a lossless run's last slice acknowledged
                wait_acked([ch.publisher for ch in node.outlet.channels.values()])
            elif node is not None and report is not None:
                drain(executor, lambda: node.received, report)
                wait_acked([ch.publisher for ch in node.outlet.channels.values()])
        except KeyboardInterrupt:
            pass
        if node is not None:
            if sim:
                write_report(report, {"t": node.t, "samples": node.samples_published,
                                       "failed": node.failed, "startup": startup,
                                       "messages": node.outlet.counts})
            else:
                write_report(report, {"summary": node.summary(),
                                       "messages": node.outlet.counts})
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        context.try_shutdown()
    return 1 if which is not None and node is not None and node.failed else 0


def _main(argv: list[str]) -> int:
    stop_on_sigterm()
    try:
        ap = argparse.ArgumentParser(prog="python -m mechsim.ros.launch")
        ap.add_argument("target", help="scene file or system id")
        who = ap.add_mutually_exclusive_group(required=True)
        who.add_argument("--node", help="instance name (`diagnostics`: the diagnostics node, "
                         "unless an instance has that name)")
        who.add_argument("--diagnostics", action="store_true")
        ap.add_argument("--report", help="JSON file of what this process did, for the parent")
        ap.add_argument("--await-readers", type=int, default=0)
        ap.add_argument("--await-recorder", action="store_true")
        ap.add_argument("--set", action="append", default=[])
        ap.add_argument("--rate", type=float)
        ap.add_argument("--fast", action="store_true")
        ap.add_argument("--duration", type=float)
        ap.add_argument("--name")
        ap.add_argument("--parent", type=int, help="die with this process")
        a = ap.parse_args(argv)
        if a.parent is not None:
            die_with_parent(a.parent)
        from mechsim.params import DURATION, PUBLISH_RATE
        from mechsim.scene import scene_from_target

        scene = scene_from_target(a.target, a.set, a.name)
        if a.rate is not None:
            scene.publish_rate = float(PUBLISH_RATE.check(a.rate, "--rate"))
        duration = float(DURATION.check(a.duration, "--duration")) \
            if a.duration is not None else scene.duration
        which = a.node
        if a.diagnostics or (which == "diagnostics"
                             and which not in [i.name for i in scene.systems]):
            which = None
        return run_single_node(scene, which, fast=a.fast, duration=duration,
                               readers=a.await_readers, recorder=a.await_recorder,
                               report=a.report)
    except MechsimError as e:
        print(f"mechsim: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # stopped (SIGINT/SIGTERM) while still starting up
        return 130
    except RuntimeError as e:  # RosEnvironmentError and rclpy start-up failures
        if stopping.is_set():  # the stop landed inside rclpy and came out converted
            return 130
        print(f"mechsim: error: {(str(e).splitlines() or [type(e).__name__])[0]}",
              file=sys.stderr)
        return 2


if __name__ == "__main__":
    exit_process(_main(sys.argv[1:]))
