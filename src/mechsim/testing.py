"""Launch-free node tests with pytest: mechsim's pytest plugin (entry point ``pytest11``:
``mechsim``), active in every pytest run of an environment where mechsim is installed.

What it does before any test module is imported: applies the project's loopback-only Fast DDS
profile and gives the session its own ``ROS_DOMAIN_ID`` (``ROS_DOMAIN_ID`` if set, else one
derived from the process id; each pytest-xdist worker is moved to a different one), so tests
never see another run's nodes and never leave the machine.

Opting out, for a session whose tests must see a real ROS graph (a robot, another host):
``-p no:mechsim`` leaves the plugin out entirely (no fixtures either); the ini option
``mechsim_isolation = false`` (in pytest.ini, or ``-o mechsim_isolation=false``) keeps the
fixtures but changes nothing at start-up: the session keeps its own DDS settings and domain.
The fixtures' nodes then still use the loopback profile, as every mechsim process does (set in
this process when the first fixture imports rclpy).

Fixtures:

- ``ros_domain_id``: the session's domain id.
- ``ros_env``: the environment for a child process that should join the same graph.
- ``ros_context``: a fresh, initialised rclpy ``Context`` for one test.
- ``mechsim_graph``: a :class:`Graph` on that context. ``graph.start("pendulum", **params)``
  (or a scene file) starts simulator nodes and the diagnostics node in this process, spun on a
  background executor, or in a child process with ``process=True``;
  ``graph.collect(topic)`` subscribes (type from the graph) and returns a :class:`Collector`
  whose ``wait_for(count=…, predicate=…, timeout=…)`` waits on a condition, never on a fixed
  sleep; ``graph.add_node(node)`` spins a node of the test (a controller) with them;
  ``graph.set_parameters(node, **values)`` and ``graph.call(service, request)`` use
  the standard ROS interfaces; ``graph.assert_laws_ok(namespace)`` waits until every law the
  diagnostics node checks for that system has reported, and asserts they are all OK.

A minimal test::

    def test_pendulum_conserves_energy(mechsim_graph):
        mechsim_graph.start("pendulum", **{"initial.angle": 1.0})
        energy = mechsim_graph.collect("/pendulum/energy").wait_for(count=50)
        assert abs(energy[-1].total - energy[0].total) < 1e-9
        mechsim_graph.assert_laws_ok("pendulum")
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from mechsim.environment import configure_ros_environment, valid_domain_id

#: Valid domain ids, in the order workers are spread over them (0 is everyone's default).
_DOMAIN_IDS = [*range(1, 102), *range(215, 233)]
#: A generous default for every wait: conditions, not durations, decide when it ends.
DEFAULT_TIMEOUT = 120.0


#: The domain ids of the xdist workers around a nested session (set by each worker for the
#: pytest runs its tests start).
_TAKEN = "_MECHSIM_TAKEN_DOMAINS"


def _requested_domain_id() -> int:
    """ROS_DOMAIN_ID if set (checked), else one from the process id."""
    raw = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if raw:
        if not raw.isdigit() or not valid_domain_id(int(raw)):
            raise pytest.UsageError(f"ROS_DOMAIN_ID={raw[:20]!r}: not in 0..101 or 215..232")
        return int(raw)
    return _DOMAIN_IDS[os.getpid() % 101]


def worker_domain_ids(base: int, count: int, taken: set[int]) -> list[int]:
    """The domain ids of xdist workers gw0 … gw(count−1) of a session asked to run on
    ``base``: gw0 keeps ``base``; gwK takes the first valid id from K·41 places along that
    neither an earlier worker nor a worker around the session uses (``taken``: in a session
    started by a test of another session's worker, that session's workers; gw0 may share its
    own worker's id, which waits for it)."""
    n = len(_DOMAIN_IDS)
    start = _DOMAIN_IDS.index(base) if base in _DOMAIN_IDS else 0
    ids = [base]
    for k in range(1, count):
        for step in range(n):  # all taken (more workers than ids): the last one, shared
            candidate = _DOMAIN_IDS[(start + 41 * k + step) % n]
            if candidate not in taken and candidate not in ids:
                break
        ids.append(candidate)
    return ids


def session_domain_id(worker: str | None = None, count: int = 1) -> int:
    """The session's domain id: ROS_DOMAIN_ID if set (checked), else one from the process
    id; as xdist worker ``worker`` (``gwK``) of ``count``, its own (``worker_domain_ids``).
    Only a real worker moves: a pytest run started by a test inherits the worker's
    ``PYTEST_XDIST_WORKER`` and moved id, and stays on it (moved again, the nested run of
    worker gw1 landed on worker gw2's graph)."""
    base = _requested_domain_id()
    if not (worker and worker.startswith("gw") and worker[2:].isdigit()):
        return base
    taken = {int(t) for t in os.environ.get(_TAKEN, "").split(",") if t.isdigit()}
    ids = worker_domain_ids(base, max(count, int(worker[2:]) + 1), taken)
    os.environ[_TAKEN] = ",".join(str(i) for i in sorted(taken | set(ids)))
    return ids[int(worker[2:])]


#: The ini option that turns the session's isolation off (see the module docstring).
ISOLATION = "mechsim_isolation"


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addini(ISOLATION, type="bool", default=True,
                  help="mechsim: give the session the loopback-only DDS profile and a ROS "
                  "domain of its own (default true; false: leave DDS settings as they are)")


def isolated(config: pytest.Config) -> bool:
    """Whether the plugin isolates the pytest session's DDS (the ``mechsim_isolation`` option)."""
    return bool(config.getini(ISOLATION))


def pytest_configure(config: pytest.Config) -> None:
    """Before collection (so before any test module imports rclpy): the loopback profile and
    the session's domain id, also for child processes started with ``os.environ`` (unless
    ``mechsim_isolation = false``)."""
    if not isolated(config):
        return
    if os.environ.get("_MECHSIM_DOMAIN_SET_BY") == str(os.getpid()):
        return  # this process is configured already (the plugin loaded twice)
    # ``workerinput`` exists only in a pytest-xdist worker process.
    workerinput = getattr(config, "workerinput", {})
    configure_ros_environment(session_domain_id(workerinput.get("workerid"),
                                                int(workerinput.get("workercount", 1))))
    os.environ["_MECHSIM_DOMAIN_SET_BY"] = str(os.getpid())


def pytest_report_header(config: pytest.Config) -> str:
    if not isolated(config):
        return f"mechsim: {ISOLATION} = false: DDS settings and ROS domain left as they are"
    return (f"mechsim: ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID')} "
            f"FASTDDS_DEFAULT_PROFILES_FILE={os.environ.get('FASTDDS_DEFAULT_PROFILES_FILE')}")


def wait_until(executor: Any, done: Callable[[], bool], timeout: float = 120.0) -> bool:
    """Spin ``executor`` until ``done()`` holds: True, or False once ``timeout`` seconds passed
    without it (a generous deadline for a condition, never a duration under test)."""
    end = time.monotonic() + timeout
    while not done():
        if time.monotonic() > end:
            return False
        executor.spin_once(timeout_sec=0.05)
    return True


@pytest.fixture(scope="session")
def ros_domain_id() -> int:
    """The ROS domain id of this test session (0, ROS's default, where none is set)."""
    return int(os.environ.get("ROS_DOMAIN_ID", "0"))


@pytest.fixture
def ros_env() -> dict[str, str]:
    """Environment for a child process (``subprocess.Popen(..., env=ros_env)``) that joins
    the pytest session's graph (profile, domain id, RMW, library path)."""
    return dict(os.environ)


@pytest.fixture
def ros_context(ros_domain_id: int) -> Iterator[Any]:
    """A fresh rclpy Context, initialised for this test only; shut down afterwards. Pass
    ``context=ros_context`` to every Node and Executor."""
    from mechsim.environment import import_rclpy

    rclpy = import_rclpy()
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=ros_domain_id)
    try:
        yield ctx
    finally:
        ctx.try_shutdown()


@pytest.fixture
def mechsim_graph(ros_context: Any, tmp_path: Path) -> Iterator[Graph]:
    """A :class:`Graph` for one test; everything it started is stopped afterwards."""
    graph = Graph(ros_context, tmp_path)
    try:
        yield graph
    finally:
        graph.close()


class Collector:
    """Messages of one topic, in arrival order (``messages``), filled by the graph's probe
    node while a ``wait_for`` spins it."""

    def __init__(self, graph: Graph, topic: str) -> None:
        self.graph, self.topic = graph, topic
        self.messages: list[Any] = []

    def wait_for(self, count: int | None = None,
                 predicate: Callable[[list[Any]], bool] | None = None,
                 timeout: float = DEFAULT_TIMEOUT) -> list[Any]:
        """Wait until ``count`` messages arrived and/or ``predicate(messages)`` holds; return
        the messages. Fails the test (naming the topic and what was seen) at ``timeout``."""
        if count is None and predicate is None:
            count = 1

        def done() -> bool:
            return ((count is None or len(self.messages) >= count)
                    and (predicate is None or predicate(self.messages)))

        self.graph.spin_until(done, timeout, lambda: (
            f"{self.topic}: {len(self.messages)} message(s) after {timeout:g} s (wanted "
            f"count={count}, predicate={'given: not met' if predicate else 'none'})"))
        return list(self.messages)


@dataclass
class Running:
    """What ``Graph.start`` started: node namespaces and, with ``process=True``, the child."""

    namespaces: list[str]
    nodes: list[Any] = field(default_factory=list)
    process: subprocess.Popen[bytes] | None = None
    log: Path | None = None


class Graph:
    """The ROS graph of one test: starts mechsim nodes, subscribes, sets parameters, calls
    services, checks diagnostics. Every wait spins the probe node until a condition holds."""

    def __init__(self, context: Any, workdir: Path) -> None:
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        self.context, self.workdir = context, workdir
        self.probe = Node("mechsim_test_probe", context=context)
        self._probe_ex = SingleThreadedExecutor(context=context)
        self._probe_ex.add_node(self.probe)
        # One thread: rclpy's multi-threaded executor spins hot while a timer is due whose
        # callback group is busy (a paced node's tick running long), holding the interpreter
        # lock from that very tick: a closed loop's ticks then came many periods late.
        self._node_ex = SingleThreadedExecutor(context=context)
        self._spinner: threading.Thread | None = None
        self._stop_spinning = threading.Event()
        self._running: list[Running] = []
        self._collectors: dict[str, Collector] = {}
        self._own: list[Any] = []  # nodes of the test (add_node)

    # --- nodes --------------------------------------------------------------------------------
    def start(self, target: str, *, process: bool = False, name: str | None = None,
              publish_rate: float = 100.0, real_time_factor: float = 1.0,
              diagnostics: bool = True, **parameters: Any) -> Running:
        """Start a system (id) or a scene (YAML file) with ``parameters`` for every instance.
        In this process (default) the nodes spin on a background executor; ``process=True``
        runs ``mechsim run`` in a child process instead (isolation)."""
        from mechsim.scene import Scene, load_scene, single_system_scene

        if target.endswith((".yaml", ".yml")):
            scene: Scene = load_scene(target)
        else:
            scene = single_system_scene(target, parameters)
            if name is not None:
                scene.systems[0].name = name
        if process:
            return self._start_process(target, scene, parameters, publish_rate)
        from mechsim.ros.diagnostics import DiagnosticsNode
        from mechsim.ros.simulator import SimulatorNode

        run = Running([i.name for i in scene.systems])
        for idx, inst in enumerate(scene.systems):
            run.nodes.append(SimulatorNode(inst, context=self.context,
                                           publish_rate=publish_rate,
                                           real_time_factor=real_time_factor,
                                           publish_clock=(idx == 0 and not self._running)))
        if diagnostics:
            run.nodes.append(DiagnosticsNode(context=self.context, warn_drift=scene.warn_drift,
                                             error_drift=scene.error_drift))
        for node in run.nodes:
            self._node_ex.add_node(node)
        self._start_spinner()
        self._running.append(run)
        return run

    def add_node(self, node: Any) -> None:
        """Spin ``node`` (made with ``context=ros_context``: a controller under test) on the
        background executor with the started nodes; it is destroyed with the graph."""
        self._own.append(node)
        self._node_ex.add_node(node)
        self._start_spinner()

    def _start_spinner(self) -> None:
        if self._spinner is None:
            self._spinner = threading.Thread(target=self._spin_nodes, daemon=True,
                                              name="mechsim-nodes")
            self._spinner.start()

    def _spin_nodes(self) -> None:
        """Spin until :meth:`close` asks to stop (the executor is shut down only after this
        thread has ended: shutting it down under a running spin raised in this thread)."""
        from rclpy.executors import ExternalShutdownException

        try:
            while not self._stop_spinning.is_set():
                self._node_ex.spin_once(timeout_sec=0.05)
        except ExternalShutdownException:
            pass

    def _start_process(self, target: str, scene: Any, parameters: dict[str, Any],
                       publish_rate: float) -> Running:
        sets = [a for k, v in parameters.items() for a in ("--set", f"{k}={v}")]
        log = self.workdir / f"mechsim-run-{len(self._running)}.log"
        with open(log, "wb") as sink:  # the child's messages, quoted if a wait fails
            proc = subprocess.Popen([sys.executable, "-m", "mechsim.cli", "run", target,
                                     "--duration", "1e9", "--publish-rate", repr(publish_rate),
                                     *sets],
                                    env=dict(os.environ), cwd=self.workdir,
                                    stdout=sink, stderr=subprocess.STDOUT)
        run = Running([i.name for i in scene.systems], process=proc, log=log)
        self._running.append(run)
        return run

    # --- waiting ------------------------------------------------------------------------------
    def spin_until(self, done: Callable[[], bool], timeout: float,
                   what: str | Callable[[], str]) -> None:
        """Spin until ``done()``; at ``timeout`` fail the test with ``what`` (or what it
        returns then: the state at the deadline, not at the start)."""
        def alive() -> bool:
            for run in self._running:
                if run.process is not None and run.process.poll() is not None:
                    pytest.fail(f"child process of {run.namespaces} exited with "
                                f"{run.process.returncode}{self._child_logs()}")
            return True

        if not wait_until(self._probe_ex, lambda: alive() and done(), timeout):
            text = what if isinstance(what, str) else what()
            pytest.fail(f"timed out: {text}{self._child_logs()}")

    def _child_logs(self) -> str:
        tails = [f"\n--- {r.log.name}:\n" + r.log.read_text(errors="replace")[-2000:]
                 for r in self._running if r.log is not None and r.log.is_file()]
        return "".join(tails)

    def topic_type(self, topic: str, timeout: float = DEFAULT_TIMEOUT) -> str:
        """The type of ``topic`` once something publishes it."""
        found: list[str] = []

        def seen() -> bool:
            for name, types in self.probe.get_topic_names_and_types():
                if name == topic and types:
                    found.append(types[0])
                    return True
            return False

        self.spin_until(seen, timeout, f"{topic} never appeared in the graph")
        return found[0]

    def collect(self, topic: str, msg_type: Any = None, qos: Any = None) -> Collector:
        """Subscribe to ``topic`` (type from the graph unless given; QoS: reliable depth 1000,
        transient local for the latched ``system_info``, ``/tf_static``, ``markers_static``
        and ``markers_trails``)."""
        from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

        from mechsim.outputs.bag import message_class

        if topic in self._collectors:
            return self._collectors[topic]
        cls = msg_type or message_class(self.topic_type(topic))
        latched = topic.endswith(("system_info", "/tf_static", "/markers_static",
                                  "/markers_trails"))
        qos = qos or QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                                durability=(DurabilityPolicy.TRANSIENT_LOCAL if latched
                                            else DurabilityPolicy.VOLATILE))
        collector = Collector(self, topic)
        self.probe.create_subscription(cls, topic, collector.messages.append, qos)
        self._collectors[topic] = collector
        return collector

    # --- parameters and services --------------------------------------------------------------
    def set_parameters(self, node: str, timeout: float = DEFAULT_TIMEOUT,
                       **values: Any) -> list[Any]:
        """Set parameters of ``node`` (e.g. ``"/pendulum/simulator"``) through its standard
        parameter service; returns the SetParametersResult of each (``successful``,
        ``reason``): a rejected value is a result, not an exception."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        request = SetParameters.Request(parameters=[Parameter(k, value=v).to_parameter_msg()
                                                    for k, v in values.items()])
        return list(self.call(f"{node}/set_parameters", request, SetParameters,
                              timeout).results)

    def call(self, service: str, request: Any, srv_type: Any = None,
             timeout: float = DEFAULT_TIMEOUT) -> Any:
        """Call ``service`` with ``request`` (type from the request unless given)."""
        if srv_type is None:
            module = sys.modules[type(request).__module__]
            srv_type = getattr(module, type(request).__name__.split("_Request")[0])
        client: Any = self.probe.create_client(srv_type, service)
        self.spin_until(client.service_is_ready, timeout, f"{service}: service not available")
        future = client.call_async(request)
        self.spin_until(future.done, timeout, f"{service}: no answer")
        self.probe.destroy_client(client)
        return future.result()

    # --- diagnostics --------------------------------------------------------------------------
    def laws(self, namespace: str, timeout: float = DEFAULT_TIMEOUT) -> dict[str, Any]:
        """The latest /diagnostics status of each law of ``namespace`` once every law the
        system declares has reported on samples (``mechsim/<ns>/<law>`` statuses; the
        diagnostics node's "no samples yet" before its first samples does not count)."""
        from mechsim_msgs.msg import SystemInfo

        info = self.collect(f"/{namespace}/system_info", SystemInfo).wait_for(count=1,
                                                                             timeout=timeout)[-1]
        expected = {f"mechsim/{namespace}/{law.replace(':', '/')}" for law in info.laws}
        diag = self.collect("/diagnostics")
        latest: dict[str, Any] = {}

        def all_reported(msgs: list[Any]) -> bool:
            for m in msgs:
                for status in m.status:
                    if status.name in expected and any(
                            v.key == "samples" and v.value != "0" for v in status.values):
                        latest[status.name] = status
            return expected <= set(latest)

        diag.wait_for(predicate=all_reported, timeout=timeout)
        return latest

    def assert_laws_ok(self, namespace: str, timeout: float = DEFAULT_TIMEOUT) -> None:
        """Every law of ``namespace`` on /diagnostics is OK (level 0)."""
        bad = {name: (int.from_bytes(s.level, "little") if isinstance(s.level, bytes)
                      else int(s.level), s.message)
               for name, s in self.laws(namespace, timeout).items()}
        bad = {k: v for k, v in bad.items() if v[0] != 0}
        assert not bad, f"laws not OK: {bad}"

    # --- teardown -----------------------------------------------------------------------------
    def close(self) -> None:
        for run in self._running:
            if run.process is not None and run.process.poll() is None:
                run.process.terminate()
                try:
                    run.process.wait(timeout=60)
                except subprocess.TimeoutExpired:
                    run.process.kill()
        self._stop_spinning.set()
        if self._spinner is not None:
            self._spinner.join(timeout=60)
        self._node_ex.shutdown()
        for run in self._running:
            for node in run.nodes:
                node.destroy_node()
        for node in self._own:
            node.destroy_node()
        self._probe_ex.shutdown()
        self.probe.destroy_node()
