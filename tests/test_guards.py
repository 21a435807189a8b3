"""Guards of a running scene: a non-finite state or an enforced constraint residual past the hard
limit stops that system only — last good state kept, ERROR on /diagnostics, one log line naming
the cause — while the rest of the scene runs on and a recording in progress stays valid.

The fault is injected mid-scene, from a sink of ``run_scene``, into the live integration state
of one node (found through the garbage collector: no code of the guards is patched), so a
removed guard makes these tests fail: the error would escape ``run_scene`` or the corrupted
system would keep publishing garbage.
"""

from __future__ import annotations

import math
import weakref
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
import yaml

from mechsim.outputs.sink import Capabilities
from mechsim.ros.launch import FAST_CHUNK
from mechsim.scene import parse_scene

RATE = 50.0
# Several fast chunks, so that a fault injected while one is published is met by the next.
DURATION = 2.5 * FAST_CHUNK / RATE
FAULT_AT = 0.5


#: The simulator nodes made in this test (weak references): where a sink finds its victim.
_MADE: list[weakref.ref[Any]] = []


@pytest.fixture(autouse=True)
def _nodes_made(monkeypatch: pytest.MonkeyPatch) -> Any:
    from mechsim.ros.simulator import SimulatorNode

    made = SimulatorNode.__init__

    def init(self: Any, *args: Any, **kwargs: Any) -> None:
        made(self, *args, **kwargs)
        _MADE.append(weakref.ref(self))

    monkeypatch.setattr(SimulatorNode, "__init__", init)
    yield
    _MADE.clear()


class Injector:
    """Sink: when ``<victim>/state`` passes ``FAULT_AT``, corrupt the victim's stepper state."""

    capabilities = Capabilities()

    def __init__(self, victim: str, corrupt: Any) -> None:
        self.victim = victim
        self.corrupt = corrupt
        self.done_at: float | None = None
        self.stepped_to: float | None = None  # the stepper's time when it was corrupted
        self.diagnostics: list[Any] = []
        self.states: Counter[str] = Counter()
        self.last_state: dict[str, Any] = {}

    def _node(self) -> Any:
        nodes = [o for o in (ref() for ref in _MADE) if o is not None
                 and o.instance.name == self.victim and o.failed is None and o.context.ok()]
        assert len(nodes) == 1
        return nodes[0]

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        if topic == "/diagnostics":
            self.diagnostics.append(msg)
        if topic.endswith("/state"):
            name = topic.split("/")[1]
            self.states[name] += 1
            self.last_state[name] = (list(msg.position), list(msg.velocity))
            t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 - 1.0
            if name == self.victim and self.done_at is None and t >= FAULT_AT - 1e-9:
                node = self._node()
                self.stepped_to = float(node.stepper.t)  # a chunk may be stepped ahead
                self.corrupt(node)
                self.done_at = t


def _scene() -> Any:
    return parse_scene({"name": "guards", "publish_rate": RATE, "systems": [
        {"system": "pendulum", "name": "good"},
        {"system": "pendulum", "name": "victim", "parameters": {"formulation": "multiplier"},
         "method": "dop853"},
        {"system": "kepler", "name": "other"}]})


def _run(ros_context: Any, tmp_path: Path, corrupt: Any,
         caplog: pytest.LogCaptureFixture | None = None) -> tuple[Any, Injector, Path]:
    from mechsim.outputs.bag import BagWriter
    from mechsim.ros.launch import run_scene
    from mechsim.ros.record import scene_custom_data

    scene = _scene()
    inj = Injector("victim", corrupt)
    bag = BagWriter(tmp_path / "bag", scene_custom_data(scene))
    try:
        run = run_scene(scene, fast=True, duration=DURATION, sinks=[bag, inj],
                        context=ros_context)
    except BaseException:
        bag.abort()
        raise
    bag.close()
    return run, inj, tmp_path / "bag"


def _check_scene_went_on(run: Any, inj: Injector, bag: Path, cause: str) -> None:
    full = int(round(DURATION * RATE)) + 1  # t = 0 included
    assert inj.done_at is not None
    # The victim stopped, with the cause named; the others ran to the end.
    assert set(run.failures) == {"victim"}
    assert cause in run.failures["victim"]
    assert run.samples["good"] == run.samples["other"] == full
    # Nothing stepped after the corruption is published (the samples of a chunk stepped before
    # it are valid and are).
    assert inj.stepped_to is not None
    assert run.samples["victim"] <= int(round(inj.stepped_to * RATE)) + 2
    assert inj.states["good"] == full and inj.states["victim"] == run.samples["victim"]
    # Last good state kept: what was published last is finite.
    q, v = inj.last_state["victim"]
    assert all(math.isfinite(x) for x in q + v)
    # ERROR on /diagnostics for the victim's integration, naming the cause.
    errors = [s for m in inj.diagnostics for s in m.status
              if s.name == "mechsim/victim/integration" and s.level == b"\x02"]
    assert len(errors) == 1 and cause in errors[0].message
    # The recording stays valid: an independent reader gets every published message back.
    from rosbags.highlevel import AnyReader

    counts: Counter[str] = Counter()
    with AnyReader([bag]) as reader:
        for con, _, raw in reader.messages():
            counts[con.topic] += 1
            if con.topic == "/diagnostics":
                reader.deserialize(raw, con.msgtype)
    published = {t: n for t, n in run.messages.items() if n}
    assert dict(counts) == published
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["message_count"] == sum(published.values())
    assert counts["/victim/state"] == run.samples["victim"]
    assert counts["/good/state"] == full


def test_non_finite_state_stops_one_system(ros_context: Any, tmp_path: Path) -> None:
    def corrupt(node: Any) -> None:
        node.stepper.y[0] = math.nan

    run, inj, bag = _run(ros_context, tmp_path, corrupt)
    # The stepper meets the NaN in its own loop (rejections to underflow, or non-finite).
    assert "victim" in run.failures
    reason = run.failures["victim"]
    cause = "non-finite" if "non-finite" in reason else "step size underflow"
    _check_scene_went_on(run, inj, bag, cause)


def test_constraint_residual_past_hard_limit_stops_one_system(ros_context: Any,
                                                              tmp_path: Path) -> None:
    """The stepper's copy of the rod length corrupted (doubled): it keeps a consistent state on
    the wrong circle, the integration itself never fails, and only the residual guard (which
    measures against the node's parameters) can notice and stop the system."""

    def corrupt(node: Any) -> None:
        numeric = [p.name for p in node.model.parameter_spec() if p.is_numeric]
        p = node.stepper.p.copy()
        p[numeric.index("length")] *= 2.0
        node.stepper.p[:] = node.model.complete_parameters(p)  # with the constants of 2L

    run, inj, bag = _run(ros_context, tmp_path, corrupt)
    _check_scene_went_on(run, inj, bag, "constraint residual constraint_rod_length")
    assert "hard limit" in run.failures["victim"]


def test_constraint_guard_quiet_on_healthy_runs(ros_context: Any) -> None:
    """Projected runs stay at round-off: the hard limit never fires on a long healthy run of
    every constrained form used in scenes (no false stops)."""
    from mechsim.ros.launch import run_scene

    scene = parse_scene({"name": "healthy", "publish_rate": 20.0, "systems": [
        {"system": "pendulum", "name": "p", "parameters": {"formulation": "multiplier",
                                                          "initial.angle": 3.1}},
        {"system": "double_pendulum", "name": "d", "parameters": {"formulation": "multiplier"}},
        {"system": "rigid_body", "name": "r"}]})
    run = run_scene(scene, fast=True, duration=20.0, context=ros_context)
    assert run.failures == {}
    assert all(n == 401 for n in run.samples.values())


def test_constraint_limit_parameter_validated(ros_context: Any) -> None:
    from mechsim.environment import import_rclpy

    import_rclpy()
    from rclpy.parameter import Parameter

    from mechsim.ros.simulator import SimulatorNode
    from mechsim.scene import Instance

    node = SimulatorNode(Instance("pendulum", "lim", {"formulation": "multiplier"}),
                         context=ros_context, real_time_factor=0.0)
    try:
        for bad in (-1.0, 0.0, math.nan, math.inf):
            res = node.set_parameters([Parameter("constraint_limit", value=bad)])[0]
            assert not res.successful and res.reason, bad
        assert node.set_parameters([Parameter("constraint_limit", value=1e-9)])[0].successful
        assert node.constraint_limit == 1e-9
    finally:
        node.destroy_node()
