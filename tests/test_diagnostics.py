"""The diagnostics node: OK on correct runs, ERROR on a deliberately broken one (a far too large
fixed step), statuses named mechsim/<ns>/<law> with byte levels; discovery over DDS.

Hardening, each guard with a test that fails without it: a hostile peer with hundreds of fake
system_info topics is followed only up to ``max_systems`` and forgotten when it leaves; a NaN
sample is ERROR only until finite values return; a spoofed system_info or sample from another
publisher is ignored; a reset or a parameter change starts a new epoch that the laws re-base on.
No sleeps: every wait spins the executor until a condition holds, with a generous deadline."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

import mechsim
from mechsim.environment import import_rclpy

rclpy = import_rclpy()
from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402

from mechsim.outputs.messages import MessageFactory, Sample  # noqa: E402
from mechsim.outputs.sink import Capabilities  # noqa: E402
from mechsim.ros.diagnostics import DiagnosticsNode  # noqa: E402
from mechsim.ros.launch import run_scene  # noqa: E402
from mechsim.ros.outlet import LATCHED_QOS, STATE_QOS  # noqa: E402
from mechsim.ros.simulator import SimulatorNode  # noqa: E402
from mechsim.scene import Instance, parse_scene  # noqa: E402
from mechsim_msgs.msg import Energy, SystemInfo  # noqa: E402

DEADLINE = 120.0  # generous: conditions, not durations, end every wait


def spin_until(ex: SingleThreadedExecutor, done: Callable[[], bool], what: str,
               step: Callable[[], None] | None = None) -> None:
    """Spin ``ex`` (calling ``step`` between spins) until ``done()``; fail at the deadline."""
    end = time.monotonic() + DEADLINE
    while not done():
        if time.monotonic() > end:
            pytest.fail(f"timed out waiting for {what}")
        if step is not None:
            step()
        ex.spin_once(timeout_sec=0.02)


def level_of(diag: DiagnosticsNode, ns: str, key: str) -> int:
    return diag.level(diag.systems[ns].laws[key], stale=False)


class Capture:
    capabilities = Capabilities()

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
    diag = DiagnosticsNode(context=ros_context, period=0.2, stale_timeout=3600.0)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(sim)
    ex.add_node(diag)
    spin_until(ex, lambda: "/found" in diag.systems and
               sim.count_subscribers("/found/energy") > 0, "discovery of /found")
    law = diag.systems["/found"].laws["energy"]
    for k in range(1, 101):
        sim.advance_to(0.01 * k)
        spin_until(ex, lambda k=k: law.samples >= k, f"sample {k} of /found")
    statuses = {s.name: s for s in diag.statuses()}
    assert statuses["mechsim/found/energy"].level == DiagnosticStatus.OK
    assert statuses["mechsim/found/constraint/constraint_rod_length"].level == \
        DiagnosticStatus.OK
    samples = int(next(kv.value for kv in statuses["mechsim/found/energy"].values
                       if kv.key == "samples"))
    assert samples == 100
    ex.shutdown()
    diag.destroy_node()
    sim.destroy_node()


# --- hardening ----------------------------------------------------------------------------------
class Stepper:
    """Advances a simulator node by one publication interval per call (simulation time)."""

    def __init__(self, sim: SimulatorNode) -> None:
        self.sim = sim

    def __call__(self) -> None:
        self.sim.advance_to(self.sim.t + 1.0 / self.sim.publish_rate)


def test_hostile_peer_is_bounded_and_forgotten(ros_context: Any) -> None:
    """300 fake system_info topics (half of them with a message, one with 10⁴ laws): at most
    max_systems followed at any time, the real system among them; once the peer has left,
    every fake is forgotten: subscriptions back to the real system's three, nothing queued.
    Load-proof: the fakes rotate on expire_timeout (3 s, short enough for several turns within
    the deadline); should a stalled machine let the real system fall silent that long, it is
    forgotten and followed again like any other, so every wait is for an eventual state."""
    diag = DiagnosticsNode(context=ros_context, period=3600.0, stale_timeout=0.5,
                           expire_timeout=3.0, max_systems=8)
    # Subscriptions that are not for a followed namespace (left over from other tests: none).
    idle = len(list(diag.subscriptions)) - sum(len(f.subs) for f in diag._follows.values())
    sim = SimulatorNode(Instance("pendulum", "target"), context=ros_context,
                        real_time_factor=0.0)
    hostile = Node("hostile", context=ros_context)
    for k in range(300):
        pub = hostile.create_publisher(SystemInfo, f"/fake{k}/system_info", LATCHED_QOS)
        if k % 2 == 0:
            laws = [f"invariant:i{j}" for j in range(10_000)] if k == 0 else ["energy", "bogus"]
            pub.publish(SystemInfo(instance=f"fake{k}", system="pendulum", laws=laws,
                                   law_scales=[1.0] * len(laws)))
    ex = SingleThreadedExecutor(context=ros_context)
    for n in (diag, sim, hostile):
        ex.add_node(n)
    step = Stepper(sim)
    most = 0
    fakes_seen: set[str] = set()

    def bounded_and_rotating() -> bool:
        nonlocal most
        most = max(most, len(diag._follows))
        fakes_seen.update(ns for ns in diag._follows if ns.startswith("/fake"))
        return "/target" in diag.systems and len(fakes_seen) > 3 * 8
    spin_until(ex, bounded_and_rotating, "fakes followed in turns", step)
    assert most <= 8
    assert all(len(st.laws) <= 256 for st in diag.systems.values())
    ex.remove_node(hostile)
    hostile.destroy_node()  # the peer leaves

    def idle_again() -> bool:
        return (set(diag._follows) == {"/target"} and set(diag.systems) == {"/target"}
                and set(diag._quiet) <= {"/target"}  # no fake queued (the target, if stalled)
                and len(list(diag.subscriptions)) == idle + 3)
    spin_until(ex, idle_again, "the fakes to be forgotten", step)
    assert {key: level_of(diag, "/target", key) for key in diag.systems["/target"].laws} == \
        dict.fromkeys(diag.systems["/target"].laws, 0)
    ex.shutdown()
    for n in (diag, sim):
        n.destroy_node()


def _pendulum_feed(diag: DiagnosticsNode, angle: float = 1.0
                   ) -> tuple[MessageFactory, mechsim.SimulationResult]:
    model = mechsim.load_system("pendulum", **{"initial.angle": angle})
    run = mechsim.simulate(model, 1.0, 0.01, outputs=("energy", "invariants"))
    f = MessageFactory(model, "p")
    laws = model.laws()
    scales = model.law_scales()
    diag.feed("/p", "system_info", f.system_info(0, "dop853", 1e-10, [law.key for law in laws],
                                                 [scales[law.key] for law in laws]))
    return f, run


def _energy(f: MessageFactory, run: mechsim.SimulationResult, k: int, stamp: int,
            kinetic: float | None = None) -> Energy:
    s = Sample(float(run.t[k]), run.q[k], run.v[k], float(run.work_external[k]),
               float(run.work_dissipated[k]))
    s.energy = np.array([run.kinetic[k] if kinetic is None else kinetic, run.potential[k],
                         run.energy_function[k]])
    return f.energy(s, stamp)


def test_nan_sample_is_error_until_finite_values_return(ros_context: Any) -> None:
    diag = DiagnosticsNode(context=ros_context, period=3600.0, discover=False)
    f, run = _pendulum_feed(diag)
    diag.feed("/p", "energy", _energy(f, run, 0, 1, kinetic=math.nan))  # first sample: NaN
    assert level_of(diag, "/p", "energy") == 2
    for k in range(1, 40):
        diag.feed("/p", "energy", _energy(f, run, k, k + 1))
    law = diag.systems["/p"].laws["energy"]
    # Re-based on the first finite sample: E₀ = m g R (1 − cos 1) at rest.
    assert law.initial == pytest.approx(9.81 * (1 - math.cos(1.0)), rel=1e-12)
    assert level_of(diag, "/p", "energy") == 0
    diag.feed("/p", "energy", _energy(f, run, 40, 41, kinetic=math.inf))
    assert level_of(diag, "/p", "energy") == 2
    assert level_of(diag, "/p", "energy_function") == 0  # h is finite in that sample
    for k in range(41, 60):
        diag.feed("/p", "energy", _energy(f, run, k, k + 1))
    assert level_of(diag, "/p", "energy") == 0
    assert law.samples == 60 and law.nonfinite == 2 and law.max_drift < 1e-9
    assert law.worst == math.inf  # the run summary still says a sample was not finite
    # A finite sample that really drifts stays ERROR: recovery is for non-finite samples only.
    diag.feed("/p", "energy", _energy(f, run, 60, 61, kinetic=run.kinetic[60] + 1.0))
    diag.feed("/p", "energy", _energy(f, run, 61, 62))
    assert level_of(diag, "/p", "energy") == 2
    diag.destroy_node()


def test_spoofed_info_and_samples_are_ignored(ros_context: Any) -> None:
    sim = SimulatorNode(Instance("pendulum", "victim", {"initial.angle": 1.0}),
                        context=ros_context, real_time_factor=0.0)
    diag = DiagnosticsNode(context=ros_context, period=3600.0, stale_timeout=3600.0)
    spoofer = Node("spoofer", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    for n in (diag, sim, spoofer):
        ex.add_node(n)
    step = Stepper(sim)
    spin_until(ex, lambda: "/victim" in diag.systems and
               diag.systems["/victim"].laws["energy"].samples >= 20, "the real system", step)
    st = diag.systems["/victim"]
    info, laws = st.info.parameters_yaml, dict(st.laws)
    initial = st.laws["energy"].initial
    # Based on the first sample heard (energy is kept to ~1e-10 between samples).
    assert initial == pytest.approx(9.81 * (1 - math.cos(1.0)), rel=1e-8)
    fake_info = spoofer.create_publisher(SystemInfo, "/victim/system_info", LATCHED_QOS)
    fake_info.publish(SystemInfo(instance="victim", system="pendulum",
                                 parameters_yaml="initial.angle: 3.0\n",
                                 laws=["energy", "invariant:x"], law_scales=[1e9, 1.0]))
    fake_energy = spoofer.create_publisher(Energy, "/victim/energy", STATE_QOS)

    def spoof_heard() -> bool:
        fake_energy.publish(Energy(total=123.0))  # stamp 0: would start a new epoch
        return diag.ignored >= 2
    spin_until(ex, spoof_heard, "the spoofed messages", step)
    n = st.laws["energy"].samples
    spin_until(ex, lambda: st.laws["energy"].samples >= n + 20, "more real samples", step)
    assert diag.systems["/victim"] is st and st.info.parameters_yaml == info
    assert set(st.laws) == set(laws) and st.laws["energy"].initial == initial
    assert st.epoch == 0 and st.laws["energy"].scale == laws["energy"].scale
    assert all(level_of(diag, "/victim", key) == 0 for key in st.laws)
    ex.shutdown()
    for n in (diag, sim, spoofer):
        n.destroy_node()


def test_reset_and_parameter_change_start_a_new_epoch(ros_context: Any) -> None:
    """initial.angle changed, then ~/reset: the laws re-base on the new epoch (E₀ of the new
    angle), no ERROR on a correct run; gravity changed mid-run (state kept): re-based at the
    change, OK after it."""
    sim = SimulatorNode(Instance("pendulum", "swing", {"initial.angle": 1.0}),
                        context=ros_context, real_time_factor=0.0)
    diag = DiagnosticsNode(context=ros_context, period=3600.0, stale_timeout=3600.0)
    client_node = Node("client", context=ros_context)
    reset = client_node.create_client(Trigger, "/swing/simulator/reset")
    ex = SingleThreadedExecutor(context=ros_context)
    for n in (diag, sim, client_node):
        ex.add_node(n)
    step = Stepper(sim)

    def energy_samples() -> int:
        st = diag.systems.get("/swing")
        return st.laws["energy"].samples if st is not None else 0
    spin_until(ex, lambda: energy_samples() >= 50, "samples of the first epoch", step)
    assert sim.set_parameters([Parameter("initial.angle", value=2.5)])[0].successful
    for _ in range(20):
        step()  # initial values take effect at the reset: the same motion goes on
    spin_until(ex, reset.service_is_ready, "the reset service")
    future = reset.call_async(Trigger.Request())
    spin_until(ex, future.done, "the reset answer")
    assert future.result().success and sim.t == 0.0
    st = diag.systems["/swing"]
    epoch = st.epoch
    n = energy_samples()
    spin_until(ex, lambda: energy_samples() >= n + 100 and st.epoch > epoch,
               "samples of the new epoch", step)
    law = st.laws["energy"]
    assert law.initial == pytest.approx(9.81 * (1 - math.cos(2.5)), rel=1e-8)  # new angle
    assert {key: level_of(diag, "/swing", key) for key in st.laws} == dict.fromkeys(st.laws, 0)
    # Gravity changed while the pendulum swings: E = T + V jumps with V, a new epoch starts.
    epoch = st.epoch
    assert sim.set_parameters([Parameter("gravity", value=20.0)])[0].successful
    n = energy_samples()
    spin_until(ex, lambda: energy_samples() >= n + 100 and st.epoch > epoch,
               "samples after the change", step)
    assert {key: level_of(diag, "/swing", key) for key in st.laws} == dict.fromkeys(st.laws, 0)
    assert law.scale == pytest.approx(20.0 * (1 - math.cos(2.5)), rel=1e-12)  # from system_info
    ex.shutdown()
    for n in (diag, sim, client_node):
        n.destroy_node()
