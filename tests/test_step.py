"""``~/step``: a paused simulator advanced by N samples of its grid, then its state reported.
Semantics in the run core (``SystemRun.step``), served by the node (``mechsim_msgs/srv/Step``),
callable with ``mechsim service call NODE step N``."""

from __future__ import annotations

import subprocess
import sys
from typing import Any

import numpy as np
import pytest

from mechsim.errors import MechsimError, ParameterError
from test_runcore import RATE, _run


def test_step_takes_samples_of_the_grid_while_paused() -> None:
    """Stepped in pieces, the run releases the samples a continuous run releases: the same
    stamps (the grid of the publish rate), the same states to round-off (a sample's time is
    the previous one's plus the period, as for blocks of any size)."""
    from mechsim.outputs.messages import DEFAULT_TIME_OFFSET, stamps_ns

    stepped, seen = _run("pendulum", {"initial.angle": 1.0})
    with pytest.raises(MechsimError, match="pause it first"):
        stepped.step(3)
    stepped.paused = True
    assert stepped.advance_to(1.0) == 0  # paused: nothing
    taken = [stepped.step(n) for n in (1, 7, 12, 30)]
    assert taken == [1, 7, 12, 30] and stepped.paused
    assert stepped.t == pytest.approx(50 / RATE)
    straight, ref = _run("pendulum", {"initial.angle": 1.0})
    straight.advance_to(50 / RATE)
    assert np.array_equal(stamps_ns(np.array(seen.times), DEFAULT_TIME_OFFSET),
                          stamps_ns(np.arange(51) / RATE, DEFAULT_TIME_OFFSET))
    assert np.array_equal(stamps_ns(np.array(seen.times), DEFAULT_TIME_OFFSET),
                          stamps_ns(np.array(ref.times), DEFAULT_TIME_OFFSET))
    assert np.allclose(np.array(seen.Y), np.array(ref.Y), rtol=1e-12, atol=1e-12)
    with pytest.raises(ParameterError, match="samples"):
        stepped.step(0)


def test_step_stops_at_the_end_and_for_a_stopped_system() -> None:
    run, _ = _run("pendulum", end_time=0.1)
    run.paused = True
    assert run.step(100) == int(round(0.1 * RATE))  # the duration ends it
    assert run.step(5) == 0
    run.fail("test")
    with pytest.raises(MechsimError, match="stopped"):
        run.step(1)


def test_step_service_and_its_command(ros_context: Any, ros_env: dict[str, str]) -> None:
    from rclpy.executors import SingleThreadedExecutor
    from std_srvs.srv import SetBool

    from mechsim.ros.graph_check import quiet_node
    from mechsim.ros.simulator import SimulatorNode
    from mechsim.scene import Instance
    from mechsim.testing import wait_until
    from mechsim_msgs.srv import Step

    sim = SimulatorNode(Instance("pendulum", "stepper", {"initial.angle": 1.0}),
                        context=ros_context, publish_rate=100.0, real_time_factor=1.0)
    client_node = quiet_node("step_client", "/", ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(sim)
    ex.add_node(client_node)

    def call(srv: Any, name: str, request: Any) -> Any:
        client = client_node.create_client(srv, name)
        assert wait_until(ex, client.service_is_ready)
        future = client.call_async(request)
        assert wait_until(ex, future.done)
        return future.result()

    try:
        refused = call(Step, "/stepper/simulator/step", Step.Request(samples=5))
        assert not refused.success and "pause it first" in refused.message
        assert call(SetBool, "/stepper/simulator/pause", SetBool.Request(data=True)).success
        t0 = sim.t
        got = call(Step, "/stepper/simulator/step", Step.Request(samples=25))
        assert got.success and got.samples == 25, got.message
        assert got.time == pytest.approx(t0 + 0.25, abs=1e-12) and got.time == sim.t
        assert (got.stamp.sec, got.stamp.nanosec) == divmod(round((1.0 + sim.t) * 1e9), 10**9)
        assert list(got.name) == ["angle"]
        at = sim.model.layout
        assert list(got.position) == sim.run.y[at.q].tolist()
        assert list(got.velocity) == sim.run.y[at.v].tolist()
        # From the command line, as a ROS user without ros2 would (the node served here
        # while the command runs).
        cli = subprocess.Popen([sys.executable, "-m", "mechsim.cli", "service", "call",
                                "/stepper/simulator", "step", "10"], env=ros_env,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert wait_until(ex, lambda: cli.poll() is not None)
        out, err = cli.communicate()
        assert cli.returncode == 0, err
        assert out.strip() == f"step: success (10 samples to t = {sim.t:.9g} s)"
        assert sim.t == pytest.approx(t0 + 0.35, abs=1e-12) and sim.paused
    finally:
        ex.shutdown()
        client_node.destroy_node()
        sim.destroy_node()
