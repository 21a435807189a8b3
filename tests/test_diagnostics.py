"""The diagnostics node: OK on correct runs, ERROR on a deliberately broken one (a far too large
fixed step), statuses named mechsim/<ns>/<law> with byte levels; discovery over DDS."""

from __future__ import annotations

import time
from typing import Any

from mechsim.environment import import_rclpy

rclpy = import_rclpy()
from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402

from mechsim.ros.diagnostics import DiagnosticsNode  # noqa: E402
from mechsim.ros.launch import run_scene  # noqa: E402
from mechsim.ros.simulator import SimulatorNode  # noqa: E402
from mechsim.scene import Instance, parse_scene  # noqa: E402


class Capture:
    def __init__(self) -> None:
        self.messages: list[tuple[str, Any]] = []

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        self.messages.append((topic, msg))


def test_ok_on_correct_runs_error_on_broken(ros_context: Any) -> None:
    # Verlet steps at most one output interval: 5 Hz output lets its step reach 0.1 s.
    scene = parse_scene({"name": "diag", "pacing": "fast", "duration": 20.0, "publish_rate": 5.0,
                         "systems": [
        {"system": "pendulum", "name": "good", "parameters": {"initial.angle": 2.0}},
        {"system": "kepler", "name": "orbit"},
        {"system": "driven_oscillator", "name": "driven"},
        {"system": "pendulum", "name": "broken", "method": "verlet", "tolerance": 0.9,
         "parameters": {"initial.angle": 2.0}}]})
    cap = Capture()
    run = run_scene(scene, context=ros_context, sinks=[cap])
    levels = {(s, law): level for s, law, _, level in run.summary}
    for (system, law), level in levels.items():
        if system != "broken":
            assert level == 0, (system, law)
    assert levels[("broken", "energy")] == 2
    assert levels[("broken", "work_balance")] == 2
    last = [m for t, m in cap.messages if t == "/diagnostics"][-1]
    by_name = {s.name: s for s in last.status}
    assert by_name["mechsim/good/energy"].level == DiagnosticStatus.OK
    assert by_name["mechsim/broken/energy"].level == DiagnosticStatus.ERROR
    assert by_name["mechsim/orbit/invariant/runge_lenz_x"].level == DiagnosticStatus.OK
    assert "mechsim/driven/work_balance" in by_name
    assert "mechsim/driven/energy" not in by_name  # driven and damped: E is not conserved
    drift = float(next(kv.value for kv in by_name["mechsim/broken/energy"].values
                       if kv.key == "max_drift"))
    assert drift > 1e-3


def test_discovers_systems_over_dds(ros_context: Any) -> None:
    sim = SimulatorNode(Instance("pendulum", "found", {"formulation": "multiplier"}),
                        context=ros_context, real_time_factor=0.0)
    diag = DiagnosticsNode(context=ros_context, period=0.2)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(sim)
    ex.add_node(diag)
    end = time.monotonic() + 10
    while time.monotonic() < end and "/found" not in diag.systems:
        ex.spin_once(timeout_sec=0.05)
    assert "/found" in diag.systems
    for k in range(1, 101):
        sim.advance_to(0.01 * k)
        for _ in range(6):
            ex.spin_once(timeout_sec=0.001)
    statuses = {s.name: s for s in diag.statuses()}
    assert statuses["mechsim/found/energy"].level == DiagnosticStatus.OK
    assert statuses["mechsim/found/constraint/constraint_rod_length"].level == \
        DiagnosticStatus.OK
    samples = int(next(kv.value for kv in statuses["mechsim/found/energy"].values
                       if kv.key == "samples"))
    assert samples > 50
    ex.shutdown()
    diag.destroy_node()
    sim.destroy_node()
