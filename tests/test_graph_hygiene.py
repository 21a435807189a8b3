"""Graph hygiene: a scene refuses to start a simulator whose name a live node already uses, or a
second /clock, with one line naming the running node; a name left behind by a node that no
longer answers (a killed process) does not block a start."""

from __future__ import annotations

import math
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from mechsim.environment import import_rclpy

rclpy = import_rclpy()
from rclpy.executors import SingleThreadedExecutor  # noqa: E402

from mechsim.errors import MechsimError  # noqa: E402
from mechsim.ros.launch import run_scene  # noqa: E402
from mechsim.ros.simulator import SimulatorNode  # noqa: E402
from mechsim.scene import Instance, parse_scene  # noqa: E402
from mechsim.testing import wait_until  # noqa: E402


@contextmanager
def running(ctx: Any, name: str, clock: bool = False) -> Iterator[SimulatorNode]:
    """A simulator node that answers (spun in a background thread) for the block."""
    node = SimulatorNode(Instance("pendulum", name), context=ctx, real_time_factor=0.0,
                         publish_clock=clock)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            ex.spin_once(timeout_sec=0.05)

    thread = threading.Thread(target=spin, daemon=True)
    thread.start()
    try:
        yield node
    finally:
        stop.set()
        thread.join(timeout=60)
        ex.shutdown()
        node.destroy_node()


def _scene(name: str) -> Any:
    return parse_scene({"name": "second", "pacing": "fast", "duration": 0.2,
                        "publish_rate": 20.0, "systems": [{"system": "kepler", "name": name}]})


@pytest.fixture
def patient(monkeypatch: pytest.MonkeyPatch) -> None:
    """A discovery window long enough for a loaded machine: the conflict refuses the start
    as soon as it is seen, so the window is a deadline, not a wait."""
    monkeypatch.setenv("MECHSIM_GRAPH_WAIT", "120")


def test_second_node_with_the_same_name_refused(ros_context: Any, tmp_path: Path,
                                                patient: None) -> None:
    from mechsim.ros.record import run_with_outputs

    with running(ros_context, "twin"):
        with pytest.raises(MechsimError) as err:
            run_scene(_scene("twin"))  # its own context: another participant on the domain
        text = str(err.value)
        assert "/twin/simulator is already running" in text and "\n" not in text
        # Recording: refused the same way, and no empty bag is left behind.
        with pytest.raises(MechsimError, match="/twin/simulator is already running"):
            run_with_outputs(_scene("twin"), fast=True, duration=0.2, bag=str(tmp_path / "b"))
        assert not (tmp_path / "b").exists()


def _several(*names: str) -> Any:
    return parse_scene({"name": "several", "pacing": "fast", "duration": 0.2,
                        "publish_rate": 20.0,
                        "systems": [{"system": "pendulum", "name": n} for n in names]})


def test_a_conflict_refuses_a_start_whose_nodes_are_made_during_the_window(
        ros_context: Any, patient: None) -> None:
    """The nodes of a scene are made while the discovery window runs: a live node of one of
    its names still refuses the start, before any of its nodes released a sample, and the
    refused start leaves none of its nodes in the graph."""
    probe = rclpy.create_node("hygiene_probe", context=ros_context)
    started: list[str] = []
    try:
        with running(ros_context, "overlap_twin"):
            with pytest.raises(MechsimError, match="^instance 'overlap_twin': "
                               "/overlap_twin/simulator is already running"):
                run_scene(_several("overlap_a", "overlap_b", "overlap_twin"),
                          before_first_message=lambda node: started.append(node.get_name()))
        assert started == []  # no node of the refused start published anything
        ex = SingleThreadedExecutor(context=ros_context)
        ex.add_node(probe)
        try:
            assert wait_until(ex, lambda: not any(
                ns in ("/overlap_a", "/overlap_b", "/overlap_twin")
                for _, ns in probe.get_node_names_and_namespaces())), \
                "the refused start's nodes stayed in the graph"
        finally:
            ex.shutdown()
    finally:
        probe.destroy_node()


def test_the_starts_own_nodes_are_not_in_the_way() -> None:
    """A scene of several instances, one publishing /clock, made during its own window:
    none of its nodes counts as a conflict, and each starts once the check passed."""
    started: list[str] = []
    run = run_scene(_several("own_a", "own_b", "own_c"), graph_wait=1.0,
                    before_first_message=lambda node: started.append(node.get_namespace()))
    assert run.samples == {"own_a": 5, "own_b": 5, "own_c": 5} and not run.failures
    assert started == ["/own_a", "/own_b", "/own_c"]


def test_second_clock_refused(ros_context: Any, patient: None) -> None:
    with running(ros_context, "clocky", clock=True):
        with pytest.raises(MechsimError, match="/clock is already published .* by "
                           "/clocky/simulator"):
            run_scene(_scene("other"))


def test_a_name_that_no_longer_answers_does_not_block(ros_context: Any) -> None:
    """A node that exists in the graph but never answers (as a killed process's entry until
    its lease expires) is not a running instance: the scene starts."""
    frozen = SimulatorNode(Instance("pendulum", "ghost"), context=ros_context,
                           real_time_factor=0.0, publish_clock=True)
    try:
        run = run_scene(_scene("ghost"))
        assert run.samples == {"ghost": 5} and not run.failures
    finally:
        frozen.destroy_node()


@pytest.mark.parametrize("raw", ["-1", "nan", "inf", "601", "two", "1e400"])
def test_a_bad_discovery_window_is_one_line(raw: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("MECHSIM_GRAPH_WAIT", raw)
    with pytest.raises(MechsimError) as err:
        run_scene(_scene("windowed"))
    text = str(err.value)
    assert text.startswith("MECHSIM_GRAPH_WAIT: ") and "0 … 600" in text and "\n" not in text


def test_a_window_of_zero_starts_without_looking(ros_context: Any,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """``MECHSIM_GRAPH_WAIT=0``: no graph check (a run on a domain of its own), so a second
    node of the same name is not refused."""
    monkeypatch.setenv("MECHSIM_GRAPH_WAIT", "0")
    with running(ros_context, "unchecked"):
        run = run_scene(_scene("unchecked"))
    assert run.samples == {"unchecked": 5} and not run.failures


class _Future:
    def __init__(self) -> None:
        self.answered = False

    def done(self) -> bool:
        return self.answered


class _Client:
    """A parameter-service client whose service is discovered at ``ready_at`` and answers
    requests if ``answers``."""

    def __init__(self, clock: list[float], ready_at: float, answers: bool) -> None:
        self.clock, self.ready_at, self.answers = clock, ready_at, answers
        self.asked: list[_Future] = []

    def service_is_ready(self) -> bool:
        return self.clock[0] >= self.ready_at

    def call_async(self, request: Any) -> _Future:
        future = _Future()
        future.answered = self.answers
        self.asked.append(future)
        return future


class _Node:
    def __init__(self, client: _Client) -> None:
        self.client = client

    def create_client(self, kind: Any, name: str) -> _Client:
        assert name == "/twin/simulator/list_parameters"
        return self.client


def _polls(client: _Client, seen: float, end: float, until: float) -> list[tuple[float, Any]]:
    """(time, answer) of a liveness probe polled every 50 ms from ``seen`` to ``until``."""
    from mechsim.ros.graph_check import _Liveness

    clock = client.clock
    clock[0] = seen
    probe = _Liveness(_Node(client), "/twin/simulator", seen)
    answers = []
    while clock[0] <= until:
        answers.append((clock[0], probe.poll(clock[0], end)))
        clock[0] = round(clock[0] + 0.05, 10)
    return answers


def test_a_node_whose_service_is_discovered_late_still_counts() -> None:
    """Found in the graph at 1 s, its parameter service discovered only at 6 s (a loaded
    machine), inside a 120 s window: undecided until then, then alive (it was given up as
    gone after 2 s before, and a second node of its name started)."""
    client = _Client([0.0], ready_at=6.0, answers=True)
    answers = _polls(client, seen=1.0, end=120.0, until=6.5)
    assert all(a is None for t, a in answers if t < 6.0)
    assert any(a is True for t, a in answers if t >= 6.0)


def test_a_node_that_never_answers_is_gone_after_the_liveness_timeout() -> None:
    """Its service discovered but silent (a frozen node, a killed process's entry): asked
    again every 0.5 s, gone 2 s after the first request, within a long window too."""
    from mechsim.ros.graph_check import ASK_AGAIN, LIVENESS_TIMEOUT

    client = _Client([0.0], ready_at=0.0, answers=False)
    answers = _polls(client, seen=1.0, end=120.0, until=4.0)
    assert all(a is None for t, a in answers if t < 1.0 + LIVENESS_TIMEOUT)
    assert all(a is False for t, a in answers if t >= 1.0 + LIVENESS_TIMEOUT)
    assert len(client.asked) == round(LIVENESS_TIMEOUT / ASK_AGAIN)  # then no more


def test_a_node_never_reachable_is_gone_at_the_end_of_the_window() -> None:
    """Never discovered: undecided until the window ends, or the liveness timeout after it
    was seen, whichever is later; then gone (the start goes ahead)."""
    client = _Client([0.0], ready_at=1e9, answers=True)
    answers = _polls(client, seen=0.5, end=2.0, until=3.0)
    assert all(a is None for t, a in answers if t < 2.5)
    assert all(a is False for t, a in answers if t >= 2.5)
    assert not client.asked


@pytest.mark.parametrize("seconds", [math.inf, math.nan, -0.5, 601.0])
def test_a_bad_graph_wait_argument_is_refused(seconds: float) -> None:
    """``run_scene(graph_wait=inf)`` looped for ever without a conflict; nan skipped the
    check without a word."""
    with pytest.raises(MechsimError, match="^graph_wait: .* 0 … 600$"):
        run_scene(_scene("argued"), graph_wait=seconds)
