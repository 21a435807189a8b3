"""The knife edge and Chaplygin sled, a velocity (non-holonomic) constraint ("Dynamical
Systems and Constraints: Part 1 – General Theory", constraints in differential form; Lecture
10, eqs. 10.25–10.30): each run is checked against closed forms written here (the free knife
edge's circle, its sideways drift on a slope, the sled's tanh/sech law) or against an
independent integration of the Chaplygin equations with SciPy; the multiplier against the
blade force those equations give; the constraint residual at round-off; the energy conserved
and the momenta of the cyclic coordinates not."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import mechsim

M, I, G = 1.3, 0.07, 9.81


def _run(t_end: float, **kw: float) -> mechsim.SimulationResult:
    params = {"mass": M, "inertia": I, "gravity": G, **kw}
    return mechsim.simulate(mechsim.load_system("knife_edge", **params), t_end, 0.01,
                            tolerance=1e-12)


def test_free_knife_edge_runs_a_circle_at_constant_rates() -> None:
    u0, w0, th0 = 0.8, 1.7, 0.4
    run = _run(12.0, inclination=0.0, offset=0.0, **{"initial.heading": th0,
               "initial.speed": u0, "initial_rate.heading": w0, "initial.x": 0.3})
    th = th0 + w0 * run.t
    R = u0 / w0  # x = x0 + R (sin θ − sin θ0), y = −R (cos θ − cos θ0)
    assert np.max(np.abs(run.coordinate("heading") - th)) < 1e-10
    assert np.max(np.abs(run.coordinate("x") - 0.3 - R * (np.sin(th) - math.sin(th0)))) < 1e-10
    assert np.max(np.abs(run.coordinate("y") + R * (np.cos(th) - math.cos(th0)))) < 1e-10
    # the blade supplies the centripetal force m u ω along ê⊥ (to the left of the blade)
    assert np.max(np.abs(run.observables["lateral_force"] - M * u0 * w0)) < 1e-9
    assert np.max(np.abs(run.observables["forward_speed"] - u0)) < 1e-10


def test_knife_edge_on_a_slope_drifts_across_it() -> None:
    """a = 0: ω constant, u = u0 + (G/ω)(sin θ − sin θ0) with G = g sin α, and the blade
    drifts across the slope at G/(2ω) on average, never down it (integrated here by hand)."""
    alpha, u0, w, th0 = 0.3, 0.6, 2.5, 0.2
    run = _run(15.0, inclination=alpha, offset=0.0, **{"initial.heading": th0,
               "initial.speed": u0, "initial_rate.heading": w})
    t, Gs = run.t, G * math.sin(alpha)
    th = th0 + w * t
    k = u0 - Gs * math.sin(th0) / w
    x = k * (np.sin(th) - math.sin(th0)) / w + Gs / (2 * w**2) * (np.sin(th)**2
                                                                  - math.sin(th0)**2)
    y = -k * (np.cos(th) - math.cos(th0)) / w + Gs / w * (
        t / 2 - (np.sin(2 * th) - math.sin(2 * th0)) / (4 * w))
    assert np.max(np.abs(run.coordinate("heading") - th)) < 1e-9
    assert np.max(np.abs(run.observables["forward_speed"] - (k + Gs * np.sin(th) / w))) < 1e-9
    assert np.max(np.abs(run.coordinate("x") - x)) < 1e-9
    assert np.max(np.abs(run.coordinate("y") - y)) < 1e-9
    spin = run.invariants["spin"]
    assert np.max(np.abs(spin - I * w)) < 1e-12


def test_sled_speed_and_turn_rate_follow_tanh_and_sech() -> None:
    """α = 0, a > 0: u̇ = a ω², J ω̇ = −m a u ω (J = I + m a²), so with C = u² + (J/m) ω²,
    k = m a / J and φ = k √C t + artanh(u0/√C): u = √C tanh φ, ω = ω0 cosh φ0 / cosh φ."""
    a, u0, w0 = 0.15, 0.2, 3.0
    run = _run(10.0, inclination=0.0, offset=a, **{"initial.speed": u0,
               "initial_rate.heading": w0})
    J = I + M * a * a
    C, k = u0**2 + J / M * w0**2, M * a / J
    phi0 = math.atanh(u0 / math.sqrt(C))
    phi = k * math.sqrt(C) * run.t + phi0
    assert np.max(np.abs(run.observables["forward_speed"] - math.sqrt(C) * np.tanh(phi))) < 1e-9
    assert np.max(np.abs(run.rate("heading") - w0 * math.cosh(phi0) / np.cosh(phi))) < 1e-9


def _chaplygin(t: float, s: np.ndarray, a: float, Gs: float) -> list[float]:
    """The sled reduced to (x, y, θ, u, ω): ẋ = u cos θ − a ω sin θ, ẏ = u sin θ + a ω cos θ,
    u̇ = a ω² + Gs cos θ, (I + m a²) ω̇ = −m a (u ω + Gs sin θ)."""
    _, _, th, u, w = s
    c, sn = math.cos(th), math.sin(th)
    return [u * c - a * w * sn, u * sn + a * w * c, w, a * w * w + Gs * c,
            -M * a * (u * w + Gs * sn) / (I + M * a * a)]


@pytest.mark.parametrize("a", [0.0, 0.12])
def test_sled_on_a_slope_matches_an_independent_integration(a: float) -> None:
    alpha, u0, w0, th0 = 0.25, 0.4, 1.5, -0.6
    run = _run(8.0, inclination=alpha, offset=a, **{"initial.heading": th0,
               "initial.speed": u0, "initial_rate.heading": w0, "initial.y": 0.5})
    Gs = G * math.sin(alpha)
    ref = solve_ivp(_chaplygin, (0.0, 8.0), [0.0, 0.5, th0, u0, w0], t_eval=run.t,
                    args=(a, Gs), method="DOP853", rtol=1e-12, atol=1e-12)
    x, y, th, u, w = ref.y
    for name, want in (("x", x), ("y", y), ("heading", th)):
        assert np.max(np.abs(run.coordinate(name) - want)) < 1e-8, name
    assert np.max(np.abs(run.rate("heading") - w)) < 1e-8
    assert np.max(np.abs(run.observables["forward_speed"] - u)) < 1e-8
    # μ = m (a ω̇ + u ω + Gs sin θ), with ω̇ from the reduced equations
    wdot = -M * a * (u * w + Gs * np.sin(th)) / (I + M * a * a)
    mu = M * (a * wdot + u * w + Gs * np.sin(th))
    assert np.max(np.abs(run.observables["lateral_force"] - mu)) < 1e-7
    # the constraint holds to round-off; the ideal blade does no work: E = T + V conserved
    assert np.max(np.abs(run.invariants["constraint_no_side_slip"])) < 1e-13
    E = run.kinetic + run.potential
    assert np.max(np.abs(E - E[0])) < 1e-10 * max(1.0, float(np.max(np.abs(run.kinetic))))
    # the momenta of the cyclic x and y are not conserved: the blade pushes sideways
    for name in ("momentum_x", "momentum_y"):
        p = run.observables[name]
        assert np.ptp(p) > 0.1


def test_rates_that_break_the_constraint_are_projected_onto_it() -> None:
    """Rates off the constraint (a sideways slip put in by hand) are mapped to the nearest
    rates on c = 0: the least-norm correction, along A = (−sin θ, cos θ, −a)."""
    a = 0.1
    model = mechsim.load_system("knife_edge", offset=a, **{"initial.heading": 0.7})
    y = model.initial_y()
    v0 = y[3:6].copy()
    y[4] += 0.3  # ẏ: a sideways slip
    model.kernels.project(0.0, y, model.parameter_vector())
    A = np.array([-math.sin(0.7), math.cos(0.7), -a])
    assert abs(A @ y[3:6]) < 1e-15
    slip = np.array([0.0, 0.3, 0.0])
    assert np.max(np.abs(y[3:6] - (v0 + slip - A * (A @ slip) / (A @ A)))) < 1e-15
