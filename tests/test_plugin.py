"""mechsim's pytest plugin, used as a user would: fixtures from the installed entry point, no
launch files, no sleeps. The numbers are checked against physics, not against the plugin."""

from __future__ import annotations

import math
from typing import Any

import pytest


def test_plugin_is_registered(pytestconfig: pytest.Config) -> None:
    assert pytestconfig.pluginmanager.has_plugin("mechsim")


def test_pendulum_in_process(mechsim_graph: Any) -> None:
    mechsim_graph.start("pendulum", **{"initial.angle": 1.0})
    energy = mechsim_graph.collect("/pendulum/energy").wait_for(count=30)
    e0 = energy[0].total
    # E = m g R (1 − cos θ₀) with m = R = 1, g = 9.81, released at rest from θ₀ = 1 rad
    assert e0 == pytest.approx(9.81 * (1 - math.cos(1.0)), rel=1e-9)
    assert max(abs(m.total - e0) for m in energy) < 1e-9 * e0
    mechsim_graph.assert_laws_ok("pendulum")


def test_parameters_and_services(mechsim_graph: Any) -> None:
    from std_srvs.srv import SetBool

    mechsim_graph.start("pendulum", diagnostics=False)
    node = "/pendulum/simulator"
    bad, = mechsim_graph.set_parameters(node, mass=-1.0)
    assert not bad.successful and "mass" in bad.reason
    good, = mechsim_graph.set_parameters(node, mass=2.0)
    assert good.successful
    answer = mechsim_graph.call(f"{node}/pause", SetBool.Request(data=True))
    assert answer.success


def test_system_in_a_child_process(mechsim_graph: Any) -> None:
    mechsim_graph.start("harmonic_oscillator", process=True, diagnostics=False)
    state = mechsim_graph.collect("/harmonic_oscillator/state").wait_for(count=5)
    assert all(len(m.position) == 1 for m in state)
