"""Charged particle in uniform fields (Lecture 10, charged particle in an electromagnetic field
(eqs. 10.51–10.67), Introduction to analytical mechanics, “Lagrange's equation of motion velocity
dependent potentials”) and the two moving charges of “Action and Reaction”, Case 3."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from scipy.constants import epsilon_0, mu_0
from scipy.linalg import expm

import mechsim
from mechsim.errors import ParameterError
from mechsim.systems.charged_particle import (
    darwin_vector_potential,
    induction_forces,
    interaction_field_momentum,
    two_charge_forces,
)

FORMS = ("cylindrical", "symmetric", "landau")
# E in the x–z plane: the Landau p_y stays conserved (one kernel fewer to compile in CI)
DRIFT = {"electric_field.x": 0.3, "electric_field.z": 0.1, "initial.x": 2.0, "initial.y": 1.0}


def exact(params: dict, t: np.ndarray) -> np.ndarray:
    """Independent solution of m r̈ = q (E + ṙ × B ẑ): the linear system ẏ = A y + c in
    Cartesian (r, v), solved by the matrix exponential of the augmented matrix."""
    m, q, B = (params.get("mass", 1.0), params.get("charge", 1.0),
               params.get("magnetic_field", 2.0))
    E = np.array([params.get(f"electric_field.{c}", 0.0) for c in "xyz"])
    y0 = [params.get("initial.x", 1.0), params.get("initial.y", 0.0),
          params.get("initial.z", 0.0), params.get("initial_rate.x", 0.0),
          params.get("initial_rate.y", -1.5), params.get("initial_rate.z", 0.2), 1.0]
    A = np.zeros((7, 7))
    A[0:3, 3:6] = np.eye(3)
    w = q * B / m
    A[3, 4], A[4, 3] = w, -w  # (v × ẑ) = (v_y, −v_x, 0)
    A[3:6, 6] = q * E / m
    return np.array([expm(A * tt) @ y0 for tt in t])[:, :6]


def run(form: str, params: dict, t_end: float = 10.0, dt: float = 0.01,
        tol: float = 1e-12) -> mechsim.SimulationResult:
    return mechsim.simulate(mechsim.load_system("charged_particle", formulation=form,
                                                **params), t_end, dt, tolerance=tol)


@pytest.mark.parametrize(("params", "forms"), [
    ({}, FORMS), ({"charge": -0.5, "mass": 2.0, "electric_field.z": -0.3}, FORMS),
    (DRIFT, ("symmetric", "landau"))])
def test_all_gauges_follow_the_exact_trajectory(params: dict, forms: tuple[str, ...]) -> None:
    for form in forms:
        r = run(form, params)
        ref = exact(params, r.t)
        pos = r.outputs.frames[:, 1, :3]
        assert np.max(np.abs(pos - ref[:, :3])) < 1e-9, form
        assert np.max(np.abs(r.balance_residual)) < 1e-10
        assert np.ptp(r.total) < 1e-10  # E = ½mv² − qE·r, static fields


def test_cyclotron_frequency_sense_larmor_radius_pitch() -> None:
    m = mechsim.load_system("charged_particle", formulation="symmetric")
    wc = m.cyclotron_frequency()
    assert wc == pytest.approx(2.0)  # |q| B / m with q = 1, B = 2, m = 1
    r = run("symmetric", {}, t_end=2 * math.pi / wc, dt=2 * math.pi / wc / 400)
    # sense: the velocity direction turns at φ̇ = −qB/m (clockwise about +z for qB > 0)
    ang = np.unwrap(np.arctan2(r.v[:, 1], r.v[:, 0]))
    assert np.allclose(np.diff(ang) / np.diff(r.t), -2.0, atol=1e-8)
    assert m.gyration_rate() == -2.0
    # Larmor radius m v⊥ / (|q| B) = 1.5 / 2: half the x and y extent of the circle
    assert m.larmor_radius() == pytest.approx(0.75)
    assert np.ptp(r.q[:, 0]) / 2 == pytest.approx(0.75, abs=1e-6)
    assert np.ptp(r.q[:, 1]) / 2 == pytest.approx(0.75, abs=1e-6)
    # after one period the particle is back over its start, advanced by the pitch along B
    assert np.allclose(r.q[-1, :2], r.q[0, :2], atol=1e-9)
    assert r.q[-1, 2] - r.q[0, 2] == pytest.approx(m.pitch(), abs=1e-10)
    assert m.pitch() == pytest.approx(2 * math.pi * 0.2 / 2.0)
    # the guiding centre is fixed at r − (m/(qB)) ẑ × v = (0.25, 0)
    assert np.allclose(r.observables["guiding_centre_x"], 0.25, atol=1e-10)
    assert np.allclose(r.observables["guiding_centre_y"], 0.0, atol=1e-10)


def test_e_cross_b_drift() -> None:
    m = mechsim.load_system("charged_particle", formulation="symmetric", **DRIFT)
    vd = m.drift_velocity()
    E, B = np.array([0.3, 0.0, 0.1]), np.array([0, 0, 2.0])
    assert np.allclose(vd, np.cross(E, B) / 4.0, atol=1e-15)
    T = 2 * math.pi / m.cyclotron_frequency()
    r = run("symmetric", DRIFT, t_end=3 * T, dt=T / 200)
    # mean perpendicular velocity over whole gyrations (from positions, not from formulas)
    for k in range(3):
        i, j = 200 * k, 200 * (k + 1)
        assert (r.q[j, :2] - r.q[i, :2]) / T == pytest.approx(vd[:2], abs=1e-9)
    # the guiding centre moves uniformly at v_d
    xc, yc = r.observables["guiding_centre_x"], r.observables["guiding_centre_y"]
    assert np.allclose(np.gradient(xc, r.t), vd[0], atol=1e-8)
    assert np.allclose(np.gradient(yc, r.t), vd[1], atol=1e-8)
    # E_z accelerates the particle uniformly along B: z = z₀ + v_z t + ½ (qE_z/m) t²
    assert np.allclose(r.q[:, 2], 0.2 * r.t + 0.05 * r.t**2, atol=1e-9)


def test_canonical_not_mechanical_angular_momentum() -> None:
    for form in ("cylindrical", "symmetric"):
        r = run(form, {})
        p = r.invariants["canonical_angular_momentum"]
        assert np.ptp(p) < 1e-10
        assert np.ptp(r.observables["mechanical_angular_momentum"]) > 0.5
        assert np.ptp(r.observables["speed"]) < 1e-10  # E = 0: |v| constant
    # centred orbit (ρ = 1, φ̇ = −qB/m): constant radius, p_φ = −½ q B ρ²
    r = run("cylindrical", {"initial_rate.y": -2.0})
    assert np.ptp(r.coordinate("rho")) < 1e-10
    assert np.allclose(r.rate("phi"), -2.0, atol=1e-10)
    assert np.allclose(r.invariants["canonical_angular_momentum"], -1.0, atol=1e-10)


def test_gauge_transformation_and_landau_momentum() -> None:
    # L' − L = −q dΛ/dt with Λ = −½ B x y (A' = A − ∇Λ), so the equations are the same
    x, y, vx, vy, q, B = sp.symbols("x y v_x v_y q B", real=True)
    L_sym = q * (vx * (-B * y / 2) + vy * (B * x / 2))
    L_landau = q * vy * B * x
    Lam = -B * x * y / 2
    dLam = sp.diff(Lam, x) * vx + sp.diff(Lam, y) * vy
    assert sp.simplify(L_landau - L_sym + q * dLam) == 0
    r = run("landau", {})
    assert np.ptp(r.invariants["canonical_momentum_y"]) < 1e-12
    assert np.allclose(r.invariants["canonical_momentum_y"], r.v[:, 1] + 2.0 * r.q[:, 0])
    # with E_y ≠ 0 the Landau p_y is not conserved (observable only, not a law)
    m = mechsim.load_system("charged_particle", formulation="landau",
                            **{"electric_field.y": 0.2})
    assert "canonical_momentum_y" in [o.name for o in m.observables]
    assert "invariant:canonical_momentum_y" not in [law.key for law in m.laws()]
    # in crossed fields the gauge-invariant pseudo-momentum is conserved; p_φ is not
    r = run("symmetric", DRIFT)
    assert np.ptp(r.observables["canonical_angular_momentum"]) > 0.1
    for c in "xyz":
        assert np.ptp(r.invariants[f"pseudo_momentum_{c}"]) < 1e-10


def test_long_run_energy_and_momentum() -> None:
    r = run("cylindrical", {}, t_end=200 * math.pi, dt=0.05, tol=1e-11)
    assert np.ptp(r.total) / r.total[0] < 1e-9
    assert np.ptp(r.invariants["canonical_angular_momentum"]) < 1e-9
    assert np.max(np.abs(r.balance_residual)) < 1e-9


def test_laws() -> None:
    keys = [law.key for law in mechsim.load_system("charged_particle").laws()]
    assert keys[:3] == ["energy", "energy_function", "work_balance"]
    assert "invariant:canonical_angular_momentum" in keys
    m = mechsim.load_system("charged_particle", **DRIFT)
    assert "invariant:canonical_angular_momentum" not in [law.key for law in m.laws()]


def test_parameter_errors() -> None:
    with pytest.raises(ParameterError, match="^charge: must be nonzero"):
        mechsim.load_system("charged_particle", charge=0.0)
    with pytest.raises(ParameterError, match="^magnetic_field: must be > 0"):
        mechsim.load_system("charged_particle", magnetic_field=0.0)
    with pytest.raises(ParameterError, match="^initial.x: .*axis"):
        mechsim.load_system("charged_particle", **{"initial.x": 0.0})
    mechsim.load_system("charged_particle", formulation="landau", **{"initial.x": 0.0})


# --- “Action and Reaction”, Case 3: two moving charges --------------------------------------------
Q, V, RHO = 1e-6, 1e5, 0.01
K_M = mu_0 * Q**2 * V**2 / (4 * math.pi * RHO**2)
K_E = Q**2 / (4 * math.pi * epsilon_0 * RHO**2)


@pytest.mark.parametrize("alpha", [0.0, 0.3, 1.1, math.pi / 2, 2.5])
def test_parallel_velocities_weak_action_reaction(alpha: float) -> None:
    v = V * np.array([math.cos(alpha), math.sin(alpha), 0.0])
    F12, F21 = two_charge_forces(Q, Q, [0, RHO, 0], [0, 0, 0], v, v)
    assert np.allclose(F12, -F21, rtol=0, atol=1e-12 * K_E)
    # corrected L863: v² factor, −cos²α, repulsive Coulomb term
    expect = K_M * np.array([math.sin(alpha) * math.cos(alpha), -math.cos(alpha) ** 2, 0]) \
        + K_E * np.array([0, 1.0, 0])
    assert np.allclose(F12, expect, rtol=0, atol=1e-12 * K_E)
    assert F12[0] == pytest.approx(K_M * math.sin(alpha) * math.cos(alpha), abs=1e-12 * K_E)


def test_cross_the_t_and_field_momentum() -> None:
    # charge 2 moves straight at charge 1 (along +ĵ), charge 1 moves along +î
    r1, r2 = np.array([0, RHO, 0.0]), np.array([0, 0, 0.0])
    v1, v2 = np.array([V, 0, 0.0]), np.array([0, V, 0.0])
    F12, F21 = two_charge_forces(Q, Q, r1, r2, v1, v2)
    coulomb = K_E * np.array([0, 1.0, 0])
    assert np.allclose(F12 - coulomb, 0, atol=1e-12 * K_E)  # no magnetic force on 1
    mag21 = F21 + coulomb
    assert np.linalg.norm(mag21) == pytest.approx(K_M, rel=1e-12)
    assert abs(mag21[0]) == pytest.approx(K_M, rel=1e-12)
    assert np.linalg.norm(F12 + F21) == pytest.approx(K_M, rel=1e-12)  # F₁₂ ≠ −F₂₁


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_field_momentum_carries_the_missing_momentum(seed: int) -> None:
    rng = np.random.default_rng(seed)
    q1, q2 = 2e-6 * rng.uniform(0.5, 1), -1e-6 * rng.uniform(0.5, 1)
    r1, r2 = rng.normal(size=3) * 0.01, rng.normal(size=3) * 0.01
    v1, v2 = rng.normal(size=3) * 1e5, rng.normal(size=3) * 1e5
    F12, F21 = two_charge_forces(q1, q2, r1, r2, v1, v2)
    I1, I2 = induction_forces(q1, q2, r1, r2, v1, v2)
    # independent: −∂A₂/∂t at the fixed point r₁ as charge 2 moves on, by central differences
    h = 1e-5 * np.linalg.norm(r1 - r2) / max(np.linalg.norm(v1), np.linalg.norm(v2))
    dA = (darwin_vector_potential(q2, r2 + v2 * h, v2, r1)
          - darwin_vector_potential(q2, r2 - v2 * h, v2, r1)) / (2 * h)
    assert np.allclose(I1, -q1 * dA, rtol=1e-6, atol=1e-9 * np.linalg.norm(I1))
    # curl of the Darwin potential is the Biot–Savart field
    def A(p: np.ndarray) -> np.ndarray:
        return darwin_vector_potential(q2, r2, v2, p)
    e = 1e-8
    J = np.array([(A(r1 + e * np.eye(3)[k]) - A(r1 - e * np.eye(3)[k])) / (2 * e)
                  for k in range(3)])  # J[k, i] = ∂A_i/∂x_k
    curl = np.array([J[1, 2] - J[2, 1], J[2, 0] - J[0, 2], J[0, 1] - J[1, 0]])
    R = r1 - r2
    bs = mu_0 * q2 * np.cross(v2, R) / (4 * math.pi * np.linalg.norm(R) ** 3)
    assert np.allclose(curl, bs, rtol=1e-6, atol=1e-7 * np.linalg.norm(bs))
    # momentum balance along uniform motion: d(P_field)/dt = −(all forces on the pair)
    def P(tt: float) -> np.ndarray:
        return interaction_field_momentum(q1, q2, r1 + v1 * tt, r2 + v2 * tt, v1, v2)
    dP = (P(h) - P(-h)) / (2 * h)  # same h: displacement 1e-5 of the separation
    total = F12 + F21 + I1 + I2
    assert np.allclose(dP, -total, rtol=1e-6, atol=1e-6 * np.linalg.norm(dP))
    magnetic_scale = mu_0 * abs(q1 * q2) * np.linalg.norm(v1) * np.linalg.norm(v2) / (
        4 * math.pi * np.linalg.norm(R) ** 2)
    assert np.linalg.norm(F12 + F21) > 1e-2 * magnetic_scale  # mechanical: unbalanced


@pytest.mark.parametrize("form", FORMS)
@pytest.mark.parametrize("params", [
    {},  # circles the axis: φ winds
    {"charge": -0.5, "mass": 2.0, "electric_field.z": -0.3},
    DRIFT,
    {"electric_field.y": 1.5, "initial_rate.x": 0.5},  # drifts along x, past the axis
])
def test_closed_form(form: str, params: dict) -> None:
    """``propagate`` (method exact) against the matrix exponential of the Cartesian system
    (positions via the frames, every formulation) and against radau15 at 1e-14 in the
    formulation's own coordinates (φ continued through every winding): 1e-13 relative to the
    state scale over ten cyclotron periods."""
    from mechsim.integrators import make_stepper

    model = mechsim.load_system("charged_particle", formulation=form, **params)
    assert model.has_closed_form()
    r = mechsim.simulate(model, 10 * model.time_scale(), 0.05, method="exact")
    ref = exact(params, r.t)
    pos = r.outputs.frames[:, 1, :3]
    assert np.max(np.abs(pos - ref[:, :3])) < 1e-13 * np.max(np.abs(ref[:, :3]))
    assert np.ptp(r.total) < 1e-13 * np.max(np.abs(r.total)) + 1e-15
    t = np.linspace(0.0, 10 * model.time_scale(), 11)[1:]
    E = make_stepper(model, "exact").advance(t)
    R = make_stepper(model, "radau15", 1e-14).advance(t)
    for part in (slice(0, 3), slice(3, 6)):
        assert np.max(np.abs(E[:, part] - R[:, part])) < 1e-13 * np.max(np.abs(R[:, part]))


def test_closed_form_from_any_state() -> None:
    """From a state at t₀ ≠ 0 (what a stepper restarted after a parameter change passes)."""
    params = {"electric_field.x": -0.4, "electric_field.y": 0.2, "electric_field.z": 0.5}
    model = mechsim.load_system("charged_particle", formulation="symmetric", **params)
    y0 = np.array([0.3, -1.2, 0.5, 0.7, 0.1, -0.4, 0.0, 0.0])
    t0, t = 2.5, np.array([2.5, 3.0, 7.25, 20.0])
    rows = model.propagate(t0, y0, t)
    shifted = {**params, "initial.x": 0.3, "initial.y": -1.2, "initial.z": 0.5,
               "initial_rate.x": 0.7, "initial_rate.y": 0.1, "initial_rate.z": -0.4}
    ref = exact(shifted, t - t0)
    assert np.max(np.abs(rows[:, :6] - ref)) < 1e-13 * np.max(np.abs(ref))
