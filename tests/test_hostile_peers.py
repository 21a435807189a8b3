"""Peers that cannot stall, slow or stop a run.

The effort topic: a publisher that never answers is never waited for (counted: no wait, every
sample stepped without one), a controller that answered and then falls silent costs at most
``MAX_MISSED`` waits, a command beyond ``effort_limit`` (1e308) is refused and the run
completes with exit 0, and a step that fails under an effort drops the effort and goes on from
the last good sample (WARN on /diagnostics). Oracles: the run core's own counters and samples
against a free run of the same system; the pendulum's free motion for what follows a dropped
effort.
"""

from __future__ import annotations

import math
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mechsim.environment import import_rclpy
from mechsim.runcore.effort import MAX_MISSED
from mechsim.scene import Instance, parse_scene, scene_from_target
from mechsim.testing import wait_until

rclpy = import_rclpy()
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402

from mechsim.errors import ParameterError  # noqa: E402
from mechsim.outputs.sink import Capabilities  # noqa: E402
from mechsim.ros.launch import run_scene  # noqa: E402
from mechsim.ros.simulator import SimulatorNode  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from test_runcore import Collector, _run  # noqa: E402

RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)


# --- the run core: counted, no ROS -------------------------------------------------------------
def test_a_publisher_that_never_answered_is_never_waited_for() -> None:
    """A controller is present (a publisher on the effort topic) but never sends a command:
    the run never serves its runner's callbacks to wait for one, and steps in blocks as
    without it."""
    run, seen = _run("pendulum", observer=Collector(controller=True))
    served: list[float] = []
    run.serve = served.append
    calls: list[int] = []
    advance = run.stepper.advance
    run.stepper.advance = lambda t: calls.append(t.size) or advance(t)  # type: ignore
    run.advance_to(2.0)
    assert served == [] and run.effort.waits == 0
    assert run.effort.unwaited == len(calls) and max(calls) > 1  # blocks, counted
    free, free_seen = _run("pendulum")
    free.advance_to(2.0)
    assert np.array_equal(np.array(seen.Y), np.array(free_seen.Y))


def test_a_controller_that_falls_silent_costs_a_bounded_number_of_waits() -> None:
    """A controller answers five samples, then never again; later it answers once more each
    time it was given up on. The run waits for it only while it answers, and after
    MAX_MISSED waits in vain no more at all (its commands still apply)."""
    run, seen = _run("pendulum", observer=Collector(controller=True))
    run.commit(run.plan([("effort_wait", 0.01)]))
    answers = {"left": 5}

    def serve(timeout: float) -> None:
        if answers["left"] > 0:
            answers["left"] -= 1
            run.offer(np.array([0.1]))

    run.serve = serve
    run.offer(np.array([0.1]))  # the first answer: from now on it is waited for
    run.advance_to(run.t + 0.2)  # five waits answered, then one in vain
    assert (run.effort.waits, run.effort.missed) == (6, 1) and not run.effort.responsive
    unwaited = run.effort.unwaited
    assert unwaited > 0  # the samples after the miss: not waited for
    for _ in range(MAX_MISSED):
        run.offer(np.array([0.1]))  # it answers again: waited for again, until it misses
        run.advance_to(run.t + 0.2)
    assert (run.effort.waits, run.effort.missed) == (5 + MAX_MISSED, MAX_MISSED)
    run.offer(np.array([0.2]))  # answers after the last wait allowed: not waited for
    run.advance_to(run.t + 0.2)
    assert (run.effort.waits, run.effort.missed) == (5 + MAX_MISSED, MAX_MISSED)
    assert not run.effort.responsive and not run.failed
    assert [0.2] in [u for _, u in seen.efforts]  # its commands still apply
    assert sum("not waited for until it answers again" in n for n in seen.notices) \
        == MAX_MISSED
    assert f"{MAX_MISSED} missed" in seen.notices[-1]


def test_an_effort_beyond_the_limit_is_refused() -> None:
    run, seen = _run("pendulum")
    kind, why = run.offer(np.array([1e308]))  # type: ignore[misc]
    assert kind == "limit" and "beyond effort_limit 1e+06" in why and "angle" in why
    run.commit(run.plan([("effort_limit", 10.0)]))
    assert run.offer(np.array([-10.5]))[0] == "limit"  # type: ignore[index]
    assert run.offer(np.array([-9.5])) is None
    run.advance_to(0.5)
    assert not run.failed and seen.efforts[0][1] == [-9.5]
    with pytest.raises(ParameterError, match="effort_limit"):
        run.plan([("effort_limit", 0.0)])


def test_a_step_failing_under_an_effort_drops_it_and_goes_on() -> None:
    """A 1e6 N·m torque on the pendulum (within the default limit) spins it until dop853
    gives up (its stiffness test trips on the spin); the effort is dropped, the run goes on
    from the last good sample without it, and the motion after that is the free pendulum's
    from that state (the same stepper, no effort: bit for bit)."""
    run, seen = _run("pendulum", method="dop853")
    assert run.offer(np.array([1e6])) is None
    run.advance_to(1.0)
    assert not run.failed and not seen.stops
    assert run.effort.dropped == 1 and len(seen.notices) == 1
    assert seen.notices[0].startswith("effort dropped at t = ") and "\n" not in seen.notices[0]
    t_drop, zeros = seen.efforts[-1]
    assert zeros == [0.0] and 0.0 < t_drop < 0.5  # before the effort's own timeout
    times = np.array(seen.times)
    assert times[-1] == pytest.approx(1.0)
    assert np.all(np.diff(times) > 0)  # no sample lost or repeated
    k = int(np.flatnonzero(np.isclose(times, t_drop))[-1])
    y0 = np.array(seen.Y)[k]
    free, free_seen = _run("pendulum", {"initial.angle": 0.0}, method="dop853")
    free.stepper.restart(float(times[k]), y0, run.p.copy())
    free.t, free.y = float(times[k]), y0.copy()
    free.advance_to(1.0)
    after = np.array(seen.Y)[k + 1:]
    assert np.array_equal(after, np.array(free_seen.Y)[1:])


def test_effort_limit_is_a_scene_and_set_setting() -> None:
    scene = parse_scene({"systems": [{"system": "pendulum", "effort_limit": 5.0},
                                     {"system": "pendulum", "name": "other"}]})
    assert [i.settings.get("effort_limit") for i in scene.systems] == [5.0, None]
    scene = scene_from_target("pendulum", ["effort_limit=2.5"])
    assert scene.systems[0].settings["effort_limit"] == 2.5
    for sets, field in ((["effort_limit=-1"], "--set effort_limit"),
                        (["effort_limit=nan"], "--set effort_limit"),
                        (["nowhere:effort_limit=1"], "--set nowhere:effort_limit")):
        with pytest.raises(ParameterError) as e:
            scene_from_target("pendulum", sets)
        assert e.value.field == field, (sets, e.value)


# --- over ROS ----------------------------------------------------------------------------------
class Silent:
    """A node with a publisher on the effort topic that never publishes."""

    def __init__(self, context: Any, ns: str) -> None:
        self.node = Node("silent_peer", context=context)
        self.pub = self.node.create_publisher(Float64MultiArray, f"/{ns}/effort", RELIABLE)


def test_a_silent_effort_publisher_is_never_waited_for(ros_context: Any) -> None:
    """A fast run of the pendulum while a peer keeps a publisher on its effort topic and
    never publishes: the run sees the controller (it is in the graph from the first sample)
    and never waits for it."""
    scene = single_scene()
    ns = scene.systems[0].name
    peer = Silent(ros_context, ns)
    probe = Node("probe", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(probe)
    assert wait_until(ex, lambda: probe.count_publishers(f"/{ns}/effort") > 0)
    ex.shutdown()
    probe.destroy_node()
    nodes: list[SimulatorNode] = []
    try:
        run = run_scene(scene, fast=True, duration=3.0, context=ros_context,
                        before_first_message=nodes.append)
    finally:
        peer.node.destroy_node()
    assert not run.failures
    effort = nodes[0].run.effort
    assert effort.waits == 0 and effort.missed == 0 and effort.unwaited > 0


def single_scene() -> Any:
    return parse_scene({"name": "peers", "systems": [{"system": "pendulum"}]})


class Spammer:
    """A peer publishing [1e308] on an effort topic as fast as it can, in its own thread."""

    def __init__(self, context: Any, topic: str) -> None:
        self.node = Node("spammer", context=context)
        self.pub = self.node.create_publisher(Float64MultiArray, topic, RELIABLE)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while not self.stop.wait(0.005):
            self.pub.publish(Float64MultiArray(data=[1e308]))

    def close(self) -> None:
        self.stop.set()
        self.thread.join(60)
        self.node.destroy_node()


def test_a_1e308_effort_is_refused_and_the_run_completes(ros_context: Any,
                                                         ros_env: dict[str, str]) -> None:
    """`mechsim run pendulum --duration 3` (in real time) while a peer publishes 1e308 on
    its effort topic: the command is refused in a one-line warning and the run ends with exit
    0 (the peer is discovered during the command's graph check, before the node starts)."""
    spam = Spammer(ros_context, "/pendulum/effort")
    try:
        r = subprocess.run([sys.executable, "-m", "mechsim.cli", "run", "pendulum",
                            "--duration", "3"], env=ros_env, capture_output=True, text=True,
                           timeout=600)
    finally:
        spam.close()
    assert r.returncode == 0, r.stderr
    refused = [ln for ln in r.stderr.splitlines() if "command ignored" in ln]
    assert refused and all("beyond effort_limit 1e+06" in ln for ln in refused), r.stderr
    assert "Traceback" not in r.stderr and "integration stopped" not in r.stderr


def test_a_dropped_effort_is_a_warning_on_diagnostics(ros_context: Any) -> None:
    """Over ROS: a 1e6 command makes a step fail; the node drops it, says so on /diagnostics
    (WARN, mechsim/<ns>/effort) and goes on."""

    class Diagnostics:
        capabilities = Capabilities(wants=lambda topic: topic == "/diagnostics")

        def __init__(self) -> None:
            self.statuses: list[Any] = []

        def write(self, topic: str, type_name: str, msg: DiagnosticArray, qos: Any,
                  ns: int) -> None:
            self.statuses += list(msg.status)

    diag = Diagnostics()
    node = SimulatorNode(Instance("pendulum", "spun", {}, "dop853"), context=ros_context,
                         real_time_factor=0.0, sinks=[diag])
    try:
        assert node.run.offer(np.array([1e6])) is None
        node.advance_to(1.0)
        node.outlet.hand_over()
        assert not node.failed and node.run.effort.dropped == 1
        assert math.isclose(node.t, 1.0)
    finally:
        node.destroy_node()
    warn = [s for s in diag.statuses if s.name == "mechsim/spun/effort"]
    assert len(warn) == 1 and warn[0].level == b"\x01" and "effort dropped" in warn[0].message


def test_effort_limit_is_a_ros_parameter_with_its_range(ros_context: Any) -> None:
    """effort_limit: declared with its range in the descriptor; a set outside it is refused
    with its reason, one inside takes effect on the run's hold."""
    from rclpy.parameter import Parameter as RosParameter

    from mechsim.params import EFFORT_LIMIT

    node = SimulatorNode(Instance("pendulum", "limited", {}, "dop853"), context=ros_context,
                         real_time_factor=0.0)
    try:
        (descriptor,) = node.describe_parameters(["effort_limit"])
        (r,) = descriptor.floating_point_range
        assert (r.from_value, r.to_value) == (EFFORT_LIMIT.minimum, EFFORT_LIMIT.maximum)
        assert node.get_parameter("effort_limit").value == EFFORT_LIMIT.default
        (refused,) = node.set_parameters([RosParameter("effort_limit", value=-1.0)])
        assert not refused.successful and "effort_limit" in refused.reason
        (taken,) = node.set_parameters([RosParameter("effort_limit", value=5.0)])
        assert taken.successful, taken.reason
        assert node.run.effort.limit == 5.0
        assert node.run.offer(np.array([6.0]))[0] == "limit"  # type: ignore[index]
    finally:
        node.destroy_node()
