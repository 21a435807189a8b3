"""General small oscillations (PHYS0500 §8.3–8.4, Introduction to analytical mechanics, “Small
Oscillations”): frequencies and modes from the generalized eigenproblem, checked against sympy's
secular equation, the documented double pendulum (2 ± √2)g/l, the residuals (A − ω²M)a = 0 and
aᵀMa = I; the integrated motion against the matrix exponential of the first-order system; mode
energies conserved; a pure mode stays pure."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
import sympy as sp

import mechsim
from mechsim.errors import ParameterError

# the default 3 × 3 block, written out here
M3 = np.array([[2.0, 0.5, 0.0], [0.5, 1.5, 0.3], [0.0, 0.3, 1.0]])
A3 = np.array([[5.0, -2.0, 0.0], [-2.0, 6.0, -1.5], [0.0, -1.5, 4.0]])


def model(**kw):
    return mechsim.load_system("small_oscillations", **kw)


def params(M: np.ndarray, A: np.ndarray) -> dict[str, float]:
    n = M.shape[0]
    out: dict[str, float] = {"dimension": n}
    for j in range(n):
        for k in range(j, n):
            out[f"mass_matrix.m_{j + 1}{k + 1}"] = float(M[j, k])
            out[f"stiffness_matrix.k_{j + 1}{k + 1}"] = float(A[j, k])
    return out


def expm_solution(M: np.ndarray, A: np.ndarray, q0: np.ndarray, v0: np.ndarray,
                  t: np.ndarray) -> np.ndarray:
    n = M.shape[0]
    S = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, A), np.zeros((n, n))]])
    y0 = np.concatenate([q0, v0])
    return np.array([scipy.linalg.expm(S * tk) @ y0 for tk in t])


def test_matrices_from_the_upper_triangle() -> None:
    M, A = model().matrices()
    np.testing.assert_array_equal(M, M3)
    np.testing.assert_array_equal(A, A3)
    M2, _ = model(dimension=2).matrices()
    np.testing.assert_array_equal(M2, M3[:2, :2])


def test_double_pendulum_of_the_document() -> None:
    """001 §2.3/§2.21: T = ml²[[2, 1], [1, 1]], V = mgl[[2, 0], [0, 1]] (m = l = 1):
    |V − ω²T| = 0 gives ω² = (2 ± √2) g (sympy), and the mode shapes A₂ = ∓√2 A₁."""
    g = 9.81
    w2, gs = sp.symbols("omega2 g", positive=True)
    roots = sp.solve((sp.Matrix([[2 * gs, 0], [0, gs]]) - w2 * sp.Matrix([[2, 1], [1, 1]])).det(),
                     w2)
    expected = sorted(float(r.subs(gs, g)) for r in roots)
    assert expected == pytest.approx([(2 - math.sqrt(2)) * g, (2 + math.sqrt(2)) * g],
                                     rel=1e-14)
    mod = model(**params(np.array([[2.0, 1.0], [1.0, 1.0]]), np.diag([2 * g, g])))
    np.testing.assert_allclose(mod.frequencies() ** 2, expected, rtol=1e-13)
    a = mod.mode_shapes()
    np.testing.assert_allclose(a[1] / a[0], [math.sqrt(2), -math.sqrt(2)], rtol=1e-12)


@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_modes_solve_the_generalized_eigenproblem(n: int) -> None:
    rng = np.random.default_rng(n)
    B, C = rng.standard_normal((n, n)), rng.standard_normal((n, n))
    M, A = B @ B.T + n * np.eye(n), C @ C.T + 0.5 * np.eye(n)
    mod = model(**params(M, A))
    w, a = mod.frequencies(), mod.mode_shapes()
    assert np.all(np.diff(w) > 0)
    np.testing.assert_allclose(A @ a - M @ a * w**2, 0.0, atol=1e-12 * np.abs(A).max())
    np.testing.assert_allclose(a.T @ M @ a, np.eye(n), atol=1e-12)
    # each ω² is a root of the characteristic polynomial det(A − ω²M)
    for w2 in w**2:
        assert abs(np.linalg.det(A - w2 * M)) < 1e-9 * abs(np.linalg.det(A))
    # the exact modal solution is the matrix exponential of the first-order system
    q0, v0 = rng.standard_normal(n), rng.standard_normal(n)
    t = np.linspace(0.0, 7.0, 15)
    y0 = np.concatenate([q0, v0, [0.0, 0.0]])
    rows = mod.propagate(0.0, y0, t)
    np.testing.assert_allclose(rows[:, :2 * n], expm_solution(M, A, q0, v0, t), atol=1e-11)


@pytest.fixture(scope="module")
def run() -> mechsim.SimulationResult:
    return mechsim.simulate(model(**{"initial_rate.q_3": -0.2}), 30.0, 0.05,
                            tolerance=1e-13, method="dop853")


def test_motion_is_the_matrix_exponential(run: mechsim.SimulationResult) -> None:
    ref = expm_solution(M3, A3, np.array([0.1, 0.0, 0.0]), np.array([0.0, 0.0, -0.2]),
                        run.t[::20])
    np.testing.assert_allclose(run.q[::20], ref[:, :3], atol=1e-11)
    np.testing.assert_allclose(run.v[::20], ref[:, 3:], atol=1e-11)


def test_mode_energies(run: mechsim.SimulationResult) -> None:
    E = [run.invariants[f"mode_energy_{r}"] for r in (1, 2, 3)]
    for e in E:
        assert np.ptp(e) < 1e-10 * run.total[0]
    np.testing.assert_allclose(sum(E), run.total, rtol=1e-13)
    # normal coordinates: η = aᵀMq, each a free oscillation at its ω_r
    w, a = run.model.frequencies(), run.model.mode_shapes()
    eta0 = a.T @ M3 @ run.q[0]
    deta0 = a.T @ M3 @ run.v[0]
    for r in range(3):
        exact = eta0[r] * np.cos(w[r] * run.t) + deta0[r] / w[r] * np.sin(w[r] * run.t)
        np.testing.assert_allclose(run.observables[f"normal_coordinate_{r + 1}"], exact,
                                   atol=1e-11)


def test_pure_mode_stays_pure() -> None:
    base = model()
    a, w = base.mode_shapes(), base.frequencies()
    shape = 0.2 * a[:, 1] / np.max(np.abs(a[:, 1]))
    mod = model(**{f"initial.q_{j + 1}": float(shape[j]) for j in range(3)})
    run = mechsim.simulate(mod, 20.0, 0.1, tolerance=1e-13)
    np.testing.assert_allclose(run.q, np.cos(w[1] * run.t)[:, None] * shape, atol=1e-11)
    assert run.invariants["mode_energy_2"][0] == pytest.approx(run.total[0], rel=1e-13)
    for r in (1, 3):
        assert np.max(run.invariants[f"mode_energy_{r}"]) < 1e-25


def test_exact_method_matches_integration(run: mechsim.SimulationResult) -> None:
    x = mechsim.simulate(run.model, 30.0, 0.05, method="exact")
    np.testing.assert_allclose(x.q, run.q, atol=1e-11)


def test_long_run_conservation() -> None:
    mod = model(**{"initial_rate.q_2": 0.3})
    run = mechsim.simulate(mod, 3000.0, 0.5, tolerance=1e-13, method="yoshida8")
    e0 = run.total[0]
    assert np.max(np.abs(run.total - e0)) < 1e-10 * e0
    for r in (1, 2, 3):
        assert np.ptp(run.invariants[f"mode_energy_{r}"]) < 1e-9 * e0
    ref = expm_solution(M3, A3, np.array([0.1, 0.0, 0.0]), np.array([0.0, 0.3, 0.0]),
                        run.t[-3:])
    np.testing.assert_allclose(run.q[-3:], ref[:, :3], atol=1e-7)


@pytest.mark.parametrize("kw,field", [
    ({"mass_matrix.m_11": -1.0}, "mass_matrix"),
    ({"mass_matrix.m_12": 3.0}, "mass_matrix"),  # |M₁₂| > √(M₁₁M₂₂): indefinite
    ({"stiffness_matrix.k_33": 0.0, "stiffness_matrix.k_23": 0.0, "stiffness_matrix.k_22": 0.0},
     "stiffness_matrix"),
    ({"dimension": 2, "stiffness_matrix.k_13": 1.0}, "stiffness_matrix.k_13"),
    ({"dimension": 2, "initial.q_3": 0.5}, "initial.q_3"),
    ({"dimension": 5}, "dimension"), ({"dimension": 0}, "dimension")])
def test_parameter_validation(kw: dict, field: str) -> None:
    with pytest.raises(ParameterError) as err:
        model(**kw)
    assert err.value.field == field


def test_mode_energy_laws_are_scaled_by_the_total_energy() -> None:
    """Started in one mode, the others hold E_r ≈ 1e-33: their drift is measured against
    |T₀| + |V₀|, not against that round-off."""
    mod = model()
    scales = mod.law_scales()
    e = 0.5 * 0.1 * A3[0, 0] * 0.1  # V₀ = ½ A₁₁ q₁², T₀ = 0
    for r in (1, 2, 3):
        assert scales[f"invariant:mode_energy_{r}"] == pytest.approx(e, rel=1e-14)
