"""Scattering on a hard sphere and a repulsive Coulomb centre (PHYS0500 §5.3): deflection per
trajectory against the closed forms, the document's orbit integral (line 1255) by mpmath
quadrature, an independent Newtonian integration (scipy), the incoming hyperbola checked by
integrating backwards, σ from eq. 5.6 with sympy, the LAB conversion (eq. 5.10, 1312, 1316)
against a numerical derivative, and the beam's measured cross-sections."""

from __future__ import annotations

import math

import mpmath as mp
import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

import mechsim
from mechsim.errors import ParameterError
from mechsim.experiments.scattering_beam import beam
from mechsim.systems._scattering import cm_angles_of_lab, lab_angle, lab_cross_section
from mechsim.systems.scattering import COULOMB


def load(**kw: object) -> mechsim.systems.base.Model:
    return mechsim.load_system("scattering", **kw)


def positions(r: mechsim.SimulationResult) -> tuple[np.ndarray, np.ndarray]:
    names = [f.child for f in r.model.frames]
    F = r.outputs.frames
    cm = F[:, names.index("cm"), :2]
    return cm + F[:, names.index("particle_1"), :2], cm + F[:, names.index("particle_2"), :2]


def newton_relative(m: mechsim.systems.base.Model, y0: np.ndarray, t: np.ndarray,
                    rtol: float = 1e-13) -> np.ndarray:
    """μ r̈ = k r/|r|³ for the relative position, no Lagrangian."""
    k, mu = m.force_constant(), m.reduced_mass()

    def f(_: float, s: np.ndarray) -> np.ndarray:
        return np.concatenate([s[2:], k * s[:2] / (mu * np.linalg.norm(s[:2]) ** 3)])
    sol = solve_ivp(f, (t[0], t[-1]), y0, method="DOP853", rtol=rtol, atol=1e-14,
                    dense_output=True)
    return sol.sol(t).T


def test_hard_sphere_trajectory() -> None:
    m = load(target="hard_sphere", mass_1=2.0, mass_2=1.0)  # a = 2, b = 1, D = 10
    r = mechsim.simulate(m, 20.0, 0.01, tolerance=1e-12)
    a, b, D, u = 2.0, 1.0, 10.0, m.speed()
    assert abs(u - math.sqrt(2 * 1.0 / 2.0)) < 1e-15
    assert [n for _, n in r.events] == ["contact"]
    t_c = (math.sqrt(D * D - b * b) - math.sqrt(a * a - b * b)) / u
    assert abs(r.events[0][0] - t_c) < 1e-13 * t_c
    assert r.observables["radius"].min() > a * (1 - 1e-13)
    th = 2 * math.acos(b / a)
    o = {k: v[-1] for k, v in r.observables.items()}
    assert abs(o["cm_angle"] - th) < 1e-13
    assert abs(o["lab_angle_1"] - math.atan2(math.sin(th), math.cos(th) + 2.0)) < 1e-13
    assert abs(o["lab_angle_2"] - (math.pi - th) / 2) < 1e-13
    # target at rest at the origin until the contact; LAB kinetic energy conserved
    p1, p2 = positions(r)
    before = r.t < t_c
    assert np.max(np.abs(p2[before])) < 1e-14
    np.testing.assert_allclose(p1[0], [-math.sqrt(D * D - b * b), b], atol=1e-14)
    assert np.max(np.abs(r.total - 1.0)) < 1e-14
    for name in ("momentum_x", "momentum_y", "angular_momentum", "relative_energy"):
        v = r.invariants[name]
        assert np.max(np.abs(v - v[0])) < 1e-13 * max(1.0, abs(v[0])), name
    # energy sharing (T₂/T₀ = 2m₁m₂(1 − cos θ)/M², catalog supplement)
    assert abs(o["kinetic_energy_2"] - 2 * 2.0 * 1.0 * (1 - math.cos(th)) / 9.0) < 1e-13


@pytest.fixture(scope="module")
def coulomb_run() -> mechsim.SimulationResult:
    return mechsim.simulate(load(), 60.0, 0.005, tolerance=1e-12, method="dop853")


def test_coulomb_trajectory_matches_newton_and_closed_forms(coulomb_run) -> None:  # noqa: ANN001
    r = coulomb_run
    m = r.model
    k, E, b = m.force_constant(), m.cm_energy(), 1.0
    assert abs(k - COULOMB * 1e-10) < 1e-15 and abs(E - 0.8) < 1e-15
    ref = newton_relative(m, np.concatenate([r.q[0, 2:4], r.v[0, 2:4]]), r.t)
    assert np.max(np.abs(r.q[:, 2:4] - ref[:, :2])) < 1e-8
    # CM uniform at V = m₁u₁/M; target at the origin at t = 0
    V = m.value("mass_1") * m.speed() / 5.0
    np.testing.assert_allclose(r.v[:, 0], V, rtol=1e-14)
    assert np.max(np.abs(positions(r)[1][0])) < 1e-15
    # deflection: the outgoing asymptote of the orbit is the closed form at every sample,
    # and the velocity direction approaches it as the particle leaves (error ~ kb/(4Er²))
    th = 2 * math.atan(k / (2 * E * b))
    assert np.max(np.abs(r.observables["asymptotic_cm_angle"] - th)) < 1e-10
    rr = r.observables["radius"][-1]
    assert rr > 40.0 and abs(r.observables["cm_angle"][-1] - th) < k * b / (E * rr**2)
    # the LAB angle of the projectile tends to the model's ψ(b) (tan ψ = sin θ/(cos θ + m₁/m₂)),
    # as k/(E r): it depends on the relative speed, which approaches its asymptote as 1/r
    psi = float(m.lab_deflection(b))
    assert psi == pytest.approx(math.atan2(math.sin(th), math.cos(th) + m.mass_ratio()))
    assert abs(r.observables["lab_angle_1"][-1] - psi) < k / (E * rr)
    # closest approach r_min = k/(2E) + √((k/2E)² + b²) (catalog supplement)
    rmin = k / (2 * E) + math.hypot(k / (2 * E), b)
    i = int(np.argmin(r.observables["radius"]))
    assert abs(r.observables["radius"][i] - rmin) < 1e-6 * rmin
    # E, L, momenta and the LRL vector conserved
    assert np.max(np.abs(r.total - r.total[0])) < 1e-10
    for name, v in r.invariants.items():
        assert np.max(np.abs(v - v[0])) < 1e-10 * max(1.0, abs(v[0])), name


def test_incoming_state_is_on_the_asymptote_line() -> None:
    """Integrate backwards from the initial state far out: velocity → u₁ along +x; L = −μu₁b
    fixes the asymptote's distance b from the centre."""
    m = load(impact_parameter=0.7, mass_1=2.0)
    q, v = m.initial_state()
    mu, u = m.reduced_mass(), m.speed()
    assert abs(mu * (q[2] * v[3] - q[3] * v[2]) + mu * u * 0.7) < 1e-14
    back = newton_relative(m, np.concatenate([q[2:4], v[2:4]]), np.array([0.0, -2e4]),
                           rtol=1e-12)[-1]
    assert np.hypot(*back[:2]) > 2e4
    assert abs(math.atan2(back[3], back[2])) < 1e-9
    assert abs(np.hypot(*back[2:]) - u) < 1e-4 * u  # speed still lacks ~k/(2E r)
    assert back[0] < 0 and abs(back[1] - 0.7) < 0.05  # on the incoming side, height ≈ b


def test_document_orbit_integral_gives_the_rutherford_angle() -> None:
    """Θ = ∫ (b/r²) dr / √(1 − b²/r² − U/T₀′) over r > r_min (line 1255), θ = π − 2Θ (5.7),
    by mpmath quadrature in s = 1/r, against tan(θ/2) = k/(2Eb) and the simulation."""
    mp.mp.dps = 30
    m = load()
    k, E = m.force_constant(), m.cm_energy()
    for b in (0.1, 0.5, 1.0, 3.0, 10.0):
        kk, EE, bb = mp.mpf(k), mp.mpf(E), mp.mpf(b)
        # 1 − b²s² − (k/E)s = b²(s₁ − s)(s + s₂); s = s₁ − t² removes the end singularity
        disc = mp.sqrt((kk / EE) ** 2 + 4 * bb**2)
        s1, s2 = (disc - kk / EE) / (2 * bb**2), (disc + kk / EE) / (2 * bb**2)
        Theta = mp.quad(lambda t, c=s1 + s2: 2 / mp.sqrt(c - t**2), [0, mp.sqrt(s1)])
        direct = mp.quad(lambda s, b=bb, q=kk / EE: b / mp.sqrt(1 - b**2 * s**2 - q * s),
                         [0, s1])
        assert abs(mp.re(direct) - Theta) < 1e-8  # the integrand as printed, for the record
        theta = float(mp.pi - 2 * Theta)
        assert abs(theta - 2 * math.atan(k / (2 * E * b))) < 1e-14
        assert abs(theta - float(m.deflection(b))) < 1e-14
        mb = m.with_values(impact_parameter=b, **{"initial.distance": 30.0})
        r = mechsim.simulate(mb, 1.0, 1.0, tolerance=1e-12, method="dop853")
        assert np.max(np.abs(r.observables["asymptotic_cm_angle"] - theta)) < 1e-10


def test_cross_sections_from_eq_5_6() -> None:
    """σ = (b/sin θ)|db/dθ| (eq. 5.6): b = a cos(θ/2) gives a²/4 (line 1356), σ_t = πa²;
    b = (k/2E) cot(θ/2) gives (k/4E)²/sin⁴(θ/2)."""
    th, a, k, E = sp.symbols("theta a k E", positive=True)
    for b, sigma in ((a * sp.cos(th / 2), a**2 / 4),
                     (k / (2 * E) * sp.cot(th / 2), (k / (4 * E)) ** 2 / sp.sin(th / 2) ** 4)):
        expr = b / sp.sin(th) * (-sp.diff(b, th))  # db/dθ < 0 on (0, π)
        val = sp.simplify(expr - sigma)
        for t in (0.3, 1.1, 2.5):
            assert abs(float(val.subs({th: t, a: 1.7, k: 0.9, E: 0.8}))) < 1e-12
    assert sp.simplify(sp.integrate(a**2 / 4 * 2 * sp.pi * sp.sin(th), (th, 0, sp.pi))
                       - sp.pi * a**2) == 0


@pytest.mark.parametrize("x", [0.25, 0.9, 2.0])
def test_lab_conversion(x: float) -> None:
    """Eq. 5.10 against the numerical dΩ′/dΩ of ψ(θ) = atan2(sin θ, cos θ + x); eq. 1312 for
    x < 1; eq. 1316 (and the second branch for x > 1) inverts tan ψ (eq. 5.3–5.4)."""
    for th in np.linspace(0.1, 3.0, 15):
        psi = float(lab_angle(th, x))
        branches = cm_angles_of_lab(psi, x)
        assert min(abs(t - th) for t in branches) < 1e-12
        for t in branches:
            assert abs(float(lab_angle(t, x)) - psi) < 1e-12
        h = 1e-6
        dpsi = (float(lab_angle(th + h, x)) - float(lab_angle(th - h, x))) / (2 * h)
        jac = math.sin(th) / (math.sin(psi) * abs(dpsi))  # dΩ′/dΩ
        one = lab_cross_section(lambda t, c=th: 1.0 if abs(t - c) < 1e-9 else 0.0, psi, x)[0]
        assert abs(one - jac) < 1e-7 * jac
        if x < 1:  # eq. 1312
            c = math.sqrt(1 - x * x * math.sin(psi) ** 2)
            assert abs(one - (x * math.cos(psi) + c) ** 2 / c) < 1e-10 * one
    if x > 1:
        assert len(cm_angles_of_lab(0.3, x)) == 2
        assert cm_angles_of_lab(math.asin(1 / x) + 1e-3, x) == []


def test_hard_sphere_beam() -> None:
    m = load(target="hard_sphere", mass_1=2.0, mass_2=1.0, sphere_radius=1.5)
    B = beam(m, count=2000, bins=20)
    assert B.impact_parameters.size == 2001
    a = 1.5
    np.testing.assert_allclose(B.cm_angles, 2 * np.arccos(B.impact_parameters / a), atol=1e-12)
    th = B.cm_angles
    np.testing.assert_allclose(B.lab_angles, np.arctan2(np.sin(th), np.cos(th) + 2.0),
                               atol=1e-12)
    assert B.lab_angles.max() <= math.asin(0.5) + 1e-12
    # σ = a²/4 (isotropic, CM), σ_t = πa²
    np.testing.assert_allclose(B.cm_analytic, a * a / 4, rtol=1e-12)
    np.testing.assert_allclose(B.cm_measured, a * a / 4, rtol=1e-9)
    solid = 2 * np.pi * -np.diff(np.cos(B.cm_edges))
    assert abs(np.sum(B.cm_measured * solid) - math.pi * a * a) < 1e-9
    assert np.max(np.abs(B.lab_measured / B.lab_analytic - 1)) < 2e-3
    lab_solid = 2 * np.pi * -np.diff(np.cos(B.lab_edges))
    assert abs(np.sum(B.lab_analytic * lab_solid) - math.pi * a * a) < 1e-6


def test_rutherford_beam() -> None:
    m = load(**{"initial.distance": 1000.0}, mass_1=1.0, mass_2=4.0)
    B = beam(m, count=2000, bins=20)
    k, E = m.force_constant(), m.cm_energy()
    b = B.impact_parameters
    assert np.max(np.abs(B.cm_angles - 2 * np.arctan(k / (2 * E * b)))) < 5e-6
    assert abs(math.degrees(B.cm_edges[0]) - 10) < 1e-3
    assert abs(math.degrees(B.cm_edges[-1]) - 170) < 1e-3
    # the analytic bin average of (k/4E)²/sin⁴(θ/2) = ∫ 2πb db / ΔΩ with b = (k/2E) cot(θ/2)
    e = B.cm_edges
    exact = np.pi * (k / (2 * E)) ** 2 * -np.diff(1 / np.tan(e / 2) ** 2) / (
        2 * np.pi * -np.diff(np.cos(e)))
    np.testing.assert_allclose(B.cm_analytic, exact, rtol=1e-9)
    assert np.max(np.abs(B.cm_measured / B.cm_analytic - 1)) < 1e-3
    assert np.max(np.abs(B.lab_measured / B.lab_analytic - 1)) < 1e-3
    # dσ over the beam = π(b_max² − b_min²), measured again from the histogram
    solid = 2 * np.pi * -np.diff(np.cos(B.cm_edges))
    assert abs(np.sum(B.cm_measured * solid) / B.total_cross_section - 1) < 1e-12
    assert abs(B.total_cross_section - math.pi * (b[-1] ** 2 - b[0] ** 2)) < 1e-9


def test_long_run_conservation_symplectic() -> None:
    m = load(impact_parameter=0.3)
    r = mechsim.simulate(m, 300.0, 0.05, tolerance=1e-10, method="yoshida8")
    E0 = r.total[0]
    assert np.max(np.abs(r.total - E0)) < 1e-9 * abs(E0)
    assert np.max(np.abs(r.balance_residual)) < 1e-9 * abs(E0)
    for name in ("angular_momentum", "runge_lenz_x", "runge_lenz_y", "momentum_x"):
        v = r.invariants[name]
        assert np.max(np.abs(v - v[0])) < 1e-9 * max(1.0, abs(v[0])), name


def test_parameter_validation() -> None:
    with pytest.raises(ParameterError, match="^target: must be one of hard_sphere, coulomb"):
        load(target="soft")
    with pytest.raises(ParameterError, match="^charge_2: must be nonzero and of the sign"):
        load(charge_2=-1e-5)
    with pytest.raises(ParameterError, match="^initial.distance: must be > the closest"):
        load(**{"initial.distance": 1.0})
    with pytest.raises(ParameterError, match="^initial.distance: must be > sphere_radius"):
        load(target="hard_sphere", **{"initial.distance": 1.5})
    with pytest.raises(ParameterError, match="^energy: must be > 0"):
        load(energy=0.0)
    with pytest.raises(ParameterError, match="^spacing: must be log or area"):
        beam(load(), count=10, spacing="linear")
