"""The ``Law`` object and the state layout, checked against hand-computed numbers and physics:
what each law reads from a sample, its drift and level at the threshold edges, its wire key,
and the layout's columns against an independent integral (the dissipated work ∫ b ẋ² dt)."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid

import mechsim
from mechsim.systems.base import Law, StateLayout

SAMPLE = SimpleNamespace(total=10.0, energy_function=7.5, work_external=3.0,
                         work_dissipated=0.5)


def test_each_kind_reads_its_quantity() -> None:
    assert Law("energy").value(SAMPLE) == 10.0
    assert Law("energy_function").value(SAMPLE) == 7.5
    assert Law("work_balance").value(SAMPLE) == 10.0 - (3.0 - 0.5)
    inv = {"angular_momentum": 2.0, "constraint_rod_length": -1e-9}
    assert Law("invariant", "angular_momentum").value(invariants=inv) == 2.0
    assert Law("constraint", "constraint_rod_length").value(invariants=inv) == -1e-9
    assert [Law(k).stream for k in ("energy", "energy_function", "work_balance")] == \
        ["energy"] * 3
    assert Law("invariant", "x").stream == Law("constraint", "y").stream == "invariants"
    with pytest.raises(ValueError):
        Law("invariant", "angular_momentum").value(SAMPLE)  # no invariants given


def test_drift_of_a_change_and_of_a_residual() -> None:
    law, residual = Law("invariant", "L"), Law("constraint", "constraint_g")
    assert law.drift(2.5, 2.0, 4.0) == pytest.approx(0.125)
    assert residual.drift(-0.5, 123.0, 4.0) == pytest.approx(0.125)  # no initial value
    assert residual.is_constraint and not law.is_constraint
    v = np.array([2.0, 2.1, 1.8])
    np.testing.assert_allclose(law.drift(v, v[0], 2.0), [0.0, 0.05, 0.1])


def test_levels_at_the_threshold_edges() -> None:
    law = Law("energy")
    assert (Law.WARN_DRIFT, Law.ERROR_DRIFT) == (1e-6, 1e-3)  # the documented defaults
    assert law.level(0.99e-6) == 0 and law.level(1e-6) == 1
    assert law.level(0.99e-3) == 1 and law.level(1e-3) == 2
    assert law.level(math.nan) == 2 and law.level(math.inf) == 2
    assert law.level(1e-5, warn=1e-4, error=1e-2) == 0


def test_scale_of_each_kind() -> None:
    inv0 = {"L": -3.0, "zero": 0.0}
    assert Law("energy").scale(5.0, inv0) == 5.0
    assert Law("work_balance").scale(5.0, inv0) == 5.0
    assert Law("invariant", "L").scale(5.0, inv0) == 3.0
    assert Law("invariant", "zero").scale(5.0, inv0) == 1.0
    assert Law("constraint", "constraint_g").scale(5.0, inv0) == 1.0


def test_keys_on_the_wire() -> None:
    for key in ("energy", "energy_function", "work_balance", "invariant:runge_lenz_x",
                "constraint:constraint_rod_length"):
        assert Law.from_key(key).key == key
    for bad in ("", "energy:x", "invariant:", "momentum", "constraint", "bogus:x"):
        with pytest.raises(ValueError):
            Law.from_key(bad)
    with pytest.raises(ValueError):
        Law("invariant")
    assert Law.for_invariant("constraint_unit_norm").is_constraint
    assert not Law.for_invariant("angular_momentum").is_constraint


def test_pendulum_laws_and_scales() -> None:
    """Released at rest from φ₀: energy scale |T₀| + |V₀| = m g R (1 − cos φ₀); the
    multiplier form's rod residual is a constraint law with scale 1 m."""
    model = mechsim.load_system("pendulum", formulation="multiplier", **{"initial.angle": 1.0})
    keys = [law.key for law in model.laws()]
    assert keys == ["energy", "energy_function", "work_balance",
                    "constraint:constraint_rod_length"]
    scales = model.law_scales()
    assert scales["energy"] == pytest.approx(9.81 * (1 - math.cos(1.0)), rel=1e-12)
    assert scales["constraint:constraint_rod_length"] == 1.0


def test_layout_columns() -> None:
    at = StateLayout(2, 1)
    y = at.compose([1.0, 2.0], [3.0, 4.0], 5.0, 6.0, [7.0])
    assert y.tolist() == [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0] and at.size == 7
    Y = np.vstack([y, 10 * y])
    assert Y[..., at.v].tolist() == [[3.0, 4.0], [30.0, 40.0]]
    assert Y[..., at.work_dissipated].tolist() == [6.0, 60.0]
    assert Y[..., at.modes].tolist() == [[7.0], [70.0]]
    with pytest.raises(ValueError):
        at.compose([1.0], [2.0])


def test_simulate_reads_the_layout_right() -> None:
    """Damped oscillator: the work column is the dissipated energy ∫ b ẋ² dt (integrated here
    from the rate column), the balance residual closes, coordinates and rates differ."""
    b = 0.4
    model = mechsim.load_system("damped_oscillator", damping=b)
    run = mechsim.simulate(model, 5.0, 0.001, tolerance=1e-12)
    assert model.layout == StateLayout(1, 0)
    w = cumulative_trapezoid(b * run.v[:, 0] ** 2, run.t, initial=0.0)
    np.testing.assert_allclose(run.work_dissipated, w, rtol=0, atol=1e-6 * w[-1])
    assert np.all(run.work_external == 0.0)
    assert np.max(np.abs(run.balance_residual)) < 1e-10
    # ẋ is the time derivative of x (rates are not a copy of coordinates)
    np.testing.assert_allclose(np.gradient(run.q[:, 0], run.t)[1:-1], run.v[1:-1, 0],
                               atol=1e-5)
