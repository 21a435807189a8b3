"""Power-law central force F = −K rⁿ (PHYS0500 §4.2–4.5.1): the orbit against scipy, the apsidal
angle (the model's quadrature) against apsides found by an independent integration, Bertrand's
closed cases n = −2 and 1, the near-circular limit π/√(n+3), small radial oscillations
(§4.5.1), the solvable laws n = 1, −2, −3 in closed form, the Binet form against the time form,
and the fall to the centre for n ≤ −3. Every oracle is computed here."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import mechsim
from mechsim.integrators import make_stepper

MU, K = 1.3, 0.9


def _model(n: float, form: str = "polar", r0: float = 1.0, rdot0: float = 0.0,
           thdot0: float = 0.8, **kw: float) -> mechsim.Model:
    return mechsim.load_system("power_law_orbit", formulation=form, mass=MU, exponent=n,
                               force_constant=K, **{"initial.r": r0, "initial_rate.r": rdot0,
                                                    "initial_rate.theta": thdot0}, **kw)


def _scipy_orbit(n: float, r0: float, rdot0: float, thdot0: float, t_end: float,
                 t_eval: np.ndarray | None = None, events: bool = False) -> object:
    """μ r̈ = −K rⁿ r̂ in Cartesian coordinates (the document's F ∝ rⁿ) with the polar angle
    θ̇ = (x ẏ − y ẋ)/r² alongside, DOP853 at 1e-13; with ``events``, the apsides (r·v = 0)."""
    def f(_: float, s: np.ndarray) -> list[float]:
        x, y, vx, vy, _th = s
        r2 = x * x + y * y
        a = -K * r2 ** ((n - 1) / 2) / MU
        return [vx, vy, a * x, a * y, (x * vy - y * vx) / r2]

    def apsis(_: float, s: np.ndarray) -> float:
        return s[0] * s[2] + s[1] * s[3]

    return solve_ivp(f, (0.0, t_end), [r0, 0.0, rdot0, r0 * thdot0, 0.0], method="DOP853",
                     rtol=1e-13, atol=1e-13, t_eval=t_eval, events=apsis if events else None,
                     dense_output=events)


@pytest.mark.parametrize("n", [-2.5, -1.0, 0.5])
def test_orbit_matches_scipy(n: float) -> None:
    m = _model(n, rdot0=0.2)
    run = mechsim.simulate(m, 20.0, 0.05, tolerance=1e-12)
    sol = _scipy_orbit(n, 1.0, 0.2, 0.8, 20.0, t_eval=run.t)
    x, y = run.q[:, 0] * np.cos(run.q[:, 1]), run.q[:, 0] * np.sin(run.q[:, 1])
    assert np.max(np.hypot(x - sol.y[0], y - sol.y[1])) < 1e-8
    E = run.total
    assert np.max(np.abs(E - m.orbit_energy())) < 1e-11 * abs(m.orbit_energy())


def _apsides(n: float, rdot0: float, t_end: float) -> tuple[np.ndarray, np.ndarray]:
    """Times and polar angles θ (counted on, not wrapped) of the apsides of the scipy orbit."""
    sol = _scipy_orbit(n, 1.0, rdot0, 0.8, t_end, events=True)
    t = sol.t_events[0]
    t = t[t > 1e-9]
    return t, sol.sol(t)[4]


@pytest.mark.parametrize("n", [-2.5, -1.5, 0.5, 2.0])
def test_apsidal_angle_quadrature_against_integrated_apsides(n: float) -> None:
    m = _model(n, rdot0=0.3)
    t, theta = _apsides(n, 0.3, 12 * m.radial_period())
    # the orbit starts between apsides: the gaps between consecutive apsides are the angle
    assert np.max(np.abs(np.diff(theta) - m.apsidal_angle())) < 1e-9
    assert np.max(np.abs(np.diff(t[::2]) - m.radial_period())) < 1e-8 * m.radial_period()
    assert m.precession_per_orbit() == pytest.approx(2 * m.apsidal_angle() - 2 * math.pi)


@pytest.mark.parametrize(("n", "angle"), [(-2.0, math.pi), (1.0, math.pi / 2)])
def test_bertrand_closed_orbits(n: float, angle: float) -> None:
    """U ∝ r^{n+1} closes for n = −2 and 1 only (§4.4): apsidal angle π and π/2 at any
    eccentricity, and the integrated orbit returns to its start after one period."""
    for rdot0 in (0.0, 0.4):
        m = _model(n, rdot0=rdot0, thdot0=0.6)
        assert m.apsidal_angle() == pytest.approx(angle, rel=1e-11)
        assert m.precession_per_orbit() == pytest.approx(
            {-2.0: 0.0, 1.0: -math.pi}[n], abs=1e-10)
    m = _model(n, rdot0=0.4, thdot0=0.6)
    if n == -2.0:  # Kepler: a = K/2|E|, T = 2π√(μa³/K)
        a = K / (2 * abs(m.orbit_energy()))
        period = 2 * math.pi * math.sqrt(MU * a**3 / K)
    else:  # isotropic oscillator: T = 2π√(μ/K) for every orbit
        period = 2 * math.pi * math.sqrt(MU / K)
    y = make_stepper(m, "dop853", 1e-12).advance(np.array([period, 2 * period]))
    y0 = m.initial_y()
    for turns, row in enumerate(y, start=1):  # r back, θ one whole turn further per period
        assert abs(row[0] - y0[0]) < 1e-8
        assert abs(row[1] - y0[1] - 2 * math.pi * turns) < 1e-8


@pytest.mark.parametrize("n", [-2.5, -1.5, -1.0, 0.0, 0.5, 2.0])
def test_near_circular_apsidal_angle(n: float) -> None:
    """Start on the circular orbit through r = 1 (θ̇² = K/μ), nudged radially by 1e-4 of its
    speed: the quadrature gives π/√(n + 3) to O(e²)."""
    thdot = math.sqrt(K / MU)
    m = _model(n, rdot0=1e-4 * thdot, thdot0=thdot)
    expected = math.pi / math.sqrt(n + 3)
    assert m.near_circular_apsidal_angle() == pytest.approx(expected, rel=1e-15)
    assert m.apsidal_angle() == pytest.approx(expected, rel=1e-6)


@pytest.mark.parametrize("n", [-2.5, -1.0, 0.5, 2.0])
def test_small_radial_oscillations(n: float) -> None:
    """§4.5.1: ω_r² = U_eff″(r₀)/μ about the circular orbit: the model's √(n+3)θ̇₀ against a
    finite-difference U_eff″ at the radius found here by root finding, and against the
    period of r(t) of a slightly perturbed circular orbit integrated by mechsim."""
    l = MU * 1.0**2 * 0.8
    def U(r: float) -> float:
        return K * math.log(r) if n == -1.0 else K * r ** (n + 1) / (n + 1)

    def Ueff(r: float) -> float:
        return U(r) + l * l / (2 * MU * r * r)

    r0 = brentq(lambda r: (Ueff(r * (1 + 1e-7)) - Ueff(r * (1 - 1e-7))) / (2e-7 * r),
                1e-3, 1e3, xtol=1e-15)
    h = 1e-4 * r0
    curvature = (Ueff(r0 + h) - 2 * Ueff(r0) + Ueff(r0 - h)) / h**2
    m = _model(n)
    assert m.circular_radius() == pytest.approx(r0, rel=1e-9)
    assert m.radial_frequency() == pytest.approx(math.sqrt(curvature / MU), rel=1e-6)
    near = mechsim.load_system("power_law_orbit", mass=MU, exponent=n, force_constant=K,
                               **{"initial.r": r0, "initial_rate.r": 1e-5,
                                  "initial_rate.theta": l / (MU * r0 * r0)})
    period = 2 * math.pi / m.radial_frequency()
    run = mechsim.simulate(near, 6 * period, period / 200, tolerance=1e-12)
    dr = run.observables["radial_velocity"]
    up = np.flatnonzero((dr[:-1] < 0) & (dr[1:] >= 0))  # pericentres
    t_up = run.t[up] - dr[up] * (run.t[up + 1] - run.t[up]) / (dr[up + 1] - dr[up])
    assert np.mean(np.diff(t_up)) == pytest.approx(period, rel=1e-6)


def test_solvable_laws_in_closed_form() -> None:
    """n = −2: 1/r = (μK/l²)(1 + e cos(θ − θ_p)); n = 1: x, y each SHM at √(K/μ);
    n = −3 (l² > μK): the Cotes spiral u = u₀ cos βθ + (u₀′/β) sin βθ, β² = 1 − μK/l²."""
    thdot, rdot = 0.9, 0.3
    l = MU * thdot
    # n = −2
    run = mechsim.simulate(_model(-2.0, rdot0=rdot, thdot0=thdot), 15.0, 0.01, tolerance=1e-12)
    r, th = run.q[:, 0], run.q[:, 1]
    p = MU * K / l**2
    E = 0.5 * MU * (rdot**2 + thdot**2) - K
    e = math.sqrt(1 + 2 * E * l * l / (MU * K * K))
    th_p = math.atan2(-MU * rdot / l, 1.0 - p) if e else 0.0  # u′ = −e p sin, u − p = e p cos
    assert np.max(np.abs(1 / r - p * (1 + e * np.cos(th - th_p)))) < 1e-9
    # n = 1
    run = mechsim.simulate(_model(1.0, rdot0=rdot, thdot0=thdot), 15.0, 0.01, tolerance=1e-12)
    w = math.sqrt(K / MU)
    x, y = run.q[:, 0] * np.cos(run.q[:, 1]), run.q[:, 0] * np.sin(run.q[:, 1])
    assert np.max(np.abs(x - (np.cos(w * run.t) + rdot / w * np.sin(w * run.t)))) < 1e-9
    assert np.max(np.abs(y - thdot / w * np.sin(w * run.t))) < 1e-9
    # n = −3, above the critical l: escapes along a Cotes spiral
    thdot = 1.2  # l² = 2.43 > μK = 1.17
    l = MU * thdot
    run = mechsim.simulate(_model(-3.0, rdot0=rdot, thdot0=thdot), 6.0, 0.01, tolerance=1e-12)
    beta = math.sqrt(1 - MU * K / l**2)
    th = run.q[:, 1]
    u_closed = np.cos(beta * th) + (-MU * rdot / l) / beta * np.sin(beta * th)
    assert np.max(np.abs(1 / run.q[:, 0] - u_closed)) < 1e-9


def test_fall_to_the_centre() -> None:
    """n = −3 below the critical l: u = u₀ cosh β′θ + (u₀′/β′) sinh β′θ, β′² = μK/l² − 1,
    reaches 1/capture_radius at an angle found here; the work balance closes through it."""
    thdot, rdot, cap = 0.5, -0.1, 0.05
    l = MU * thdot
    m = _model(-3.0, rdot0=rdot, thdot0=thdot, capture_radius=cap)
    assert m.falls_to_centre()
    keys = [law.key for law in m.laws()]
    assert "energy" not in keys and "invariant:angular_momentum" not in keys
    run = mechsim.simulate(m, 5.0, 0.001, tolerance=1e-12)
    t_fall = run.event_times("fall")
    assert t_fall.size == 1
    bp = math.sqrt(MU * K / l**2 - 1)
    u1 = -MU * rdot / l
    theta_fall = brentq(lambda th: math.cosh(bp * th) + u1 / bp * math.sinh(bp * th) - 1 / cap,
                        0.0, 50.0, xtol=1e-14)
    after = run.t > t_fall[0]
    assert np.allclose(run.q[after, 1], theta_fall, atol=1e-8)
    assert np.allclose(run.q[after, 0], cap, rtol=1e-9)
    assert np.max(np.abs(run.balance_residual)) < 1e-9 * abs(m.orbit_energy())


def test_binet_form_matches_the_time_form() -> None:
    """u(θ) and t(θ) of the orbit equation (θ the independent variable) against the polar
    time form at the times t(θ): r = 1/u and θ agree, and both carry the same energy."""
    n = -2.5
    binet = mechsim.simulate(_model(n, "binet", rdot0=0.2), 4 * math.pi, 0.05, tolerance=1e-12)
    theta = binet.observables["theta"]
    assert np.allclose(theta, binet.t)  # θ₀ = 0: the clock counts θ
    tau = binet.coordinate("time")
    polar = _model(n, rdot0=0.2)
    y = make_stepper(polar, "dop853", 1e-12).advance(tau[1:])
    assert np.max(np.abs(y[:, 0] - 1 / binet.coordinate("u")[1:])) < 1e-8
    assert np.max(np.abs(y[:, 1] - theta[1:])) < 1e-8
    assert np.allclose(binet.total, polar.orbit_energy(), rtol=1e-11)
    assert np.max(np.abs(binet.invariants["time_momentum"])) < 1e-12


def test_binet_conic_for_the_inverse_square_law() -> None:
    m = _model(-2.0, "binet", rdot0=0.3, thdot0=0.9)
    run = mechsim.simulate(m, 6 * math.pi, 0.01, tolerance=1e-12)
    l = MU * 0.9
    p = MU * K / l**2
    u, up = 1.0, -MU * 0.3 / l  # u(0), u′(0)
    closed = p + (u - p) * np.cos(run.t) + up * np.sin(run.t)
    assert np.max(np.abs(run.coordinate("u") - closed)) < 1e-9


def test_refusals() -> None:
    with pytest.raises(mechsim.ParameterError, match="initial_rate.theta: must be nonzero"):
        _model(-2.0, thdot0=0.0)
    with pytest.raises(mechsim.ParameterError, match="formulation: binet takes bound orbits"):
        _model(-2.0, "binet", thdot0=2.0)  # E > 0: escapes
    with pytest.raises(mechsim.ParameterError, match="exponent"):
        _model(7.0)
