"""N coupled oscillators (PHYS0500 ch. 8, Introduction to analytical mechanics, “Small
Oscillations”): normal modes from |A − ω²M| = 0, modal solution, conserved mode energies, beats and
the transfer time."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg
import sympy as sp

import mechsim
from mechsim.errors import ParameterError


def model(**kw):
    return mechsim.load_system("coupled_oscillators", **kw)


def matrices(n: int, m: float, k: float, kc: float) -> tuple[np.ndarray, np.ndarray]:
    """A and M typed from the forces −κx_j − κ₁₂(x_j − x_{j±1}) (independent of the code)."""
    A = np.zeros((n, n))
    for j in range(n):
        A[j, j] = k
        for i in (j - 1, j + 1):
            if 0 <= i < n:
                A[j, j] += kc
                A[j, i] -= kc
    return A, m * np.eye(n)


def test_two_oscillator_secular_equation() -> None:
    """sympy: |A − ω²M| = 0 for the document's pair gives ω² = κ/M and (κ + 2κ₁₂)/M (8.2),
    with symmetric and antisymmetric modes."""
    w2, M, k, kc = sp.symbols("omega2 M kappa kappa12", positive=True)
    A = sp.Matrix([[k + kc, -kc], [-kc, k + kc]])
    roots = sp.solve((A - w2 * M * sp.eye(2)).det(), w2)
    assert {sp.simplify(r) for r in roots} == {k / M, (k + 2 * kc) / M}
    mod = model(mass=2.0, spring_constant=3.0, coupling_constant=0.5)
    np.testing.assert_allclose(mod.mode_frequencies() ** 2, [1.5, 2.0], rtol=1e-15)
    u = mod.mode_shapes()
    np.testing.assert_allclose(np.abs(u), np.full((2, 2), 1 / math.sqrt(2)), rtol=1e-15)
    assert u[0, 0] * u[0, 1] > 0 and u[1, 0] * u[1, 1] < 0


@pytest.mark.parametrize("n", [1, 3, 4, 7])
def test_closed_form_modes_match_generalized_eigenproblem(n: int) -> None:
    m, k, kc = 1.3, 2.1, 0.7
    A, M = matrices(n, m, k, kc)
    w2, a = scipy.linalg.eigh(A, M)
    mod = model(count=n, mass=m, spring_constant=k, coupling_constant=kc)
    np.testing.assert_allclose(mod.mode_frequencies() ** 2, w2, rtol=1e-13)
    u = mod.mode_shapes()
    np.testing.assert_allclose(u @ M @ u.T / m, np.eye(n), atol=1e-14)  # M-orthogonal
    np.testing.assert_allclose(np.abs(u @ M @ a / math.sqrt(m)), np.eye(n), atol=1e-12)


def test_modal_solution_and_mode_energies() -> None:
    mod = model(count=4, mass=1.3, spring_constant=2.1, coupling_constant=0.7)
    r = mechsim.simulate(mod, 20.0, 0.05, tolerance=1e-12, method="dop853")
    # exact solution independent of the model: expm of the first-order system
    A, M = matrices(4, 1.3, 2.1, 0.7)
    S = np.block([[np.zeros((4, 4)), np.eye(4)], [-np.linalg.solve(M, A), np.zeros((4, 4))]])
    y0 = np.concatenate(mod.initial_state())
    ref = np.array([scipy.linalg.expm(S * t) @ y0 for t in r.t[::40]])
    np.testing.assert_allclose(r.q[::40], ref[:, :4], atol=1e-10)
    np.testing.assert_allclose(mod.exact_solution(r.t), r.q, atol=1e-10)
    E = sum(r.invariants[f"mode_energy_{i}"] for i in range(1, 5))
    np.testing.assert_allclose(E, r.total, rtol=1e-12)
    for i in range(1, 5):
        assert np.ptp(r.invariants[f"mode_energy_{i}"]) < 1e-10
    own = sum(r.observables[f"oscillator_energy_{j}"] for j in range(1, 5))
    np.testing.assert_allclose(own + r.observables["coupling_energy"], r.total, rtol=1e-12)


def test_pure_mode_stays_pure() -> None:
    mod = model(count=4, **{"initial.mode": 3}, coupling_constant=1.0)
    r = mechsim.simulate(mod, 10.0, 0.1, tolerance=1e-12)
    assert r.invariants["mode_energy_3"][0] == pytest.approx(r.total[0], rel=1e-14)
    for i in (1, 2, 4):
        assert np.max(r.invariants[f"mode_energy_{i}"]) < 1e-20
    # every coordinate oscillates at ω₃ with a fixed shape
    w3 = mod.mode_frequencies()[2]
    np.testing.assert_allclose(r.q, np.cos(w3 * r.t)[:, None] * r.q[0], atol=1e-10)


def test_beats_and_transfer_time() -> None:
    """x₁(0) = D: x₁ = (D/2)(cos ω₁t + cos ω₂t), x₂ = (D/2)(cos ω₂t − cos ω₁t); the envelope
    of x₁ vanishes at t* = π/(ω₁ − ω₂) ≈ π/(2εω₀): x₁ = 0 and ẋ₁ = −DΔ cos(Σt*) with
    Σ, Δ = (ω₁ ± ω₂)/2, so mass 1 keeps only an O(ε²) share of the energy."""
    k, kc, m, D = 4.0, 0.2, 1.0, 0.3
    mod = model(spring_constant=k, coupling_constant=kc, mass=m, **{"initial.amplitude": D})
    wa, ws = math.sqrt((k + 2 * kc) / m), math.sqrt(k / m)
    t_star = math.pi / (wa - ws)
    assert mod.transfer_time() == pytest.approx(t_star, rel=1e-14)
    eps = kc / (2 * k)
    w0 = math.sqrt((k + kc) / m)
    assert mod.transfer_time(approximate=True) == pytest.approx(math.pi / (2 * eps * w0),
                                                                rel=1e-14)
    assert mod.transfer_time(approximate=True) == pytest.approx(t_star, rel=2 * eps)
    r = mechsim.simulate(mod, 2 * t_star, 2 * t_star / 4000, tolerance=1e-12)
    np.testing.assert_allclose(r.coordinate("x_1"),
                               D / 2 * (np.cos(wa * r.t) + np.cos(ws * r.t)), atol=1e-10)
    np.testing.assert_allclose(r.coordinate("x_2"),
                               D / 2 * (np.cos(ws * r.t) - np.cos(wa * r.t)), atol=1e-10)
    end = mechsim.simulate(mod, t_star, t_star, tolerance=1e-12)
    x1, v1 = end.q[-1, 0], end.v[-1, 0]
    Sg, Dl = (wa + ws) / 2, (wa - ws) / 2
    assert abs(x1) < 1e-10
    assert v1 == pytest.approx(-D * Dl * math.cos(Sg * t_star), abs=1e-10)
    E1 = end.observables["oscillator_energy_1"]
    E2 = end.observables["oscillator_energy_2"]
    assert E1[0] == pytest.approx(0.5 * k * D**2, rel=1e-14)
    assert E1[-1] < 0.5 * m * (D * Dl) ** 2 + 1e-15
    assert E1[-1] < eps**2 * E1[0]
    assert E2[-1] > (1 - 2 * eps) * E1[0]


def test_long_run_conservation() -> None:
    mod = model(count=4)
    r = mechsim.simulate(mod, 3000.0, 0.5, tolerance=1e-14)
    assert r.method == "radau15"  # auto at 1e-14: the machine-precision method
    rel = np.abs(r.total / r.total[0] - 1)
    assert rel.max() < 1e-9
    for i in (1, 2, 3, 4):
        e = r.invariants[f"mode_energy_{i}"]
        assert np.ptp(e) < 1e-9 * r.total[0]


def test_frames() -> None:
    mod = model(count=3)
    assert [(f.child, f.parent, f.static) for f in mod.frames] == [
        ("chain", "world", True), ("anchor_1", "chain", True), ("anchor_2", "chain", True),
        ("anchor_3", "chain", True), ("mass_1", "chain", False), ("mass_2", "chain", False),
        ("mass_3", "chain", False)]


@pytest.mark.parametrize("kw,field", [({"count": 0}, "count"), ({"count": 2.5}, "count"),
                                      ({"count": 13}, "count"),
                                      ({"count": 3, "initial.mode": 4}, "initial.mode"),
                                      ({"coupling_constant": -1.0}, "coupling_constant")])
def test_parameter_validation(kw: dict, field: str) -> None:
    with pytest.raises(ParameterError) as err:
        model(**kw)
    assert err.value.field == field


@pytest.mark.parametrize("n", [1, 2, 5, 12])
def test_closed_form_against_matrix_exponential_and_radau15(n: int) -> None:
    """``propagate`` from an arbitrary state at t₀ ≠ 0 equals exp(K (t − t₀)) y₀ of the
    first-order system K = [[0, 1], [−M⁻¹A, 0]] (A, M typed from the forces) to 1e-13 over a
    time scale (further on, scipy's expm itself drifts by ~1e-13: ‖K t‖ grows), and the exact
    method agrees with radau15 at 1e-14 to 1e-13 over ten time scales."""
    from mechsim.integrators import make_stepper

    mod = model(count=n, mass=1.3, spring_constant=3.0, coupling_constant=0.7)
    A, M = matrices(n, 1.3, 3.0, 0.7)
    K = np.zeros((2 * n, 2 * n))
    K[:n, n:] = np.eye(n)
    K[n:, :n] = -np.linalg.solve(M, A)
    rng = np.random.default_rng(n)
    y0 = np.concatenate([rng.normal(size=2 * n), [0.25, -0.5]])
    t0, t = 1.7, 1.7 + np.linspace(0.0, mod.time_scale(), 7)
    rows = mod.propagate(t0, y0, t)
    ref = np.array([scipy.linalg.expm(K * (s - t0)) @ y0[:2 * n] for s in t])
    assert np.max(np.abs(rows[:, :2 * n] - ref)) < 1e-13 * np.max(np.abs(ref))
    assert np.all(rows[:, 2 * n:] == y0[2 * n:])  # nothing works on the chain
    assert mod.has_closed_form()
    ts = (np.linspace(0.0, 10.0, 11)[1:] - 0.37) * mod.time_scale()  # not at whole periods
    exact = make_stepper(mod, "auto", closed_form=True)
    assert exact.method == "exact"
    E, R = exact.advance(ts), make_stepper(mod, "radau15", 1e-14).advance(ts)
    for part in (slice(0, n), slice(n, 2 * n)):
        assert np.max(np.abs(E[:, part] - R[:, part])) < 1e-13 * np.max(np.abs(R[:, part]))
