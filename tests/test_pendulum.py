"""Simple pendulum (“Dynamical Systems and Constraints: Part 3 – Simple Pendulum”): exact period,
tension, multiplier = −tension in the document's own polar form and in Cartesian coordinates, the
forms agree, the small-angle form beside the exact one, long-run energy conservation. Oracles are
computed here from scipy/mpmath and the document's equations, or are the model's analytic
methods (exact period, tension from energy conservation) checked against those first."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import mechsim

G, R, M = 9.81, 1.3, 0.7


def _period_mpmath(phi0: float) -> float:
    """T = 4 √(R/g) K(sin²(φ₀/2)), evaluated independently with mpmath at 30 digits."""
    mpmath.mp.dps = 30
    return float(4 * mpmath.sqrt(R / G) * mpmath.ellipk(mpmath.sin(phi0 / 2) ** 2))


def _model(form: str, phi0: float) -> mechsim.systems.base.Model:
    return mechsim.load_system("pendulum", formulation=form, mass=M, length=R, gravity=G,
                               **{"initial.angle": phi0})


@pytest.mark.parametrize("form", ["reduced", "multiplier"])
@pytest.mark.parametrize("phi0", [0.3, 2.0, 3.0])
def test_exact_period(form: str, phi0: float) -> None:
    period = _period_mpmath(phi0)
    m = _model(form, phi0)
    run = mechsim.simulate(m, 1.5 * period, period / 400, tolerance=1e-12,
                           method="dop853" if form == "multiplier" else "auto")
    angle = run.q[:, 0] if form == "reduced" else run.observables["angle"]
    rate = run.v[:, 0] if form == "reduced" else np.gradient(angle, run.t)
    # First return to φ₀ with φ̇ changing sign from + to −... locate the turning point near T.
    k = np.argmin(np.abs(run.t - period))
    window = slice(k - 3, k + 4)
    # Fit a parabola to φ(t) around the turning point: its vertex is the measured period.
    c = np.polyfit(run.t[window] - run.t[k], angle[window], 2)
    t_turn = run.t[k] - c[1] / (2 * c[0])
    assert abs(t_turn - period) < 2e-7 * period
    # the model's own oracle (scipy's K) agrees with mpmath's at 30 digits
    assert m.exact_period() == pytest.approx(period, rel=1e-14)
    assert np.sign(rate[k - 5]) != np.sign(rate[k + 5]) or phi0 < 0.5


@pytest.mark.parametrize("phi0", [1.0, 2.0, 3.0])
def test_tension_formula_and_multiplier_sign(phi0: float) -> None:
    m = _model("multiplier", phi0)
    run = mechsim.simulate(m, 5.0, 0.01, tolerance=1e-12)
    phi = run.observables["angle"]
    expected = M * G * (3 * np.cos(phi) - 2 * math.cos(phi0))  # from energy conservation
    assert np.max(np.abs(run.observables["tension"] - expected)) < 1e-8 * M * G
    # the model's oracle is this formula
    assert np.allclose(m.tension_at(phi), expected, rtol=1e-14, atol=1e-14 * M * G)
    assert np.allclose(run.observables["multiplier"], -run.observables["tension"], atol=0)
    # Rod in compression for φ₀ > π/2 (catalog: min T = −4.0824 N for φ₀ = 2 rad, m = 1).
    if phi0 > math.pi / 2:
        assert run.observables["tension"].min() < 0


def test_catalog_minimum_tension_value() -> None:
    m = mechsim.load_system("pendulum", formulation="multiplier", mass=1.0, length=1.0,
                            gravity=9.81, **{"initial.angle": 2.0})
    run = mechsim.simulate(m, 3.0, 0.001, tolerance=1e-12)
    # min over φ of mg(3 cos φ − 2 cos 2) is at φ = ±2: mg cos 2 = −4.0824
    assert abs(run.observables["tension"].min() - 9.81 * math.cos(2.0)) < 1e-4


def test_formulations_agree() -> None:
    red = mechsim.simulate(_model("reduced", 2.5), 10.0, 0.01, tolerance=1e-12, method="dop853")
    mul = mechsim.simulate(_model("multiplier", 2.5), 10.0, 0.01, tolerance=1e-12)
    assert np.max(np.abs(red.q[:, 0] - mul.observables["angle"])) < 1e-8
    assert np.max(np.abs(red.observables["tension"] - mul.observables["tension"])) < 1e-7
    assert np.max(np.abs(mul.invariants["constraint_rod_length"])) < 1e-14
    assert np.max(np.abs(red.total - mul.total)) < 1e-8


def test_long_run_energy_drift_default_settings() -> None:
    """10⁴ periods at default settings (auto: radau15 over so long a horizon): relative energy
    error ≤ 1e-10, and no secular growth above round-off."""
    m = mechsim.load_system("pendulum")
    period = _period_mpmath(1.0) * math.sqrt(G / 9.81) * math.sqrt(1.0 / R)  # R = 1, g = 9.81
    run = mechsim.simulate(m, 1e4 * period, period / 3, outputs=("energy",))
    E = run.total
    drift = np.abs(E - E[0]) / abs(E[0])
    assert drift.max() <= 1e-10
    # No secular growth: the last tenth is no worse than 3x the first tenth.
    n = len(E) // 10
    assert drift[-n:].max() <= 3 * max(drift[:n].max(), 1e-13)


def test_rejects_bad_parameters() -> None:
    with pytest.raises(mechsim.ParameterError, match="mass: must be > 0"):
        mechsim.load_system("pendulum", mass=-1.0)
    with pytest.raises(mechsim.ParameterError, match="length: must be finite"):
        mechsim.load_system("pendulum", length=float("nan"))
    with pytest.raises(mechsim.ParameterError, match="masss: unknown parameter"):
        mechsim.load_system("pendulum", masss=1.0)
    with pytest.raises(mechsim.ParameterError, match="formulation: must be one of"):
        mechsim.load_system("pendulum", formulation="newtonian")


def _document_pendulum(phi0: float, t: np.ndarray) -> np.ndarray:
    """φ(t) of R φ̈ + g sin φ = 0 (the post's L32), by scipy's DOP853 at 1e-13."""
    sol = solve_ivp(lambda _, s: [s[1], -G / R * math.sin(s[0])], (0.0, float(t[-1])),
                    [phi0, 0.0], t_eval=t, method="DOP853", rtol=1e-13, atol=1e-13)
    return sol.y[0]


@pytest.mark.parametrize("phi0", [1.0, 2.5])
def test_polar_multiplier_is_the_documents_form(phi0: float) -> None:
    """(ρ, φ) with ρ − R = 0 (L78): the multiplier is −(m g cos φ + m R φ̇²) read off the state
    (the Newtonian tension, L28; L90 gives λ = −T), ρ stays R, φ(t) is the document's
    pendulum, and the tension follows energy conservation (``tension_at``)."""
    m = _model("polar_multiplier", phi0)
    run = mechsim.simulate(m, 6.0, 0.01, tolerance=1e-12)
    rho, phi, dphi = run.q[:, 0], run.q[:, 1], run.v[:, 1]
    newton_tension = M * G * np.cos(phi) + M * R * dphi**2
    assert np.max(np.abs(run.observables["multiplier"] + newton_tension)) < 1e-8 * M * G
    assert np.array_equal(run.observables["tension"], -run.observables["multiplier"])
    assert np.max(np.abs(rho - R)) < 1e-12 * R
    assert np.max(np.abs(run.invariants["constraint_rod_length"])) < 1e-12 * R
    assert np.max(np.abs(phi - _document_pendulum(phi0, run.t))) < 1e-8
    assert np.max(np.abs(run.observables["tension"] - m.tension_at(phi))) < 1e-8 * M * G


def test_polar_and_cartesian_multipliers_agree_with_the_reduced_form() -> None:
    """The three forms of the post (substitution, polar multiplier) and the Cartesian one: the
    same φ(t), the same λ = −T along it."""
    runs = {f: mechsim.simulate(_model(f, 2.5), 8.0, 0.01, tolerance=1e-12, method="dop853")
            for f in ("reduced", "multiplier", "polar_multiplier")}
    phi = runs["reduced"].q[:, 0]
    assert np.max(np.abs(runs["polar_multiplier"].q[:, 1] - phi)) < 1e-8
    assert np.max(np.abs(runs["multiplier"].observables["angle"] - phi)) < 1e-8
    lam_polar = runs["polar_multiplier"].observables["multiplier"]
    assert np.max(np.abs(lam_polar - runs["multiplier"].observables["multiplier"])) < 1e-7
    assert np.max(np.abs(lam_polar + runs["reduced"].observables["tension"])) < 1e-7


@pytest.mark.parametrize("phi0", [0.1, 1.0, 2.5])
def test_small_angle_form_is_isochronous(phi0: float) -> None:
    """The linearised pendulum integrated (not its closed form): φ₀ cos ω₀t, period 2π√(R/g)
    at every amplitude; the exact period exceeds it by 1 + φ₀²/16 + 11φ₀⁴/3072 + 173φ₀⁶/737280
    + … (series checked at φ₀ = 0.1, where the next term is 2e-10)."""
    w0 = math.sqrt(G / R)
    run = mechsim.simulate(_model("small_angle", phi0), 10.0, 0.01, tolerance=1e-12,
                           method="dop853")
    assert np.max(np.abs(run.q[:, 0] - phi0 * np.cos(w0 * run.t))) < 1e-9 * phi0
    small = 2 * math.pi / w0
    exact = _model("reduced", phi0).exact_period()
    assert exact > small
    if phi0 <= 0.1:
        series = small * (1 + phi0**2 / 16 + 11 * phi0**4 / 3072 + 173 * phi0**6 / 737280)
        assert exact == pytest.approx(series, rel=1e-9)
