"""Launch-free node tests: nodes created in-process, a probe node subscribes to every topic;
a second process subscribes over DDS; parameters, services and laziness."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time
from collections import defaultdict
from collections.abc import Callable
from typing import Any

import pytest

from mechsim.environment import import_rclpy

rclpy = import_rclpy()
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from std_srvs.srv import SetBool, Trigger  # noqa: E402

from mechsim.ros.outlet import CLOCK_QOS, LATCHED_QOS, STATE_QOS, TF_QOS  # noqa: E402
from mechsim.ros.simulator import SimulatorNode  # noqa: E402
from mechsim.scene import Instance  # noqa: E402
from mechsim_msgs.msg import Energy, NamedScalars, SystemInfo  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

NS = "pend_test"
TOPICS: dict[str, tuple[type, Any]] = {
    f"/{NS}/state": (JointState, STATE_QOS),
    f"/{NS}/energy": (Energy, STATE_QOS),
    f"/{NS}/invariants": (NamedScalars, STATE_QOS),
    f"/{NS}/observables": (NamedScalars, STATE_QOS),
    f"/{NS}/system_info": (SystemInfo, LATCHED_QOS),
    "/tf": (TFMessage, TF_QOS),
    "/tf_static": (TFMessage, LATCHED_QOS),
    "/clock": (Clock, CLOCK_QOS),
}


def spin_until(ex: SingleThreadedExecutor, cond: Callable[[], bool], timeout: float = 120.0
               ) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        ex.spin_once(timeout_sec=0.02)
    return cond()


def stamp(msg: Any) -> float:
    h = msg.clock if isinstance(msg, Clock) else (
        msg.transforms[0].header.stamp if isinstance(msg, TFMessage) else msg.header.stamp)
    return h.sec + 1e-9 * h.nanosec


@pytest.fixture
def sim(ros_context: Any) -> Any:
    node = SimulatorNode(Instance("pendulum", NS, {"formulation": "multiplier"}),
                         context=ros_context, real_time_factor=0.0, publish_clock=True)
    yield node
    node.destroy_node()


def test_every_topic_in_process(ros_context: Any, sim: Any) -> None:
    probe = Node("probe", context=ros_context)
    got: dict[str, list[Any]] = defaultdict(list)
    for topic, (typ, qos) in TOPICS.items():
        probe.create_subscription(typ, topic, lambda m, t=topic: got[t].append(m), qos)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(sim)
    ex.add_node(probe)
    volatile = [t for t in TOPICS if t not in ("/tf_static", f"/{NS}/system_info")]
    assert spin_until(ex, lambda: all(
        sim.outlet.channels[t].publisher.get_subscription_count() > 0 for t in volatile))
    # One sample at a time with the executor spinning in between, as in a paced run (a burst
    # larger than the subscriber's KEEP_LAST depth would overwrite its queue).
    for k in range(1, 51):
        assert sim.advance_to(0.01 * k) == 1
        for _ in range(3 * len(TOPICS)):  # spin_once runs one callback
            ex.spin_once(timeout_sec=0.001)
    reliable = [t for t in volatile if t != "/clock"]
    assert spin_until(ex, lambda: all(len(got[t]) >= 50 for t in reliable)
                      and got["/tf_static"] and got[f"/{NS}/system_info"]
                      and len(got["/clock"]) >= 25), {t: len(v) for t, v in got.items()}
    for topic, (typ, _) in TOPICS.items():
        assert all(isinstance(m, typ) for m in got[topic]), topic
    # Stamps: simulation time + 1 s, strictly increasing at 100 Hz; /clock never at 0.
    e = [stamp(m) for m in got[f"/{NS}/energy"]]
    assert e[0] == pytest.approx(1.01, abs=1e-9) and e[-1] == pytest.approx(1.5, abs=1e-9)
    assert all(b - a == pytest.approx(0.01, abs=1e-9) for a, b in zip(e, e[1:], strict=False))
    assert min(stamp(m) for m in got["/clock"]) > 0
    js = got[f"/{NS}/state"][-1]
    assert list(js.name) == ["y", "z"] and len(js.position) == 2 and len(js.velocity) == 2
    tf = got["/tf"][-1].transforms[0]
    assert tf.header.frame_id == f"{NS}/pivot" and tf.child_frame_id == f"{NS}/bob"
    st = got["/tf_static"][-1].transforms[0]
    assert st.header.frame_id == "world" and st.child_frame_id == f"{NS}/pivot"
    info = got[f"/{NS}/system_info"][-1]
    assert info.system == "pendulum" and "constraint:constraint_rod_length" in info.laws
    obs = got[f"/{NS}/observables"][-1]
    assert [s.unit for s in obs.scalars if s.name == "tension"] == ["N"]
    ex.shutdown()
    probe.destroy_node()


def test_second_process_receives(ros_context: Any, sim: Any, ros_env: dict[str, str]) -> None:
    script = textwrap.dedent(f"""
        import sys, time
        from mechsim.environment import import_rclpy
        rclpy = import_rclpy()
        from rclpy.node import Node
        from mechsim_msgs.msg import Energy
        from tf2_msgs.msg import TFMessage
        rclpy.init()
        n = Node("far_probe")
        got = {{"e": 0, "tf": 0}}
        def count(key):
            return lambda m: got.__setitem__(key, got[key] + 1)
        n.create_subscription(Energy, "/{NS}/energy", count("e"), 100)
        n.create_subscription(TFMessage, "/tf", count("tf"), 100)
        print("ready", flush=True)
        end = time.monotonic() + 120
        while time.monotonic() < end and (got["e"] < 20 or got["tf"] < 20):
            rclpy.spin_once(n, timeout_sec=0.05)
        print(got["e"], got["tf"], flush=True)
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], env=ros_env, stdout=subprocess.PIPE,
                            text=True)
    assert proc.stdout is not None
    assert proc.stdout.readline().strip() == "ready"
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(sim)
    assert spin_until(ex, lambda: sim.outlet.channels[f"/{NS}/energy"].publisher
                      .get_subscription_count() > 0, 120)
    # Publish until the other process has what it waits for (a condition, not a pace).
    end = time.monotonic() + 120
    k = 0
    while proc.poll() is None and time.monotonic() < end:
        k += 1
        sim.advance_to(0.01 * k)
        ex.spin_once(timeout_sec=0.001)
    out, _ = proc.communicate(timeout=120)
    e, tf = (int(x) for x in out.split())
    assert e >= 20 and tf >= 20
    ex.shutdown()


def test_parameters_validated_and_applied(sim: Any) -> None:
    bad = sim.set_parameters([Parameter("mass", value=-1.0)])[0]
    assert not bad.successful and "mass" in bad.reason and "> 0" in bad.reason
    bad = sim.set_parameters([Parameter("gravity", value=float("inf"))])[0]
    assert not bad.successful and "gravity" in bad.reason
    bad = sim.set_parameters([Parameter("formulation", value="newtonian")])[0]
    assert not bad.successful and "formulation" in bad.reason
    assert sim.advance_to(0.1) == 10  # the simulation goes on after rejected sets
    ok = sim.set_parameters([Parameter("gravity", value=3.0)])[0]
    assert ok.successful and sim.model.value("gravity") == 3.0
    assert sim.get_parameter("initial.angle").value == 1.0
    desc = sim.describe_parameter("initial.angle")
    assert "rad" in desc.description and desc.floating_point_range
    assert sim.advance_to(0.2) == 10


def test_reset_and_pause_services(ros_context: Any, sim: Any) -> None:
    probe = Node("svc_probe", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(sim)
    ex.add_node(probe)
    sim.advance_to(0.3)
    pause = probe.create_client(SetBool, f"/{NS}/simulator/pause")
    reset = probe.create_client(Trigger, f"/{NS}/simulator/reset")
    assert spin_until(ex, lambda: pause.service_is_ready() and reset.service_is_ready())
    fut = pause.call_async(SetBool.Request(data=True))
    assert spin_until(ex, fut.done) and fut.result().success
    assert sim.advance_to(1.0) == 0 and sim.t == pytest.approx(0.3)
    fut = pause.call_async(SetBool.Request(data=False))
    assert spin_until(ex, fut.done)
    fut = reset.call_async(Trigger.Request())
    assert spin_until(ex, fut.done) and fut.result().success
    assert sim.t == 0.0
    ex.shutdown()
    probe.destroy_node()


def test_outputs_computed_only_when_consumed(ros_context: Any) -> None:
    node = SimulatorNode(Instance("kepler", "lazy"), context=ros_context, real_time_factor=0.0)
    node.advance_to(1.0)
    assert node.computed == {"energy": 0, "invariants": 0, "observables": 0, "frames": 0}
    probe = Node("lazy_probe", context=ros_context)
    probe.create_subscription(Energy, "/lazy/energy", lambda m: None, 10)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(probe)
    ex.add_node(node)
    assert spin_until(ex, lambda: node.outlet.channels["/lazy/energy"].publisher
                      .get_subscription_count() > 0)
    node.advance_to(2.0)
    assert node.computed["energy"] == 100
    assert node.computed["invariants"] == 0 and node.computed["frames"] == 0
    ex.shutdown()
    probe.destroy_node()
    node.destroy_node()


def test_failure_stops_system_with_error_status(ros_context: Any) -> None:
    node = SimulatorNode(Instance("kepler", "doomed"), context=ros_context,
                         real_time_factor=0.0)
    probe = Node("diag_probe", context=ros_context)
    got: list[DiagnosticArray] = []
    probe.create_subscription(DiagnosticArray, "/diagnostics", got.append, 10)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(probe)
    ex.add_node(node)
    assert spin_until(ex, lambda: node.outlet.channels["/diagnostics"].publisher
                      .get_subscription_count() > 0)
    node.stepper.y[:] = float("nan")  # inject a non-finite state
    node.advance_to(0.5)
    assert node.failed and "non-finite" in node.failed
    assert spin_until(ex, lambda: bool(got))
    status = got[0].status[0]
    assert status.level == b"\x02" and status.name == "mechsim/doomed/integration"
    assert node.advance_to(1.0) == 0  # stays stopped, last good state kept
    ex.shutdown()
    probe.destroy_node()
    node.destroy_node()


def test_scene_runner_computes_only_what_is_consumed(ros_context: Any) -> None:
    """In a scene, the diagnostics feed consumes energy and invariants only: observables and
    frames of a system nobody watches are never computed (a counter, not a timer)."""
    import mechsim.ros.simulator as simulator
    from mechsim.ros import launch
    from mechsim.scene import parse_scene

    seen: list[Any] = []

    original = simulator.SimulatorNode

    class Spy(original):  # type: ignore[misc, valid-type]
        def __init__(self, *a: Any, **k: Any) -> None:
            super().__init__(*a, **k)
            seen.append(self)

    simulator.SimulatorNode = Spy  # type: ignore[misc]
    try:
        scene = parse_scene({"name": "lazy", "pacing": "fast", "duration": 1.0,
                             "systems": [{"system": "kepler", "name": "quiet"}]})
        launch.run_scene(scene, context=ros_context)
    finally:
        simulator.SimulatorNode = original  # type: ignore[misc]
    (node,) = seen
    assert node.computed["energy"] == 101 and node.computed["invariants"] == 101
    assert node.computed["observables"] == 0 and node.computed["frames"] == 0
