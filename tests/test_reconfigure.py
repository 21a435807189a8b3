"""Runtime reconfiguration of a simulator node is a transaction: a parameter set is validated
completely (values, the whole model, the method's compatibility, the new stepper; structural
changes compiled in a child process with a time limit) or rejected with its reason, and an
accepted set changes stepping and outputs together. Epochs mark every reset and model change.

The physics checks are independent of the node: the bead's energy is recomputed here from the
published state with numpy and the curve's own formula."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from mechsim.environment import import_rclpy
from mechsim.testing import wait_until

rclpy = import_rclpy()
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402

from mechsim.outputs.sink import Capabilities  # noqa: E402
from mechsim.ros.simulator import SimulatorNode  # noqa: E402
from mechsim.scene import Instance, parse_scene  # noqa: E402


class Capture:
    """Sink keeping every state and energy message (in-process: nothing dropped)."""

    capabilities = Capabilities(wants=lambda topic: topic.endswith(("/state", "/energy")))

    def __init__(self) -> None:
        self.state: list[Any] = []
        self.energy: list[Any] = []

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        if topic.endswith("/state"):
            self.state.append(msg)
        elif topic.endswith("/energy"):
            self.energy.append(msg)


def _node(ctx: Any, system: str, name: str, sinks: list[Any] | None = None, **kw: Any
          ) -> SimulatorNode:
    params = kw.pop("parameters", {})
    return SimulatorNode(Instance(system, name, params), context=ctx, real_time_factor=0.0,
                         sinks=sinks, **kw)


def _one_line_rejection(result: Any, why: str) -> None:
    assert not result.successful, why
    assert why in result.reason and "\n" not in result.reason, result.reason


def test_incompatible_method_rejected_nothing_changes(ros_context: Any) -> None:
    """The issue's first defect: `exact` on a system without a closed form or `gauss6` on a
    constrained form, alone in a set, were accepted and raised later in the executor."""
    node = _node(ros_context, "pendulum", "meth", parameters={"formulation": "multiplier"})
    try:
        node.advance_to(0.5)
        before = (node.stepper, node.model, node.epoch, node.t)
        for method, why in (("exact", "no closed form"),
                            ("gauss6", "needs a conservative unconstrained"),
                            ("yoshida8", "needs a separable")):
            _one_line_rejection(node.set_parameters([Parameter("method", value=method)])[0],
                                why)
            assert (node.stepper, node.model, node.epoch, node.t) == before
            assert node.get_parameter("method").value == "auto"
        # One atomic set: the bad method takes the good gravity down with it.
        g = node.model.value("gravity")
        r = node.set_parameters_atomically([Parameter("gravity", value=3.0),
                                            Parameter("method", value="exact")])
        _one_line_rejection(r, "no closed form")
        assert node.get_parameter("gravity").value == g and node.model.value("gravity") == g
        assert node.advance_to(1.0) == 50 and node.failed is None
    finally:
        node.destroy_node()


def _quartic(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return 0.3 * x**4, 1.2 * x**3


def test_structural_change_rebuilds_stepper_kernels_and_outputs(ros_context: Any) -> None:
    """The bead's wire changed from the parabola z = x² to z = 0.3 x⁴ at runtime: the run
    restarts from the new wire's initial state, the published energy is the quartic wire's
    (recomputed here from the published x, ẋ), and it is conserved, which it would not be if
    the stepper still integrated the parabola while the outputs used the quartic."""
    cap = Capture()
    node = _node(ros_context, "bead_on_wire", "wire", sinks=[cap])
    try:
        node.advance_to(0.5)
        epoch = node.epoch
        r = node.set_parameters_atomically([Parameter("shape", value="custom"),
                                            Parameter("curve", value="0.3*x**4")])
        assert r.successful, r.reason
        assert node.t == 0.0 and node.epoch == epoch + 1
        assert node.stepper.model.kernels is node.model.kernels
        n_before = len(cap.state) - 1  # the t = 0 sample of the new epoch is published
        assert node.advance_to(3.0) == 300
        states, energies = cap.state[n_before:], cap.energy[n_before:]
        assert len(states) == len(energies) == 301
        x = np.array([s.position[0] for s in states])
        v = np.array([s.velocity[0] for s in states])
        f, f1 = _quartic(x)
        m, g = 1.0, 9.81
        kinetic = 0.5 * m * (1 + f1**2) * v**2
        potential = m * g * f
        assert np.allclose([e.kinetic for e in energies], kinetic, rtol=1e-12, atol=1e-12)
        assert np.allclose([e.potential for e in energies], potential, rtol=1e-12, atol=1e-12)
        total = kinetic + potential
        assert abs(x[0] - 1.0) < 1e-15 and np.ptp(x) > 1.0  # from rest at x = 1: it swings
        assert np.max(np.abs(total - total[0])) < 1e-7 * total[0]
    finally:
        node.destroy_node()


def test_state_size_change_restarts(ros_context: Any) -> None:
    """A number of masses is structural: the state grows, the run restarts, nothing breaks."""
    cap = Capture()
    node = _node(ros_context, "coupled_oscillators", "chain", sinks=[cap])
    try:
        node.advance_to(0.3)
        assert node.set_parameters([Parameter("count", value=3)])[0].successful
        assert node.t == 0.0 and len(cap.state[-1].position) == 3
        assert node.advance_to(0.5) == 50 and node.failed is None
        assert len(cap.state[-1].name) == 3
    finally:
        node.destroy_node()


def test_structural_change_compiled_with_a_time_limit(ros_context: Any) -> None:
    """Derivation and compilation run in a child process with a time limit; past it the set is
    rejected and nothing changed (a tiny limit makes this deterministic)."""
    node = _node(ros_context, "pendulum", "slow", parameters={"formulation": "multiplier"},
                 prepare_timeout=0.05)
    try:
        model, stepper = node.model, node.stepper
        r = node.set_parameters([Parameter("formulation", value="reduced")])[0]
        _one_line_rejection(r, "took longer than 0.05 s")
        assert node.model is model and node.stepper is stepper
        assert node.get_parameter("formulation").value == "multiplier"
        assert node.advance_to(0.2) == 20
    finally:
        node.destroy_node()


def test_hostile_curve_rejected_before_sympy(ros_context: Any) -> None:
    """9**9**7 (4.6 million digits if evaluated) is refused by the expression bounds; the bead
    runs on with its wire."""
    node = _node(ros_context, "bead_on_wire", "evil")
    try:
        for curve, why in (("9**9**7*x", "power in an exponent"),
                           ("exp(exp(exp(1e6)))*x", "not a finite real number"),
                           ("x*" * 120 + "x", "longer than 200 characters")):
            r = node.set_parameters_atomically([Parameter("shape", value="custom"),
                                                Parameter("curve", value=curve)])
            _one_line_rejection(r, why)
        assert node.get_parameter("shape").value == "parabola"
        assert node.advance_to(0.1) == 10
    finally:
        node.destroy_node()


def _reset(ctx: Any, node: SimulatorNode) -> None:
    from rclpy.node import Node
    from std_srvs.srv import Trigger

    probe = Node("reset_probe", context=ctx)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    ex.add_node(probe)
    client = probe.create_client(Trigger, f"/{node.instance.name}/simulator/reset")
    _spin_until(ex, client.service_is_ready)
    future = client.call_async(Trigger.Request())
    _spin_until(ex, future.done)
    assert future.result().success
    ex.remove_node(node)
    ex.shutdown()
    probe.destroy_node()


def _spin_until(ex: Any, cond: Callable[[], bool], timeout: float = 120.0) -> None:
    assert wait_until(ex, cond, timeout), "condition not met"


def test_epochs_and_when_initial_values_take_effect(ros_context: Any) -> None:
    """A model change or a reset starts a new epoch; a method change, a rejected set or a
    rate change does not. initial.* is stored at once and takes effect at the reset."""
    cap = Capture()
    node = _node(ros_context, "pendulum", "ep", sinks=[cap])
    try:
        node.advance_to(0.3)
        e0 = node.epoch
        last = cap.state[-1].position[0]
        assert node.set_parameters([Parameter("initial.angle", value=0.5)])[0].successful
        assert node.epoch == e0 + 1 and node.t == pytest.approx(0.3)
        node.advance_to(0.31)  # continues from the current state, not from 0.5
        assert abs(cap.state[-1].position[0] - last) < 0.05
        assert node.set_parameters([Parameter("method", value="dop853")])[0].successful
        assert node.set_parameters([Parameter("publish_rate", value=50.0)])[0].successful
        assert not node.set_parameters([Parameter("mass", value=-1.0)])[0].successful
        assert node.epoch == e0 + 1 and node.stepper.method == "dop853"
        _reset(ros_context, node)
        assert node.epoch == e0 + 2 and node.t == 0.0
        assert cap.state[-1].position[0] == pytest.approx(0.5, abs=1e-15)
        assert node.advance_to(0.1) == 5  # 50 Hz now
    finally:
        node.destroy_node()


def test_stepped_node_real_time_factor_read_only(ros_context: Any) -> None:
    """A node the scene runner steps never paces itself: a remote real_time_factor is refused
    (it used to start a second timer and run past the duration)."""
    node = _node(ros_context, "pendulum", "stepped", end_time=0.2)
    try:
        _one_line_rejection(node.set_parameters([Parameter("real_time_factor",
                                                           value=5.0)])[0], "read-only")
        assert node._timer is None
        assert node.advance_to(10.0) == 20 and node.t == pytest.approx(0.2) and node.finished
    finally:
        node.destroy_node()


def test_self_paced_node_one_timer_and_end_time(ros_context: Any) -> None:
    """A node pacing itself keeps exactly one timer through rate and factor changes, and
    stops at end_time whatever the factor."""
    node = SimulatorNode(Instance("pendulum", "paced"), context=ros_context,
                         real_time_factor=5.0, publish_rate=50.0, end_time=1.0)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    try:
        for name, value in (("real_time_factor", 20.0), ("publish_rate", 100.0),
                            ("real_time_factor", 50.0)):
            assert node.set_parameters([Parameter(name, value=value)])[0].successful
            assert len(list(node.timers)) == 1
        _one_line_rejection(node.set_parameters([Parameter("real_time_factor",
                                                           value=0.0)])[0], "must be > 0")
        assert len(list(node.timers)) == 1
        _spin_until(ex, lambda: node.finished)
        published = node.samples_published
        for _ in range(20):  # the timer keeps firing: nothing more is integrated
            ex.spin_once(timeout_sec=0.05)
        assert node.t == pytest.approx(1.0) and node.samples_published == published
    finally:
        ex.shutdown()
        node.destroy_node()


def test_extreme_value_fails_one_system_cleanly(ros_context: Any) -> None:
    """gravity = 1e300 makes the integrator's step count overflow (a numba typing error
    before): that system stops with one line, the other runs to the end, nothing raises."""
    from mechsim.ros.launch import run_scene

    scene = parse_scene({"name": "extreme", "pacing": "fast", "duration": 1.0,
                         "publish_rate": 20.0, "systems": [
                             {"system": "pendulum", "name": "heavy",
                              "parameters": {"gravity": 1e300}},
                             {"system": "kepler", "name": "calm"}]})
    run = run_scene(scene, context=ros_context)
    assert set(run.failures) == {"heavy"}
    assert "\n" not in run.failures["heavy"]
    assert run.samples["calm"] == 21


def test_change_continues_from_the_published_state(ros_context: Any) -> None:
    """A change that keeps the state continues from the last published sample, not from the
    stepper's own state (DOP853 steps past its last output time): the sample republished at
    the change equals the one published before it."""
    cap = Capture()
    node = _node(ros_context, "pendulum", "cont", sinks=[cap],
                 parameters={"initial.angle": 1.0})
    try:
        node.advance_to(0.37)
        before = cap.state[-1]
        result, = node.set_parameters([Parameter("tolerance", value=1e-9)])
        assert result.successful, result.reason
        node.advance_to(0.38)  # the new stepper's first sample
        result, = node.set_parameters([Parameter("gravity", value=9.0)])
        assert result.successful, result.reason
        again = cap.state[-1]  # the current sample, republished with the new parameters
        assert again.header.stamp == cap.state[-2].header.stamp
        assert list(again.position) == list(cap.state[-2].position)
        assert before.position[0] != cap.state[-2].position[0]
    finally:
        node.destroy_node()
