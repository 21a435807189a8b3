"""Pendulum in a plane forced to turn at ω (Lecture 10, spherical pendulum forced to rotate (eqs.
10.49–10.50)): E′ = h conserved, E − E₀ = ∫Gω dt with the required torque G = 2ml²ω sinθ cosθ θ̇,
λ = G in the multiplier form, the bifurcation at
ω_c = √(g/l), the off-axis equilibrium arccos(g/(lω²)) and the small-oscillation frequencies
(ω² sin²θ₀ above, g/l − ω² below; derived with sympy from θ̈ = ω² sinθ cosθ − (g/l) sinθ)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import simpson

import mechsim
from mechsim.errors import ParameterError

M, L, G = 0.6, 0.8, 9.81
WC = math.sqrt(G / L)


def _model(form: str, w: float, th0: float, dth0: float = 0.0) -> mechsim.systems.base.Model:
    return mechsim.load_system("rotating_hoop", formulation=form, mass=M, length=L, gravity=G,
                               angular_velocity=w, **{"initial.angle": th0,
                                                      "initial_rate.angle": dth0})


@pytest.mark.parametrize("form", ["reduced", "multiplier"])
def test_effective_energy_conserved_and_torque_work(form: str) -> None:
    m = _model(form, 5.0, 0.3)
    keys = [law.key for law in m.laws()]
    assert "energy" not in keys and "invariant:effective_energy" in keys
    run = mechsim.simulate(m, 10.0, 0.001, tolerance=1e-12)
    scale = M * G * L
    e = run.invariants["effective_energy"]
    assert np.max(np.abs(e - e[0])) < 1e-10 * scale
    th, dth = run.q[:, 0], run.v[:, 0]
    G_exact = 2 * M * L**2 * 5.0 * np.sin(th) * np.cos(th) * dth
    np.testing.assert_allclose(run.observables["torque"], G_exact, atol=1e-8 * scale)
    # E varies a lot, and E − E₀ = ∫ G ω dt (Simpson on the 1 ms samples).
    dE = run.total - run.total[0]
    assert np.ptp(dE) > 1.0
    work = np.array([simpson(G_exact[: k + 1] * 5.0, x=run.t[: k + 1]) if k else 0.0
                     for k in range(0, run.t.size, 500)])
    np.testing.assert_allclose(dE[::500], work, atol=1e-8 * scale)
    np.testing.assert_allclose(run.work_external[::500], work, atol=1e-8 * scale)
    assert np.max(np.abs(run.balance_residual)) < 1e-9 * scale
    if form == "multiplier":
        np.testing.assert_array_equal(run.observables["multiplier"], run.observables["torque"])
        assert np.max(np.abs(run.invariants["constraint_rotation"])) < 1e-12
        # The two-coordinate h on the constraint is E itself (h − E = 0), not conserved.
        assert np.max(np.abs(run.energy_function - run.total)) < 1e-9 * scale
    else:
        assert np.max(np.abs(run.energy_function - e)) < 1e-12 * scale


def test_forms_agree() -> None:
    a = mechsim.simulate(_model("reduced", 4.0, 1.0, 0.5), 5.0, 0.01, tolerance=1e-12)
    b = mechsim.simulate(_model("multiplier", 4.0, 1.0, 0.5), 5.0, 0.01, tolerance=1e-12)
    np.testing.assert_allclose(a.q[:, 0], b.q[:, 0], atol=1e-9)
    np.testing.assert_allclose(a.observables["torque"], b.observables["torque"], atol=1e-7)
    np.testing.assert_allclose(a.outputs.frames, b.outputs.frames, atol=1e-9)


@pytest.mark.parametrize("w", [5.0, 4.0])
def test_off_axis_equilibrium_and_its_frequency(w: float) -> None:
    th_eq = math.acos(G / (L * w * w))
    still = mechsim.simulate(_model("reduced", w, th_eq), 5.0, 0.05, tolerance=1e-12)
    assert np.max(np.abs(still.q[:, 0] - th_eq)) < 1e-9
    w_osc = math.sqrt(w * w - G * G / (L * L * w * w))
    assert abs(w_osc - w * math.sin(th_eq)) < 1e-12
    eps = 1e-5
    run = mechsim.simulate(_model("reduced", w, th_eq + eps), 3 * 2 * math.pi / w_osc, 0.002,
                           tolerance=1e-13)
    assert np.max(np.abs(run.q[:, 0] - th_eq - eps * np.cos(w_osc * run.t))) < 2e-3 * eps


def test_bifurcation_at_critical_speed() -> None:
    eps = 1e-4
    # Below ω_c: θ = 0 is stable, ω_osc² = g/l − ω².
    w = 0.6 * WC
    w_osc = math.sqrt(G / L - w * w)
    low = mechsim.simulate(_model("reduced", w, eps), 2 * 2 * math.pi / w_osc, 0.005,
                           tolerance=1e-13)
    assert np.max(np.abs(low.q[:, 0] - eps * np.cos(w_osc * low.t))) < 1e-3 * eps
    # Above ω_c: a tiny displacement grows to an oscillation around arccos(g/(lω²)).
    w = 1.5 * WC
    th_eq = math.acos(G / (L * w * w))
    high = mechsim.simulate(_model("reduced", w, eps), 10.0, 0.005, tolerance=1e-12)
    assert high.q[:, 0].max() > th_eq
    assert high.q[:, 0].max() < 2 * th_eq + 0.1
    # the model's critical speed is where the two regimes meet: ω_c = √(g/l)
    assert _model("reduced", w, eps).critical_speed() == pytest.approx(WC, rel=1e-15)


def test_parameter_validation() -> None:
    with pytest.raises(ParameterError, match="^angular_velocity: must be >= 0"):
        mechsim.load_system("rotating_hoop", angular_velocity=-1.0)
    with pytest.raises(ParameterError, match="^formulation: must be one of"):
        mechsim.load_system("rotating_hoop", formulation="euler")
