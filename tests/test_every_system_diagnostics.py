"""Every system, end to end: its default scene through the real node graph (simulator and
diagnostics nodes, as fast as possible), every conservation law it declares reported OK by the
diagnostics node; and the document's naive bead formulation, which violates energy and the
constraint by design, flagged ERROR."""

from __future__ import annotations

from typing import Any

import pytest

import mechsim
from mechsim.environment import import_rclpy

import_rclpy()
from mechsim.ros.launch import run_scene  # noqa: E402
from mechsim.scene import parse_scene, single_system_scene  # noqa: E402


@pytest.mark.parametrize("system", mechsim.system_ids())
def test_default_run_is_ok_on_every_law(system: str, ros_context: Any) -> None:
    run = run_scene(single_system_scene(system), fast=True, duration=2.0, context=ros_context)
    assert not run.failures, run.failures
    laws = {law for _, law, _, _ in run.summary}
    declared = {law.key for law in mechsim.load_system(system).laws()}
    assert laws == declared
    bad = [(law, drift, level) for _, law, drift, level in run.summary if level != 0]
    assert not bad, bad


def test_naive_bead_is_flagged(ros_context: Any) -> None:
    scene = parse_scene({"name": "naive", "systems": [
        {"system": "bead_on_wire", "parameters": {"formulation": "naive", "shape": "parabola"}}]})
    run = run_scene(scene, fast=True, duration=2.0, context=ros_context)
    levels = {law: level for _, law, _, level in run.summary}
    assert levels["energy"] == 2
    assert any(law.startswith("constraint:") and level == 2 for law, level in levels.items())
