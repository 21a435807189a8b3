"""The unrestricted planar three-body problem (“Action and Reaction”, Case 2): against scipy's
integration of Newton's equations for three bodies written here; E, P and L conserved; as
m₃ → 0 the third body follows the restricted problem (scipy, primaries on their circles); the
Jacobi "constant" drifts, first order in m₃, at the published rate."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import cumulative_simpson, solve_ivp

import mechsim

G, M1, M2, L = 1.0, 0.9, 0.1, 1.0
W = math.sqrt(G * (M1 + M2) / L**3)


def _model(m3: float) -> mechsim.Model:
    return mechsim.load_system("three_body", gravitational_constant=G, primary_mass=M1,
                               secondary_mass=M2, third_mass=m3, separation=L)


def _newton(masses: tuple[float, float, float]):  # type: ignore[no-untyped-def]
    def f(_: float, s: np.ndarray) -> np.ndarray:
        r, v = s[:6].reshape(3, 2), s[6:]
        a = np.zeros((3, 2))
        for i in range(3):
            for j in range(3):
                if i != j:
                    d = r[j] - r[i]
                    a[i] += G * masses[j] * d / np.linalg.norm(d) ** 3
        return np.concatenate([v, a.ravel()])
    return f


def test_against_scipy_three_bodies() -> None:
    m3 = 0.05
    model = _model(m3)
    run = mechsim.simulate(model, 12.0, 0.05, tolerance=1e-13)
    y0 = model.initial_y()
    sol = solve_ivp(_newton((M1, M2, m3)), (0.0, 12.0), y0[:12], t_eval=run.t,
                    method="DOP853", rtol=1e-13, atol=1e-13)
    assert np.max(np.abs(run.q - sol.y[:6].T)) < 1e-7
    # the barycentre stays at the origin, at rest
    masses = np.array([M1, M2, m3])
    cm = masses @ run.q.reshape(-1, 3, 2) / masses.sum()
    assert np.max(np.abs(cm)) < 1e-12
    for name in ("momentum_x", "momentum_y", "angular_momentum"):
        assert np.max(np.abs(run.invariants[name] - run.invariants[name][0])) < 1e-13
    assert np.max(np.abs(run.total - run.total[0])) < 1e-12 * abs(run.total[0])


def _restricted(t_end: float, t: np.ndarray) -> np.ndarray:
    """The third body of the circular restricted problem (the post's equation of motion with
    G, and the primaries at ±(m/M)L û(ωt))."""
    def f(tt: float, s: np.ndarray) -> list[float]:
        x, y, vx, vy = s
        c, sn = math.cos(W * tt), math.sin(W * tt)
        ax = ay = 0.0
        for m, k in ((M1, M2 / (M1 + M2)), (M2, -M1 / (M1 + M2))):
            dx, dy = k * L * c - x, k * L * sn - y
            d3 = (dx * dx + dy * dy) ** 1.5
            ax += G * m * dx / d3
            ay += G * m * dy / d3
        return [vx, vy, ax, ay]
    sol = solve_ivp(f, (0.0, t_end), [0.5, 0.0, 0.0, 0.9], t_eval=t, method="DOP853",
                    rtol=1e-13, atol=1e-13)
    return sol.y[:2].T


def test_light_third_body_is_the_restricted_problem() -> None:
    run = mechsim.simulate(_model(1e-9), 10.0, 0.05, tolerance=1e-13)
    assert np.max(np.abs(run.q[:, 4:6] - _restricted(10.0, run.t))) < 1e-6
    J = run.observables["jacobi"]
    assert np.ptp(J) < 1e-7


def test_jacobi_drift_is_first_order_in_the_third_mass() -> None:
    """ptp J over ten time units, per unit m₃, is the same for m₃ = 1e-3 and 1e-4 (to the
    second-order part, ~m₃): the drift is the back-reaction, not integration error."""
    spans = []
    for m3 in (1e-3, 1e-4):
        run = mechsim.simulate(_model(m3), 10.0, 0.01, tolerance=1e-12)
        spans.append(np.ptp(run.observables["jacobi"]) / m3)
    assert spans[0] == pytest.approx(spans[1], rel=0.05)
    assert spans[1] > 1.0  # J moves by more than m₃ per unit time here: far above round-off


def test_jacobi_rate_is_the_derivative_of_the_jacobi_integral() -> None:
    """∫ dJ/dt dt (published rate, Simpson on fine samples) = J(t) − J(0) (published J)."""
    run = mechsim.simulate(_model(0.01), 10.0, 0.002, tolerance=1e-12)
    J, rate = run.observables["jacobi"], run.observables["jacobi_rate"]
    integral = cumulative_simpson(rate, x=run.t, initial=0.0)
    assert np.max(np.abs(integral - (J - J[0]))) < 1e-4 * np.ptp(J)
    assert np.allclose(run.observables["jacobi_constant"], -2 * J, rtol=1e-15)
