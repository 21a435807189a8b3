"""A scene with one process per node (``mechsim run --processes``), and the node processes.

``run_processes`` writes the parsed scene once, as data (``scene.scene_data``, JSON), and
starts one ``mechsim simulator`` process per instance, one ``mechsim diagnostics`` and (with a
bag or a .rrd) one ``mechsim recorder``: the hidden verbs of the one command, each the function
of its node kind here (``simulator_process``, ``diagnostics_process``; the recorder's:
``mechsim.ros.recorder.run_recorder``), which ``mechsim run --only NODE`` runs too. Each child
dies with the parent (``PR_SET_PDEATHSIG``, also after a SIGKILL of the parent) and runs in its
own session: a Ctrl-C in the terminal reaches the parent only, which stops them with SIGTERM
(handled from their first lines; ROS and the models are imported later, so a child stopped
while starting exits quietly). The simulators wait for the diagnostics' and the recorder's
subscriptions before their first step, stop at the scene's duration by themselves and let
every reader acknowledge what they sent; then the consumers drain and stop. The parent's exit
status is the first non-zero status of a child (a refused start: 2; a failed system: 1).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from mechsim.errors import ParameterError
from mechsim.ros.graph_check import (
    GraphCheck,
    discovery_window,
    ros_arguments,
    start_context,
)
from mechsim.ros.launch import FAST_CHUNK, SceneRun, _warm
from mechsim.ros.process import (
    NOTHING_PUBLISHED,
    bounded_teardown,
    drain,
    end_node_process,
    write_report,
)
from mechsim.runcore.stops import stop_on_sigterm, stopping

if TYPE_CHECKING:
    from mechsim.scene import Scene

#: Seconds a simulator process waits for its consumers' subscriptions (diagnostics, recorder)
#: before it steps anyway, with a warning.
CONSUMER_WAIT = 60.0
#: Largest scene data a node process reads (bytes).
MAX_SCENE_DATA = 64 << 20


# --- the parent ---------------------------------------------------------------------------
def run_processes(scene: Scene, *, bag: str | None = None,
                  rrd: str | None = None) -> tuple[SceneRun, list[str], int]:
    """Each simulator node, the diagnostics node and (with ``bag`` or ``rrd``) a recorder node
    in its own process, until the scene's duration or Ctrl-C / SIGTERM (which stop all).
    Returns (the run as each process reported it, output lines, exit status: the first
    non-zero status of a child, else 0)."""
    previous_term = signal.getsignal(signal.SIGTERM)
    stop_on_sigterm()
    workdir = tempfile.mkdtemp(prefix="mechsim-run-")
    children = _Children(workdir, replace(scene, bag=bag, rrd=rrd))
    interrupted = False
    start = time.monotonic()
    try:
        children.start()
        children.watch()
    except KeyboardInterrupt:
        interrupted = True
    finally:
        wall = time.monotonic() - start
        children.stop()
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGTERM, previous_term)
        got = children.reports()
        shutil.rmtree(workdir, ignore_errors=True)
    run = _merged(scene, got, wall, interrupted or children.status == 130)
    lines = _recording(run, got.get("recorder")) if bag is not None or rrd is not None else []
    return run, lines, children.status


class _Children:
    """The node processes of one multi-process run, their scene file and reports."""

    def __init__(self, workdir: str, scene: Scene) -> None:
        from mechsim.files import write_atomic
        from mechsim.scene import scene_data

        self.workdir, self.scene = workdir, scene
        self.scene_file = os.path.join(workdir, "scene.json")
        write_atomic(self.scene_file, json.dumps(scene_data(scene)))
        self.sims: list[subprocess.Popen[bytes]] = []
        self.consumers: list[subprocess.Popen[bytes]] = []
        self.roles: list[str] = []
        self.status = 0

    def _report(self, role: str) -> str:
        self.roles.append(role)
        return os.path.join(self.workdir, f"{role}.json")

    def _spawn(self, kind: str, role: str, *args: str) -> subprocess.Popen[bytes]:
        return subprocess.Popen([sys.executable, "-m", "mechsim.cli", kind,
                                 "--scene", self.scene_file, "--parent", str(os.getpid()),
                                 "--report", self._report(role), *args, *ros_arguments()],
                                env=dict(os.environ), start_new_session=True)

    def start(self) -> None:
        self.consumers.append(self._spawn("diagnostics", "diagnostics"))
        recording = self.scene.bag is not None or self.scene.rrd is not None
        if recording:
            self.consumers.append(self._spawn("recorder", "recorder"))
        readers = ["--await-readers", str(len(self.consumers))]
        if recording:
            readers.append("--await-recorder")
        for i, inst in enumerate(self.scene.systems):
            self.sims.append(self._spawn("simulator", f"system{i}", "--instance", inst.name,
                                         *readers))

    def watch(self) -> None:
        """Until every simulator ended, or a child failed otherwise than its system (a refused
        start, an error: the rest are stopped), or a simulator did not start stepping within
        ``START_DEADLINE`` seconds of its launch (a process hung in its start-up, e.g. in the
        DDS library: the rest are stopped, status 1)."""
        launched = time.monotonic()
        while True:
            codes = [p.returncode for p in [*self.sims, *self.consumers]
                     if p.poll() not in (None, 0)]
            if codes:
                self.status = codes[0]
                if self.status != 1:
                    return
            if all(p.returncode is not None for p in self.sims):
                return
            if time.monotonic() - launched > START_DEADLINE and self._hung():
                return
            time.sleep(0.1)

    def _hung(self) -> bool:
        """Whether a simulator still running has not said it started (``started_file``):
        said on stderr, status 1."""
        hung = [self.scene.systems[i].name for i, p in enumerate(self.sims)
                if p.returncode is None and not os.path.exists(
                    started_file(os.path.join(self.workdir, f"system{i}.json")))]
        if hung:
            print(f"mechsim: {', '.join(hung)}: the simulator process did not start within "
                  f"{START_DEADLINE:g} s (hung in its start-up); stopping the run",
                  file=sys.stderr)
            self.status = 1
        return bool(hung)

    def stop(self) -> None:
        """Simulators first (they let their readers acknowledge), then the consumers drain
        (diagnostics before the recorder: its last report is recorded too)."""
        for group in (self.sims, *([c] for c in self.consumers)):
            if self.consumers and group and group[0] is self.consumers[0] \
                    and not _published_any(self.workdir):  # once, after the simulators ended
                open(os.path.join(self.workdir, NOTHING_PUBLISHED), "x").close()
            for p in group:
                if p.poll() is None:
                    p.send_signal(signal.SIGTERM)
            for p in group:
                try:
                    p.wait(timeout=60)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()

    def reports(self) -> dict[str, Any]:
        got = {}
        for role in self.roles:
            try:
                with open(os.path.join(self.workdir, f"{role}.json")) as fh:
                    got[role] = json.load(fh)
            except FileNotFoundError:
                continue
        return got


#: Seconds from a multi-process run's launch within which every simulator process must
#: start stepping (its node made, its consumers waited for).
START_DEADLINE = 300.0


def started_file(report: str) -> str:
    """The file a simulator process makes beside its ``report`` once it steps."""
    return os.path.splitext(report)[0] + ".started"


def _published_any(reports: str) -> bool:
    """Did a simulator of a multi-process run publish a sample (its report in ``reports``)?"""
    for f in os.listdir(reports):
        if f.startswith("system") and f.endswith(".json"):
            try:
                with open(os.path.join(reports, f)) as fh:
                    if json.load(fh).get("samples", 0):
                        return True
            except (OSError, ValueError):
                return True  # unreadable: assume it did, and drain
    return False


def _merged(scene: Scene, got: dict[str, Any], wall: float, interrupted: bool) -> SceneRun:
    """The run as its processes reported it."""
    run = SceneRun(scene=scene, sim_time=0.0, wall_time=wall, startup_time=0.0, samples={},
                   messages={}, interrupted=interrupted)
    for i, inst in enumerate(scene.systems):
        r = got.get(f"system{i}")
        if r is None:
            continue
        run.sim_time = max(run.sim_time, r["t"])
        run.startup_time = max(run.startup_time, r["startup"])
        run.samples[inst.name] = r["samples"]
        if r["failed"]:
            run.failures[inst.name] = r["failed"]
        if r.get("effort_acted"):
            run.efforts.append(inst.name)
        for topic, n in r["messages"].items():
            run.messages[topic] = run.messages.get(topic, 0) + n
    diag = got.get("diagnostics", {})
    run.summary = [tuple(row) for row in diag.get("summary", [])]  # type: ignore[misc]
    for topic, n in diag.get("messages", {}).items():
        run.messages[topic] = run.messages.get(topic, 0) + n
    return run


def _recording(run: SceneRun, rec: dict[str, Any] | None) -> list[str]:
    """What the recorder process wrote, and what of the published messages it received."""
    if rec is None:
        return ["the recorder process reported nothing (see its error above)"]
    from mechsim.outputs.batch import recorded

    lines = list(rec["lines"])
    counts = rec["counts"]
    kept = recorded(run.scene.bag_topics)  # (others are published for other subscribers)
    lost = {t: n - counts.get(t, 0) for t, n in run.messages.items()
            if n > counts.get(t, 0) and kept(t)}
    dropped = {t: n for t, n in lost.items() if t in rec["best_effort"]}
    reliable = {t: n for t, n in lost.items() if t not in dropped}
    total = sum(run.messages.values())
    if reliable:
        lines.append(f"{sum(reliable.values())} of {total} published messages on reliable "
                     f"topics did not reach the recorder ({', '.join(sorted(reliable))})")
    else:
        lines.append("every message of the reliable topics recorded")
    for t, n in sorted(dropped.items()):
        lines.append(f"{t}: {run.messages[t] - n} of {run.messages[t]} recorded (best "
                     "effort: a slow reader drops; in-process recording keeps all)")
    return lines


# --- the node processes -------------------------------------------------------------------
def read_scene(path: str) -> Scene:
    """The scene a parent wrote for its node processes (``scene.scene_data``)."""
    from mechsim.files import read_bounded
    from mechsim.scene import scene_from_data

    try:
        data = json.loads(read_bounded(path, MAX_SCENE_DATA))
    except OSError as e:
        raise ParameterError("--scene", f"{path}: cannot read ({e.strerror or e})") from None
    except ValueError:
        raise ParameterError("--scene", f"{path}: not JSON") from None
    try:
        return scene_from_data(data)
    except ParameterError as e:
        raise ParameterError("--scene", f"{path}: {e.reason}") from None


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


def _pubs(node: Any) -> list[Any]:
    return [ch.publisher for ch in node.outlet.channels.values()]


def diagnostics_process(scene: Scene | None, report: str | None = None) -> int:
    """The diagnostics node of ``scene`` (None: alone, its thresholds its parameters') until
    SIGINT/SIGTERM, then it drains what is in flight. ``report``: a JSON file of what it did,
    for the parent. Exit status 0."""
    context = start_context()
    from rclpy.executors import SingleThreadedExecutor

    from mechsim.ros.diagnostics import DiagnosticsNode
    from mechsim.ros.outlet import wait_acked

    executor = SingleThreadedExecutor(context=context)
    node = None
    try:
        node = DiagnosticsNode(context=context) if scene is None else DiagnosticsNode(
            context=context, warn_drift=scene.warn_drift, error_drift=scene.error_drift)
        executor.add_node(node)
        while not stopping.is_set():
            executor.spin_once(timeout_sec=0.1)
    except KeyboardInterrupt:
        pass
    finally:
        try:
            if node is not None and report is not None:
                drain(executor, lambda: node.received, report)
                # The last report, on what was drained: a run shorter than the period (or
                # stopped before the timer fired) still has its /diagnostics recorded.
                node.publish_now()
                wait_acked(_pubs(node))
        except KeyboardInterrupt:
            pass
        if node is not None:
            write_report(report, {"summary": node.summary(), "messages": node.outlet.counts})
        end_node_process("the diagnostics process's teardown", lambda: 0, executor, node,
                         context)
    return 0


def simulator_process(scene: Scene, name: str, *, readers: int = 0, recorder: bool = False,
                      report: str | None = None) -> int:
    """The simulator node of instance ``name`` until the scene's duration or SIGINT/SIGTERM,
    paced as the scene says. It first waits for ``readers`` consumers (and the recorder's
    subscriptions, with ``recorder``) and lets them acknowledge everything before it exits.
    ``report``: a JSON file of what it did, for the parent. Exit status 1 if the system
    failed, else 0."""
    names = [i.name for i in scene.systems]
    if name not in names:
        raise ParameterError("--instance", f"no instance {name!r} in the scene (instances: "
                             f"{', '.join(names)})")
    window = discovery_window()  # refused before joining the graph
    context = start_context()
    from rclpy.executors import SingleThreadedExecutor

    executor = SingleThreadedExecutor(context=context)
    start = time.monotonic()
    sim = _Simulator(scene, names.index(name), context, executor, readers, recorder)
    try:
        sim.start(window)
        sim.startup = time.monotonic() - start
        if report is not None:
            open(started_file(report), "x").close()  # (in the parent's own work directory)
        sim.step()
    except KeyboardInterrupt:
        pass
    finally:
        sim.close(report)

        def status() -> int:
            return 1 if sim.node is None or sim.node.failed else 0

        end_node_process(f"{name}: the simulator's teardown", status, executor, sim.node,
                         context)
    return 1 if sim.node is not None and sim.node.failed else 0


class _Simulator:
    """One simulator node in a process of its own."""

    def __init__(self, scene: Scene, index: int, context: Any, executor: Any, readers: int,
                 recorder: bool) -> None:
        self.scene, self.index, self.context, self.executor = scene, index, context, executor
        self.readers, self.recorder = readers, recorder
        self.node: Any = None
        self.startup = 0.0
        self.late: list[str] = []

    def start(self, window: float) -> None:
        from mechsim.ros.simulator import SimulatorNode

        scene, idx = self.scene, self.index
        waits = bool(self.readers or self.recorder)
        rtf = 0.0 if scene.pacing == "fast" else scene.real_time_factor
        graph = GraphCheck(self.context) if window > 0 else None
        try:
            _warm(replace(scene, systems=[scene.systems[idx]]))
            # Made before the check's node goes (one participant), begun once it passed.
            node = self.node = SimulatorNode(
                scene.systems[idx], context=self.context, publish_rate=scene.publish_rate,
                real_time_factor=rtf, publish_clock=(idx == 0), end_time=scene.duration,
                before_first_message=self._consumers_listen if waits else None,
                deferred=True)
            if graph is not None:
                graph.check([scene.systems[idx].name], idx == 0, window, own=[node])
        finally:
            if graph is not None:
                with bounded_teardown(f"{scene.systems[idx].name}: the graph check's close",
                                      lambda: 1):
                    graph.close()
        node.begin()
        node.run.serve = lambda timeout: self.executor.spin_once(timeout_sec=timeout)
        if waits:
            node.set_paused(True)  # before the executor first runs its pacing timer
        self.executor.add_node(node)
        if waits:
            # Then the diagnostics node's sample subscriptions, made once it had system_info.
            if not _wait_for(lambda: _subscribers(node)[node.topics.t_energy] >= self.readers,
                             lambda: self.executor.spin_once(timeout_sec=0.05)):
                self.late.append("energy")
            if self.late:
                node.get_logger().warning(
                    f"{scene.systems[idx].name}: the diagnostics/recorder processes did not "
                    f"subscribe within {CONSUMER_WAIT:g} s ({', '.join(self.late)}); "
                    "stepping anyway")
            node.set_paused(False)

    def _consumers_listen(self, n: Any) -> None:
        """Before the first message: every consumer reads system_info (the diagnostics node
        follows a system from it), the recorder every topic."""
        from mechsim.outputs.batch import recorder_subscribed

        bag_topics = self.scene.bag_topics
        if not _wait_for(lambda: _subscribers(n)[n.topics.t_info] >= self.readers and (
                not self.recorder or recorder_subscribed(_subscribers(n), bag_topics)),
                         lambda: time.sleep(0.05)):
            self.late.append("system_info")

    def step(self) -> None:
        """Until the duration: stepped as fast as possible (serving services and parameters
        in between), or paced by the node's own timer."""
        from rclpy.qos import DurabilityPolicy, ReliabilityPolicy

        from mechsim.ros.outlet import wait_acked

        node, executor = self.node, self.executor
        # Recorded from another process, a stepped node sends no more than its publishers
        # keep (their history depth) before the recorder has acknowledged it: lossless
        # however far the simulator could run ahead.
        chunk = FAST_CHUNK
        if self.recorder:
            chunk = min(ch.qos.depth for ch in node.outlet.channels.values()
                        if ch.qos.reliability == ReliabilityPolicy.RELIABLE
                        and ch.qos.durability == DurabilityPolicy.VOLATILE)
        while not node.finished and not stopping.is_set():
            if node.stepped and not node.paused:
                node.advance_to(node.t + chunk / node.publish_rate)
                if self.recorder:
                    wait_acked(_pubs(node), CONSUMER_WAIT)
                executor.spin_once(timeout_sec=0)
            else:
                executor.spin_once(timeout_sec=0.1)

    def close(self, report: str | None) -> None:
        from mechsim.ros.outlet import wait_acked

        node = self.node
        if node is None:
            return
        try:
            node.outlet.settle()  # a lossless run's last slice acknowledged
            wait_acked(_pubs(node))
        except KeyboardInterrupt:
            pass
        write_report(report, {"t": node.t, "samples": node.samples_published,
                               "failed": node.failed, "startup": self.startup,
                               "effort_acted": node.run.effort.acted,
                               "messages": node.outlet.counts})
