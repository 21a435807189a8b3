"""A scene's loop keeps the objects alive at its start out of the garbage collector's passes
(``gc.freeze``) while it runs, and gives them back when it ends, leaving a caller's own frozen
objects as they were."""

from __future__ import annotations

import gc
from typing import Any

from mechsim.outputs.sink import Capabilities, Takes
from mechsim.ros.launch import _start_frozen


def test_the_objects_alive_at_the_start_are_frozen_for_the_loop_only() -> None:
    gc.unfreeze()
    alive = len(gc.get_objects())
    with _start_frozen():
        assert gc.get_freeze_count() >= alive // 2
        made = [[k] for k in range(100)]  # made during the loop: collected as ever
        ids = {id(m) for m in made}
        assert sum(id(o) in ids for o in gc.get_objects()) == len(made)
    assert gc.get_freeze_count() == 0


def test_a_callers_frozen_objects_stay_frozen() -> None:
    gc.freeze()
    try:
        frozen = gc.get_freeze_count()
        with _start_frozen():
            assert gc.get_freeze_count() == frozen
        assert gc.get_freeze_count() == frozen
    finally:
        gc.unfreeze()


class _FreezeSeen:
    """A sink noting the frozen-object count whenever the loop hands it samples."""

    capabilities = Capabilities(Takes.COLUMNS)

    def __init__(self) -> None:
        self.counts: list[int] = []

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        self.counts.append(gc.get_freeze_count())

    def write_columns(self, topic: str, ns: Any, values: Any) -> None:
        self.counts.append(gc.get_freeze_count())


def test_a_run_freezes_while_it_steps_and_thaws_at_its_end(ros_context: Any) -> None:
    from mechsim.ros.launch import run_scene
    from mechsim.scene import single_system_scene

    gc.unfreeze()
    seen = _FreezeSeen()
    run = run_scene(single_system_scene("pendulum"), fast=True, duration=5.0,
                    context=ros_context, sinks=[seen])
    assert run.sim_time >= 5.0 - 1e-9
    # Frozen whenever the loop handed samples over (not as the nodes start and finish).
    frozen = sum(c > 0 for c in seen.counts)
    assert seen.counts[0] == 0 and frozen > len(seen.counts) // 2, seen.counts
    assert gc.get_freeze_count() == 0
