"""The run core (``mechsim.runcore``) stepped without ROS: the same samples as the node that
publishes them and as ``simulate()``; parameter changes as transactions, resets, the effort
hold and the guards, observed by a plain Python observer."""

from __future__ import annotations

import math
import subprocess
import sys
import threading
from typing import Any

import numpy as np
import pytest

from mechsim.errors import MechsimError
from mechsim.outputs.sink import Capabilities
from mechsim.runcore import run as run_module
from mechsim.runcore.change import Settings
from mechsim.runcore.pacing import BLOCK
from mechsim.runcore.run import Block, SystemRun
from mechsim.scene import Instance
from mechsim.simulate import OUTPUTS, OutputShape, simulate
from mechsim.systems import load_system

RATE = 50.0


class Collector:
    """An observer that keeps every released sample: what a node would publish."""

    def __init__(self, want: tuple[str, ...] = OUTPUTS, controller: bool = False) -> None:
        self.want = want
        self.controller = controller
        self.times: list[float] = []
        self.Y: list[np.ndarray] = []
        self.outputs: dict[str, list[np.ndarray]] = {name: [] for name in OUTPUTS}
        self.models: list[tuple[Any, bool]] = []
        self.laws = 0
        self.efforts: list[tuple[float, list[float]]] = []
        self.stops: list[str] = []
        self.notices: list[str] = []
        self.run: SystemRun | None = None

    def wanted(self) -> tuple[str, ...]:
        assert self.run is not None
        shape = self.run.shape
        have = {"energy": True, "invariants": bool(shape.invariants),
                "observables": bool(shape.observables),
                "frames": any(not f.static for f in self.run.model.frames)}
        return tuple(name for name in self.want if have[name])

    def encode(self, block: Block) -> None:
        block.encoded = "ready"

    def release(self, block: Block, a: int, b: int) -> None:
        assert block.encoded == "ready"
        self.times += block.times[a:b].tolist()
        self.Y += list(block.Y[a:b])
        for name, values in block.outputs.items():
            self.outputs[name] += list(values[a:b])

    def flush(self) -> None:
        pass

    def model_changed(self, model: Any, structural: bool) -> None:
        self.models.append((model, structural))

    def laws_changed(self) -> None:
        self.laws += 1

    def effort_applied(self, u: np.ndarray) -> None:
        assert self.run is not None
        self.efforts.append((self.run.t, u.tolist()))

    def stopped(self, reason: str) -> None:
        self.stops.append(reason)

    def effort_notice(self, message: str) -> None:
        self.notices.append(message)

    def controller_present(self) -> bool:
        return self.controller


def _run(system: str = "pendulum", params: dict[str, Any] | None = None,
         method: str = "auto", end_time: float | None = None,
         observer: Collector | None = None) -> tuple[SystemRun, Collector]:
    seen = observer or Collector()
    run = SystemRun(load_system(system, **(params or {})), method,
                    Settings(publish_rate=RATE, real_time_factor=0.0), seen, stepped=True,
                    end_time=end_time)
    seen.run = run
    run.start()
    return run, seen


def test_the_core_runs_without_ros() -> None:
    """Stepped, changed, reset and stopped in a process that never imports rclpy."""
    code = """if True:
        import sys
        from tests.test_runcore import _run
        run, seen = _run("pendulum", {"formulation": "multiplier"}, end_time=2.0)
        assert run.advance_to(10.0) == 100 and run.finished
        run.commit(run.plan([("gravity", 3.0)]))
        run.reset()
        assert run.advance_to(1.0) == 50 and len(seen.times) == 1 + 100 + 1 + 1 + 50
        assert not any(m.startswith(("rclpy", "rcl_", "rmw")) for m in sys.modules), \\
            sorted(m for m in sys.modules if m.startswith("rcl"))
    """
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=600, cwd=str(__import__("pathlib").Path(__file__).parents[1]))
    assert r.returncode == 0, r.stderr


def test_the_core_gives_what_simulate_gives() -> None:
    """The samples of a run stepped in chunks are simulate()'s at the same times (an
    independent path: one call of the stepper over the whole span)."""
    run, seen = _run("double_pendulum", method="dop853", end_time=4.0)
    for k in range(1, 9):
        run.advance_to(0.5 * k)
    model = load_system("double_pendulum")
    ref = simulate(model, 4.0, 1.0 / RATE, method="dop853")
    assert np.allclose(seen.times, ref.t, rtol=0, atol=1e-12)
    Y = np.array(seen.Y)
    at = model.layout
    assert np.allclose(Y[:, at.q], ref.q, rtol=1e-9, atol=1e-9)
    assert np.allclose(Y[:, at.v], ref.v, rtol=1e-9, atol=1e-9)
    E = np.array(seen.outputs["energy"])
    assert np.allclose(E[:, 0], ref.kinetic, rtol=1e-9, atol=1e-9)
    assert np.allclose(E[:, 1], ref.potential, rtol=1e-9, atol=1e-9)
    assert seen.laws == 1 and seen.stops == []


def test_the_node_publishes_what_its_core_releases(ros_context: Any) -> None:
    """The node's messages carry exactly the core's samples: same stamps, state, energy,
    invariants and observables, bit for bit (a node is its core plus the encoding)."""
    from mechsim.outputs.messages import DEFAULT_TIME_OFFSET, stamps_ns
    from mechsim.ros.simulator import SimulatorNode

    class Sink:
        capabilities = Capabilities()  # every message of every topic

        def __init__(self) -> None:
            self.got: dict[str, list[tuple[int, Any]]] = {}

        def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
            self.got.setdefault(topic.rpartition("/")[2], []).append((ns, msg))

    sink = Sink()
    params = {"formulation": "multiplier", "initial.angle": 2.0}
    node = SimulatorNode(Instance("pendulum", "same", params), context=ros_context,
                         publish_rate=RATE, real_time_factor=0.0, sinks=[sink])
    try:
        for k in range(1, 4):
            node.advance_to(0.7 * k)
        node.outlet.hand_over()
    finally:
        node.destroy_node()
    run, seen = _run("pendulum", params)
    for k in range(1, 4):
        run.advance_to(0.7 * k)
    n = len(seen.times)
    assert n == int(round(2.1 * RATE)) + 1
    ns = stamps_ns(np.array(seen.times), DEFAULT_TIME_OFFSET)
    Y = np.array(seen.Y)
    at = run.model.layout
    state = sink.got["state"]
    assert [s for s, _ in state] == ns.tolist()
    assert np.array_equal([m.position for _, m in state], Y[:, at.q])
    assert np.array_equal([m.velocity for _, m in state], Y[:, at.v])
    energy = [m for _, m in sink.got["energy"]]
    E = np.array(seen.outputs["energy"])
    assert np.array_equal([[m.kinetic, m.potential, m.energy_function] for m in energy], E)
    assert np.array_equal([[m.work_external, m.work_dissipated] for m in energy],
                          Y[:, [at.work_external, at.work_dissipated]])
    shape = OutputShape.of(run.model)
    for leaf, names in (("invariants", shape.invariants), ("observables", shape.observables)):
        msgs = [m for _, m in sink.got[leaf]]
        assert [[s.name for s in m.scalars] for m in msgs] == [list(names)] * n
        assert np.array_equal([[s.value for s in m.scalars] for m in msgs],
                              np.array(seen.outputs[leaf]))


def test_a_change_is_all_or_nothing() -> None:
    run, seen = _run("pendulum")
    run.advance_to(0.3)
    before = (run.model, run.stepper, run.epoch, run.t, dict(run.values))
    with pytest.raises(MechsimError, match="mass"):
        run.plan([("gravity", 3.0), ("mass", -1.0)])  # the second value is bad: neither
    assert (run.model, run.stepper, run.epoch, run.t, run.values) == before
    change = run.plan([("gravity", 3.0), ("publish_rate", 25.0)])
    assert (run.model, run.stepper) == before[:2]  # planned, not committed
    run.commit(change)
    # The current sample again (same time: a new epoch), with the new parameters.
    assert run.epoch == before[2] + 1 and seen.times[-2:] == [0.3, 0.3]
    assert run.model.value("gravity") == 3.0 and run.advance_to(0.5) == 5  # 25 Hz now


def test_a_structural_change_restarts_and_initial_values_wait_for_a_reset() -> None:
    run, seen = _run("pendulum")
    run.advance_to(0.2)
    run.commit(run.plan([("initial.angle", 0.5)]))
    assert run.t == pytest.approx(0.2)  # continues from the current state
    run.commit(run.plan([("formulation", "multiplier")]))
    assert run.t == 0.0 and seen.models[-1][1] is True
    # The new equations, from the initial values stored before.
    y0 = load_system("pendulum", formulation="multiplier", **{"initial.angle": 0.5}).initial_y()
    assert np.array_equal(seen.Y[-1], y0)
    run.advance_to(0.2)
    run.reset()
    assert run.t == 0.0 and seen.times[-1] == 0.0 and np.array_equal(seen.Y[-1], y0)


def test_the_effort_hold() -> None:
    """A command applies from the next sample, is held over the sample periods, returns to
    zero after the timeout; a bad one is refused with its reason and changes nothing."""
    run, seen = _run("pendulum")
    run.commit(run.plan([("effort_timeout", 0.1)]))
    assert run.offer(np.array([1.0, 2.0])) == ("length", pytest.approx(
        "2 values, expected 1 (one per coordinate: angle)"))
    assert run.offer(np.array([math.nan]))[0] == "finite"  # type: ignore[index]
    assert run.offer(np.array([0.5])) is None
    run.advance_to(0.5)
    assert seen.efforts == [(0.0, [0.5]), (pytest.approx(0.1), [0.0])]
    assert (run.effort.received, run.effort.rejected) == (1, 2)
    assert seen.laws == 2  # the start, the first effort (only the laws that then hold)
    W = np.array(seen.Y)[:, run.model.layout.work_external]
    assert W[1] != 0.0 and W[-1] == W[6]  # work done while held, none after


def test_a_guard_stops_the_system_and_keeps_the_last_good_state() -> None:
    run, seen = _run("pendulum", {"formulation": "multiplier"}, method="dop853")
    run.advance_to(0.5)
    good = seen.Y[-1].copy()
    run.stepper.y[0] = math.nan  # corrupt the stepper's state
    run.advance_to(1.0)
    assert run.failed and len(seen.stops) == 1 and seen.stops[0] == run.failed
    assert np.isfinite(np.array(seen.Y)).all() and run.advance_to(2.0) == 0
    assert run.t <= 1.0 and np.isfinite(run.y).all()
    run.reset()  # a reset starts again
    assert run.failed is None and run.advance_to(0.1) == 5
    assert not np.array_equal(seen.Y[-1], good)


def test_paced_lookahead_releases_only_what_is_due() -> None:
    """Computed ahead in one call of the kernels, released as it becomes due; a command
    drops what was computed ahead and applies from the next sample."""
    run, seen = _run("pendulum")
    run.lookahead = 20
    integrated = []
    advance = run.stepper.advance
    run.stepper.advance = lambda t: integrated.append(t.size) or advance(t)  # type: ignore
    # To the next block boundary (every 20 samples, the first at t = 0).
    assert run.advance_to(0.1) == 5 and integrated == [19]
    assert run.advance_to(0.2) == 5 and integrated == [19]  # released from the block ahead
    run.offer(np.array([0.3]))
    assert run.advance_to(0.24) == 2
    assert integrated == [19, 1, 1]  # the rest dropped; held: sample by sample
    assert seen.efforts == [(pytest.approx(0.2), [0.3])]
    assert seen.times == pytest.approx([k / RATE for k in range(13)])


class _Counted:
    """``run.NextBlock`` counting the blocks integrated ahead."""

    made = 0

    def __init__(self, *args: Any) -> None:
        type(self).made += 1
        self.inner = run_module.NextBlock.__wrapped__(*args)  # type: ignore[attr-defined]

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


def _blocks_ahead(monkeypatch: pytest.MonkeyPatch) -> type[_Counted]:
    class Counted(_Counted):
        made = 0

    Counted.__wrapped__ = run_module.NextBlock  # type: ignore[attr-defined]
    monkeypatch.setattr(run_module, "NextBlock", Counted)
    monkeypatch.setattr(SystemRun, "integrates_ahead", True)  # (off by default)
    return Counted


def _in_block_calls(run: SystemRun, t_end: float) -> None:
    """``run`` to ``t_end`` one block per call: no block is integrated ahead."""
    while run.t < t_end - 1e-9 and run.advance_to(min(run.t + BLOCK / RATE, t_end)):
        pass


@pytest.mark.parametrize(("system", "method", "ahead"), [
    ("double_pendulum", "radau15", 3), ("three_body", "auto", 3), ("pendulum", "dop853", 3),
    ("gas_in_box", "auto", 0)])
def test_blocks_integrated_ahead_change_no_sample(system: str, method: str, ahead: int,
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    """Unpaced, a run integrates each block's successor while it releases the block
    (``NextBlock``): 3.5 blocks in one call give the samples of calls one block each, bit
    for bit. A model with events (the gas's collisions) integrates them one after the
    other."""
    counted = _blocks_ahead(monkeypatch)
    t_end = 3.5 * BLOCK / RATE
    whole, seen_whole = _run(system, method=method)
    assert whole.advance_to(t_end) == 3.5 * BLOCK and counted.made == ahead
    part, seen_part = _run(system, method=method)
    _in_block_calls(part, t_end)
    assert counted.made == ahead  # (none more: nothing was left to integrate ahead)
    assert seen_whole.times == seen_part.times
    assert np.array_equal(np.array(seen_whole.Y), np.array(seen_part.Y))
    for name in OUTPUTS:
        assert np.array_equal(np.array(seen_whole.outputs[name]),
                              np.array(seen_part.outputs[name]))


def test_a_stop_drops_the_block_integrated_ahead(monkeypatch: pytest.MonkeyPatch) -> None:
    """A guard that stops the system in a block whose successor was being integrated: the
    same samples released and the same reason as without the block ahead, nothing after."""
    counted = _blocks_ahead(monkeypatch)

    def poisoned(system_run: SystemRun) -> None:
        advance = system_run.stepper.advance

        def poisoned_advance(t: np.ndarray) -> np.ndarray:
            Y = advance(t)
            at = np.flatnonzero(np.isclose(t, 1.5 * BLOCK / RATE))
            if at.size:
                Y[at[0], 0] = math.nan  # the state goes bad half way through block 2
            return Y

        system_run.stepper.advance = poisoned_advance  # type: ignore[method-assign, assignment]

    whole, seen_whole = _run("pendulum", method="dop853")
    poisoned(whole)
    whole.advance_to(3 * BLOCK / RATE)
    assert counted.made == 2  # block 2 while block 1 left; block 3 while block 2 did
    part, seen_part = _run("pendulum", method="dop853")
    poisoned(part)
    _in_block_calls(part, 3 * BLOCK / RATE)
    assert whole.failed and whole.failed == part.failed
    assert len(seen_whole.times) == len(seen_part.times) == 1 + 1.5 * BLOCK - 1
    assert np.array_equal(np.array(seen_whole.Y), np.array(seen_part.Y))
    assert whole.t == part.t and np.array_equal(whole.y, part.y)


def test_an_effort_during_a_block_drops_the_block_integrated_ahead(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A command offered while a block is released (from another thread, as a controller's
    callback may) applies from the next sample: the block integrated ahead without it is
    dropped, and the samples are those of a run given the command between two calls."""
    counted = _blocks_ahead(monkeypatch)

    class Commanding(Collector):
        def release(self, block: Block, a: int, b: int) -> None:
            super().release(block, a, b)
            if len(self.times) == 1 + BLOCK:  # the first block out
                assert self.run is not None
                threading.Thread(target=self.run.offer, args=(np.array([0.2]),)).start()

    whole, seen_whole = _run("pendulum", method="dop853", observer=Commanding())
    whole.commit(whole.plan([("effort_timeout", 1e3)]))
    whole.advance_to(2 * BLOCK / RATE)
    assert counted.made == 1
    part, seen_part = _run("pendulum", method="dop853")
    part.commit(part.plan([("effort_timeout", 1e3)]))
    part.advance_to(BLOCK / RATE)
    assert part.offer(np.array([0.2])) is None
    part.advance_to(2 * BLOCK / RATE)
    assert seen_whole.efforts == seen_part.efforts == [(pytest.approx(BLOCK / RATE), [0.2])]
    assert seen_whole.times == seen_part.times
    assert np.array_equal(np.array(seen_whole.Y), np.array(seen_part.Y))
