"""Graph hygiene: a scene refuses to start a simulator whose name a live node already uses, or a
second /clock, with one line naming the running node; a name left behind by a node that no
longer answers (a killed process) does not block a start."""

from __future__ import annotations

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
