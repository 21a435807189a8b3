"""CR3BP (“Action and Reaction”, Case 2): Jacobi integral, Lagrange points, both formulations,
against scipy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import mechsim
from mechsim.errors import ParameterError

EARTH_MOON = {"primary_mass": 1 - 0.012150585, "secondary_mass": 0.012150585}


def reference(params: dict, t: np.ndarray) -> np.ndarray:
    """Independent solution of the corrected document equation (L810 with G, ω² = GM/L³,
    document layout m₁ at +(m₂/M)Lû): inertial x, y, ẋ, ẏ at times t."""
    G, m1, m2, L = (params.get("gravitational_constant", 1.0), params.get("primary_mass", 0.9),
                    params.get("secondary_mass", 0.1), params.get("separation", 1.0))
    M = m1 + m2
    w = math.sqrt(G * M / L**3)

    def f(tt: float, s: np.ndarray) -> list[float]:
        u = np.array([math.cos(w * tt), math.sin(w * tt)])
        r1, r2 = m2 / M * L * u, -m1 / M * L * u
        r = s[:2]
        a = G * m1 * (r1 - r) / np.linalg.norm(r1 - r) ** 3 \
            + G * m2 * (r2 - r) / np.linalg.norm(r2 - r) ** 3
        return [s[2], s[3], a[0], a[1]]

    s0 = [params.get("initial.x", 0.5), params.get("initial.y", 0.0),
          params.get("initial_rate.x", 0.0), params.get("initial_rate.y", 0.9)]
    sol = solve_ivp(f, (t[0], t[-1]), s0, method="DOP853", rtol=1e-13, atol=1e-13,
                    dense_output=True)
    return sol.sol(t).T


@pytest.fixture(scope="module")
def runs() -> dict[str, mechsim.SimulationResult]:
    return {f: mechsim.simulate(mechsim.load_system("cr3bp", formulation=f), 20.0, 1e-3,
                                tolerance=1e-12) for f in ("inertial", "synodic")}


def test_trajectory_matches_independent_solution(runs: dict) -> None:
    r = runs["inertial"]
    ref = reference({}, r.t)
    assert np.max(np.abs(r.q - ref[:, :2])) < 1e-7
    assert np.max(np.abs(r.v - ref[:, 2:])) < 1e-6  # close pass by m₂ near t ≈ 19
    # inertial position published on the particle frame, for both formulations
    for f in ("inertial", "synodic"):
        assert np.max(np.abs(runs[f].outputs.frames[:, 3, :2] - ref[:, :2])) < 1e-8


def test_formulations_agree(runs: dict) -> None:
    a, b = runs["inertial"], runs["synodic"]
    assert np.max(np.abs(a.outputs.frames - b.outputs.frames)) < 1e-7
    for name in a.observables:
        assert np.max(np.abs(a.observables[name] - b.observables[name])) < 1e-7, name
    # synodic: the engine's energy function h is the Jacobi integral, T + V the inertial E
    assert np.max(np.abs(b.energy_function - b.invariants["jacobi"])) < 1e-12
    assert np.max(np.abs(b.total - b.observables["inertial_energy"])) < 1e-12


def test_jacobi_conserved_energy_and_angular_momentum_not(runs: dict) -> None:
    for r in runs.values():
        J = r.invariants["jacobi"]
        assert np.ptp(J) < 1e-9
        assert np.max(np.abs(r.balance_residual)) < 1e-8
        E, Lz = r.observables["inertial_energy"], r.observables["angular_momentum_z"]
        assert np.ptp(E) > 0.5 and np.ptp(Lz) > 0.1
        w = r.model.rotation_rate()
        assert np.max(np.abs(E - w * Lz - J)) < 1e-12
        assert np.max(np.abs(r.observables["jacobi_constant"] + 2 * J)) < 1e-12


def test_inertial_energy_range_dense_sampling() -> None:
    """Catalog erratum: the range comes from dense sampling; compute both sides, hard-code none."""
    r = mechsim.simulate(mechsim.load_system("cr3bp"), 20.0, 2e-4, tolerance=1e-12)
    ref = reference({}, r.t)
    m1, m2 = 0.9, 0.1
    u = np.stack([np.cos(r.t), np.sin(r.t)], axis=1)
    E = 0.5 * np.sum(ref[:, 2:] ** 2, axis=1) \
        - m1 / np.linalg.norm(ref[:, :2] - m2 * u, axis=1) \
        - m2 / np.linalg.norm(ref[:, :2] + m1 * u, axis=1)
    Em = r.observables["inertial_energy"]
    assert abs(Em.min() - E.min()) < 1e-8 and abs(Em.max() - E.max()) < 1e-8
    assert -2.54 < Em.min() < -2.53 and -1.55 < Em.max() < -1.54  # not the quoted −2.4496


def test_rotation_rate_is_kepler_third_law() -> None:
    m = mechsim.load_system("cr3bp", gravitational_constant=2.0, primary_mass=3.0,
                            secondary_mass=1.0, separation=2.0, **{"initial.x": 0.3})
    w = m.rotation_rate()
    # each primary's circular orbit: ω² r_i = G m_j / L²
    assert w**2 * (1.0 / 4.0) * 2.0 == pytest.approx(2.0 * 1.0 / 4.0, rel=1e-14)
    assert w**2 * (3.0 / 4.0) * 2.0 == pytest.approx(2.0 * 3.0 / 4.0, rel=1e-14)
    r = mechsim.simulate(m, 1.0, 0.5, outputs=("frames",))
    q = r.outputs.frames[-1, 0, 3:]  # synodic frame: yaw ωt about +z
    assert 2 * math.atan2(q[2], q[3]) == pytest.approx(w * 1.0, rel=1e-13)


def test_lagrange_points_published_values_and_layout() -> None:
    m = mechsim.load_system("cr3bp", **EARTH_MOON)
    pts = m.lagrange_points()
    # textbook Earth–Moon values (μ = 0.012150585), negated for the document layout
    assert pts["L1"][0] == pytest.approx(-0.836915, abs=2e-6)
    assert pts["L2"][0] == pytest.approx(-1.155682, abs=2e-6)
    assert pts["L3"][0] == pytest.approx(1.005063, abs=2e-6)
    mu = 0.012150585
    assert pts["L4"] == pytest.approx([-(0.5 - mu), -math.sqrt(3) / 2], abs=1e-14)
    # L4 leads m₂ by 60° in the sense of rotation (+z)
    ang = math.atan2(pts["L4"][1], pts["L4"][0]) - math.atan2(0.0, -(1 - mu))
    assert math.remainder(ang, 2 * math.pi) == pytest.approx(math.pi / 3, abs=0.02)


@pytest.mark.parametrize("params", [{}, EARTH_MOON, {"gravitational_constant": 3.0,
                                                     "separation": 2.0, "primary_mass": 0.6,
                                                     "secondary_mass": 0.4}])
def test_lagrange_points_are_equilibria(params: dict) -> None:
    m = mechsim.load_system("cr3bp", formulation="synodic", **params)
    G, L = m.value("gravitational_constant"), m.value("separation")
    m1, m2 = m.value("primary_mass"), m.value("secondary_mass")
    w = m.rotation_rate()
    p1, p2 = np.array([m2 / (m1 + m2) * L, 0]), np.array([-m1 / (m1 + m2) * L, 0])
    for name, xy in m.lagrange_points().items():
        # independent: gradient of the effective potential ½ω²ρ² + Gm₁/ρ₁ + Gm₂/ρ₂ vanishes
        g = w**2 * xy - G * m1 * (xy - p1) / np.linalg.norm(xy - p1) ** 3 \
            - G * m2 * (xy - p2) / np.linalg.norm(xy - p2) ** 3
        assert np.max(np.abs(g)) < 1e-12 * G * (m1 + m2) / L**2, name
        # and the model's own equations of motion: zero acceleration at rest in synodic
        y = np.array([xy[0], xy[1], 0.0, 0.0, 0.0, 0.0])
        dy = np.empty(6)
        m.kernels.rhs(0.0, y, m.parameter_vector(), dy)
        assert np.max(np.abs(dy[2:4])) < 1e-12 * G * (m1 + m2) / L**2, name


def test_l4_stable_l1_unstable_earth_moon() -> None:
    base = mechsim.load_system("cr3bp", formulation="synodic", **EARTH_MOON)
    w = base.rotation_rate()
    out = {}
    for name in ("L1", "L4"):
        x, y = base.lagrange_points()[name]
        # inertial initial conditions of a particle at rest in the synodic frame
        m = base.with_values(**{"initial.x": x, "initial.y": y, "initial_rate.x": -w * y,
                                "initial_rate.y": w * x})
        r = mechsim.simulate(m, 20 * base.time_scale(), base.time_scale(), tolerance=1e-12)
        out[name] = np.max(np.hypot(r.q[:, 0] - x, r.q[:, 1] - y))
    assert out["L4"] < 1e-8
    assert out["L1"] > 1e-3  # round-off grows like e^{2.9 ω t}


def test_long_run_jacobi_drift() -> None:
    m = mechsim.load_system("cr3bp", **EARTH_MOON, **{"initial.x": -0.5, "initial.y": 0.5,
                                                     "initial_rate.x": -0.3,
                                                     "initial_rate.y": -0.5})
    r = mechsim.simulate(m, 100 * m.time_scale(), 0.1, tolerance=1e-12)
    J = r.invariants["jacobi"]
    assert np.ptp(J) / abs(J[0]) < 1e-8
    assert np.max(np.abs(r.balance_residual)) < 1e-8


def test_laws() -> None:
    keys = {f: [law.key for law in mechsim.load_system("cr3bp", formulation=f).laws()]
            for f in ("inertial", "synodic")}
    assert keys["inertial"] == ["work_balance", "invariant:jacobi"]
    assert keys["synodic"] == ["energy_function", "work_balance", "invariant:jacobi"]


def test_parameter_errors() -> None:
    with pytest.raises(ParameterError, match="^secondary_mass: must be > 0"):
        mechsim.load_system("cr3bp", secondary_mass=-1.0)
    with pytest.raises(ParameterError, match="^initial.x: .*primary"):
        mechsim.load_system("cr3bp", **{"initial.x": 0.1})
    with pytest.raises(ParameterError, match="^formulation:"):
        mechsim.load_system("cr3bp", formulation="rotating")
