"""The effort input of a simulator node (``<ns>/effort``): a generalized force held over each
sample period. Oracles: the pendulum's equation with a torque, θ'' = −(g/R) sin θ + τ/(m R²),
integrated by scipy, and the work of a constant torque, W = τ (θ − θ₀)."""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mechsim.environment import import_rclpy
from mechsim.testing import wait_until

rclpy = import_rclpy()
from rcl_interfaces.msg import Log  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_msgs.msg import Float64MultiArray  # noqa: E402

from mechsim.outputs import messages  # noqa: E402
from mechsim.outputs.bag.reader import read_messages  # noqa: E402
from mechsim.outputs.bag.writer import BagWriter  # noqa: E402
from mechsim.outputs.sink import Capabilities  # noqa: E402
from mechsim.ros.launch import run_scene  # noqa: E402
from mechsim.ros.simulator import SimulatorNode  # noqa: E402
from mechsim.scene import Instance, single_system_scene  # noqa: E402

G, M, R = 9.81, 1.2, 0.8  # gravity, bob mass, rod length of every pendulum here
PENDULUM = {"gravity": G, "mass": M, "length": R, "initial.angle": 1.0}
RELIABLE = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)


def pendulum_rhs(torque: float) -> Callable[[float, np.ndarray], list[float]]:
    return lambda t, y: [y[1], -G / R * math.sin(y[0]) + torque / (M * R * R)]


def oracle(y0: list[float], t0: float, times: np.ndarray, torque: float) -> np.ndarray:
    """(θ, θ̇) at ``times`` from ``y0`` at ``t0`` under a constant torque (scipy, tight)."""
    sol = solve_ivp(pendulum_rhs(torque), (t0, float(times[-1])), y0, method="DOP853",
                    t_eval=times, rtol=1e-13, atol=1e-13)
    return sol.y.T


class Recorder:
    """Sink: every message the node sends (and every effort it applied), with its time."""

    capabilities = Capabilities()

    def __init__(self, offset: float) -> None:
        self.offset = offset
        self.rows: list[tuple[str, float, Any]] = []

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        t = (ns - messages.stamp_ns(0.0, self.offset)) * 1e-9
        self.rows.append((topic, round(t, 9), msg))

    def topic(self, leaf: str) -> list[tuple[float, Any]]:
        return [(t, m) for topic, t, m in self.rows if topic.endswith("/" + leaf)]

    def states(self) -> tuple[np.ndarray, np.ndarray]:
        """Times and (θ, θ̇) rows of the state samples (the last of each time: a new epoch
        republishes the current one)."""
        by_time = {t: (m.position[0], m.velocity[0]) for t, m in self.topic("state")}
        times = np.array(sorted(by_time))
        return times, np.array([by_time[t] for t in times])

    def work_external(self) -> dict[float, float]:
        return {t: m.work_external for t, m in self.topic("energy")}


class Loop:
    """A stepped pendulum node, a probe publishing its commands, one executor."""

    def __init__(self, context: Any, name: str = "pend", system: str = "pendulum",
                 **params: Any) -> None:
        self.ex = SingleThreadedExecutor(context=context)
        self.rec = Recorder(messages.DEFAULT_TIME_OFFSET)
        self.node = SimulatorNode(Instance(system, name, params), context=context,
                                  real_time_factor=0.0, sinks=[self.rec])
        self.probe = Node("commander", context=context)
        self.pub = self.probe.create_publisher(Float64MultiArray, f"/{name}/effort", RELIABLE)
        self.logs: list[str] = []
        self.probe.create_subscription(Log, "/rosout", lambda m: self.logs.append(m.msg),
                                       QoSProfile(depth=1000))
        self.ex.add_node(self.node)
        self.ex.add_node(self.probe)
        self.spin_until(lambda: self.pub.get_subscription_count() > 0, "effort subscription")

    def spin_until(self, cond: Callable[[], bool], what: str, timeout: float = 120.0) -> None:
        if not wait_until(self.ex, cond, timeout):
            pytest.fail(f"timed out waiting for {what}")

    def set(self, **values: Any) -> None:
        results = self.node.set_parameters([Parameter(k, value=v) for k, v in values.items()])
        assert all(r.successful for r in results), [r.reason for r in results]

    def send(self, values: list[float]) -> None:
        """Publish a command and wait until the node has taken or rejected it."""
        seen = self.node.effort_received + self.node.effort_rejected
        self.pub.publish(Float64MultiArray(data=values))
        self.spin_until(lambda: self.node.effort_received + self.node.effort_rejected > seen,
                        f"command {values}")

    def close(self) -> None:
        self.ex.shutdown()
        self.node.destroy_node()
        self.probe.destroy_node()


@pytest.fixture
def loops(ros_context: Any) -> Any:
    made: list[Loop] = []

    def make(**kw: Any) -> Loop:
        made.append(Loop(ros_context, **kw))
        return made[-1]

    yield make
    for loop in made:
        loop.close()


def test_constant_effort_is_a_constant_torque(loops: Any) -> None:
    loop = loops(**PENDULUM)
    loop.set(effort_timeout=100.0)
    tau, t_on = 2.5, 0.2
    loop.node.advance_to(t_on)
    loop.send([tau])
    loop.node.advance_to(2.0)
    times, Y = loop.rec.states()
    assert times[-1] == pytest.approx(2.0)
    free, forced = times <= t_on + 1e-9, times >= t_on - 1e-9
    expected_free = oracle([1.0, 0.0], 0.0, times[free], 0.0)
    y_on = expected_free[-1]
    expected = oracle(list(y_on), t_on, times[forced], tau)
    assert np.max(np.abs(Y[free] - expected_free)) < 1e-8
    assert np.max(np.abs(Y[forced] - expected)) < 1e-8
    assert np.max(np.abs(Y[forced] - oracle(list(y_on), t_on, times[forced], 0.0))) > 0.1
    # W_ext = ∫ τ θ̇ dt = τ (θ − θ(t_on)): the balance is closed by the effort's work.
    work = loop.rec.work_external()
    theta = dict(zip(times, Y[:, 0], strict=True))
    for t in times[forced]:
        assert work[t] == pytest.approx(tau * (theta[t] - theta[t_on]), abs=1e-9)
    energy = [m for _, m in loop.rec.topic("energy")]
    assert max(abs(m.total - m.work_external - energy[0].total) for m in energy) < 1e-9
    # Recorded: the applied effort on <ns>/effort, stamped with the sample it applies from.
    applied = [(t, list(m.data)) for t, m in loop.rec.topic("effort")]
    assert applied == [(t_on, [tau])]
    # Under an effort, system_info lists only the laws that still hold.
    infos = [m for _, m in loop.rec.topic("system_info")]
    assert "energy" in infos[0].laws and list(infos[-1].laws) == ["work_balance"]


def test_effort_returns_to_zero_after_the_timeout(loops: Any) -> None:
    loop = loops(**PENDULUM)
    loop.set(effort_timeout=0.3)
    tau = 1.5
    loop.node.advance_to(0.1)
    loop.send([tau])
    loop.node.advance_to(1.0)
    times, Y = loop.rec.states()
    theta = dict(zip(times, Y[:, 0], strict=True))
    work = loop.rec.work_external()
    assert [(t, list(m.data)) for t, m in loop.rec.topic("effort")] == [(0.1, [tau]),
                                                                       (0.4, [0.0])]
    for t in times[(times >= 0.1 - 1e-9) & (times <= 0.4 + 1e-9)]:
        assert work[t] == pytest.approx(tau * (theta[t] - theta[0.1]), abs=1e-9)
    after = times >= 0.4 - 1e-9
    i0 = int(np.argmax(after))
    expected = oracle(list(Y[i0]), 0.4, times[after], 0.0)  # free motion from t = 0.4
    assert np.max(np.abs(Y[after] - expected)) < 1e-8
    assert max(abs(work[t] - work[0.4]) for t in times[after]) < 1e-12
    # ... and not the motion with the torque still on.
    assert np.max(np.abs(Y[after] - oracle(list(Y[i0]), 0.4, times[after], tau))) > 0.05


def test_bad_commands_are_rejected_and_ignored(loops: Any) -> None:
    loop = loops(**PENDULUM)
    free = loops(name="pend_free", **PENDULUM)
    loop.node.advance_to(0.1)
    loop.send([1.0, 2.0])
    loop.send([math.nan])
    loop.send([math.inf])
    assert (loop.node.effort_received, loop.node.effort_rejected) == (0, 3)
    loop.node.advance_to(1.0)
    free.node.advance_to(1.0)
    times, Y = loop.rec.states()
    times_free, Y_free = free.rec.states()
    assert np.array_equal(times, times_free)
    assert np.max(np.abs(Y - Y_free)) < 1e-12
    assert loop.rec.topic("effort") == []
    loop.spin_until(lambda: sum("command ignored" in m for m in loop.logs) >= 2, "two warnings")
    warnings = [m for m in loop.logs if "command ignored" in m]
    assert all("\n" not in m for m in warnings)
    assert any("2 values, expected 1" in m and "angle" in m for m in warnings)
    assert any("not finite" in m for m in warnings)
    # Throttled: the second non-finite command (within the period) logged nothing.
    assert sum("not finite" in m for m in warnings) == 1
    # A method that integrates without the effort: rejected, not silently dropped.
    loop.set(method="yoshida8")
    loop.send([1.0])
    assert loop.node.effort_received == 0
    loop.spin_until(lambda: any("yoshida8" in m for m in loop.logs), "method warning")


def test_system_without_effort_input_rejects(loops: Any) -> None:
    loop = loops(name="body", system="rigid_body")
    loop.send([0.0] * len(loop.node.model.coordinates))
    assert loop.node.effort_received == 0
    loop.spin_until(lambda: any("takes no effort" in m for m in loop.logs), "warning")


class DampingController:
    """u = −c θ̇ from each state sample, in its own thread (a controller in another node).
    It says it is there with one zero command once the node subscribes: a fast run waits only
    for a controller that has answered (``mechsim.runcore.effort``)."""

    def __init__(self, context: Any, ns: str, c: float) -> None:
        self.node = Node("damper", context=context)
        self.c = c
        self.sent: dict[float, float] = {}  # sample time -> command computed from it
        self.pub = self.node.create_publisher(Float64MultiArray, f"/{ns}/effort", RELIABLE)
        self.node.create_subscription(JointState, f"/{ns}/state", self.on_state, RELIABLE)
        self.ex = SingleThreadedExecutor(context=context)
        self.ex.add_node(self.node)
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.stop = False
        self.thread.start()

    def _spin(self) -> None:
        greeted = False
        while not self.stop:
            if not greeted and self.pub.get_subscription_count() > 0:
                self.pub.publish(Float64MultiArray(data=[0.0]))  # here, before any state
                greeted = True
            self.ex.spin_once(timeout_sec=0.05)

    def on_state(self, msg: JointState) -> None:
        u = -self.c * msg.velocity[0]
        self.sent[msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec] = u
        self.pub.publish(Float64MultiArray(data=[u]))

    def close(self) -> None:
        self.stop = True
        self.thread.join(timeout=60)
        self.ex.shutdown()
        self.node.destroy_node()


def test_closed_loop_in_fast_mode_keeps_the_work_balance(ros_context: Any, tmp_path: Any,
                                                         capsys: Any) -> None:
    scene = single_system_scene("pendulum", dict(PENDULUM))
    ns = scene.systems[0].name
    controller = DampingController(ros_context, ns, c=0.8)
    rec = Recorder(messages.DEFAULT_TIME_OFFSET)
    bag = BagWriter(tmp_path / "bag")
    try:
        # The controller must be in the graph when stepping starts (else the first samples
        # run open loop): run_scene sees its publisher from the first sample on.
        probe = Node("probe", context=ros_context)
        ex = SingleThreadedExecutor(context=ros_context)
        ex.add_node(probe)
        assert wait_until(ex, lambda: probe.count_subscribers(f"/{ns}/state") > 0
                          and probe.count_publishers(f"/{ns}/effort") > 0), \
            "controller not in the graph"
        ex.shutdown()
        probe.destroy_node()

        def answered(node: SimulatorNode) -> None:
            """Before the first sample: the controller's greeting taken (it has answered)."""
            wait = SingleThreadedExecutor(context=ros_context)
            wait.add_node(node)
            assert wait_until(wait, lambda: node.effort_received > 0), "no greeting"
            wait.remove_node(node)

        run = run_scene(scene, fast=True, duration=2.0, sinks=[rec, bag], context=ros_context,
                        before_first_message=answered)
    finally:
        controller.close()
        bag.close()
    assert not run.failures
    energy = rec.topic("energy")
    e0 = energy[0][1].total
    residual = max(abs(m.total - e0 - (m.work_external - m.work_dissipated))
                   for _, m in energy)
    assert energy[-1][1].work_external < -0.1 * e0  # the controller took energy out
    assert residual < 1e-9 * e0
    # Diagnostics: every law of the (effort) set OK, and only those that hold.
    laws = {(law, level) for system, law, _, level in run.summary if system == ns}
    assert laws == {("work_balance", 0)}, run.summary
    # ... and the conservation table says why the others are not in it.
    from mechsim.cli.common import print_summary

    assert run.efforts == [ns]
    capsys.readouterr()
    print_summary(run)
    said = [ln for ln in capsys.readouterr().out.splitlines() if "effort was applied" in ln]
    assert len(said) == 1 and said[0].strip().startswith(f"{ns}: ") and "energy" in said[0]
    # Lockstep: the effort applied from each sample is the controller's answer to it.
    applied = {t: m.data[0] for t, m in rec.topic("effort")}
    offset = messages.DEFAULT_TIME_OFFSET
    sent = {round(t - offset, 6): u for t, u in controller.sent.items()}
    assert len(applied) > 150
    for t, u in applied.items():
        assert u == sent[round(t, 6)], t
    # The bag holds the applied efforts like every other topic.
    recorded = list(read_messages(tmp_path / "bag", [f"/{ns}/effort"]))
    assert len(recorded) == len(applied) == run.messages[f"/{ns}/effort"]
    assert {m.type_name for m in recorded} == {"std_msgs/msg/Float64MultiArray"}
