"""Double pendulum (Introduction to analytical mechanics, “Double pendulum”): equations (the L767
sign fixed), small-oscillation normal modes, E over long chaotic runs, angle and multiplier forms
and their rod tensions agree."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

import mechsim
from mechsim.errors import ParameterError

P = {"mass_1": 1.3, "mass_2": 0.7, "length_1": 0.9, "length_2": 1.4, "gravity": 9.81}


def model(formulation: str = "angles", **kw):
    return mechsim.load_system("double_pendulum", formulation=formulation, **{**P, **kw})


def test_equations_of_motion_and_document_sign() -> None:
    """sympy: the catalog's final equations are the EL equations of the document's L, and
    with equal masses and lengths the θ̇₂² term is +l θ̇₂² sin(θ₁ − θ₂) (L767 prints −)."""
    t = sp.Symbol("t")
    m1, m2, l1, l2, g = sp.symbols("m1 m2 l1 l2 g", positive=True)
    t1, t2 = sp.Function("theta1")(t), sp.Function("theta2")(t)
    d1, d2 = t1.diff(t), t2.diff(t)
    T = (m1 * l1**2 * d1**2 / 2
         + m2 * (l1**2 * d1**2 + l2**2 * d2**2 + 2 * l1 * l2 * d1 * d2 * sp.cos(t1 - t2)) / 2)
    V = m1 * g * (l1 + l2 - l1 * sp.cos(t1)) + m2 * g * (l1 + l2 - l1 * sp.cos(t1)
                                                          - l2 * sp.cos(t2))
    L = T - V

    def el(q):
        return sp.diff(L.diff(q.diff(t)), t) - L.diff(q)

    eq1 = ((m1 + m2) * l1**2 * t1.diff(t, 2) + m2 * l1 * l2 * t2.diff(t, 2) * sp.cos(t1 - t2)
           + m2 * l1 * l2 * d2**2 * sp.sin(t1 - t2) + (m1 + m2) * g * l1 * sp.sin(t1))
    eq2 = (m2 * l2**2 * t2.diff(t, 2) + m2 * l1 * l2 * t1.diff(t, 2) * sp.cos(t1 - t2)
           - m2 * l1 * l2 * d1**2 * sp.sin(t1 - t2) + m2 * g * l2 * sp.sin(t2))
    assert sp.simplify(el(t1) - eq1) == 0
    assert sp.simplify(el(t2) - eq2) == 0
    m, l = sp.symbols("m l", positive=True)
    same = {m1: m, m2: m, l1: l, l2: l}
    fixed = (2 * l * t1.diff(t, 2) + l * t2.diff(t, 2) * sp.cos(t1 - t2)
             + l * d2**2 * sp.sin(t1 - t2) + 2 * g * sp.sin(t1))
    printed = fixed - 2 * l * d2**2 * sp.sin(t1 - t2)  # L767's sign
    assert sp.simplify(el(t1).subs(same) / (m * l) - fixed) == 0
    assert sp.simplify(el(t1).subs(same) / (m * l) - printed) != 0


def reference(y0: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Hand-typed catalog equations (general masses), integrated by scipy at rtol 1e-12."""
    m1, m2, l1, l2, g = (P[k] for k in ("mass_1", "mass_2", "length_1", "length_2", "gravity"))

    def f(_t: float, y: np.ndarray) -> list[float]:
        a, b, wa, wb = y
        c, s = math.cos(a - b), math.sin(a - b)
        M = np.array([[(m1 + m2) * l1**2, m2 * l1 * l2 * c], [m2 * l1 * l2 * c, m2 * l2**2]])
        rhs = np.array([-m2 * l1 * l2 * wb**2 * s - (m1 + m2) * g * l1 * math.sin(a),
                        m2 * l1 * l2 * wa**2 * s - m2 * g * l2 * math.sin(b)])
        acc = np.linalg.solve(M, rhs)
        return [wa, wb, acc[0], acc[1]]

    sol = solve_ivp(f, (t[0], t[-1]), y0, method="DOP853", t_eval=t, rtol=1e-12, atol=1e-13)
    return sol.y.T


def test_against_independent_integration() -> None:
    kw = {"initial.angle_1": 0.9, "initial.angle_2": -0.4, "initial_rate.angle_2": 1.0}
    r = mechsim.simulate(model(**kw), 5.0, 0.05, tolerance=1e-13)
    ref = reference(np.array([0.9, -0.4, 0.0, 1.0]), r.t)
    np.testing.assert_allclose(r.q, ref[:, :2], atol=1e-8)
    np.testing.assert_allclose(r.v, ref[:, 2:], atol=1e-7)


def test_formulations_and_tensions_agree() -> None:
    a = mechsim.simulate(model("angles"), 3.0, 0.05, tolerance=1e-13)
    b = mechsim.simulate(model("multiplier"), 3.0, 0.05, tolerance=1e-13)
    for k in ("angle_1", "angle_2"):
        np.testing.assert_allclose(np.unwrap(b.observables[k]), a.coordinate(k), atol=1e-6)
    for k in ("tension_1", "tension_2"):
        np.testing.assert_allclose(a.observables[k], b.observables[k], atol=1e-5)
    np.testing.assert_allclose(a.total, b.total, rtol=1e-10)
    assert np.max(np.abs(b.invariants["constraint_rod_1"])) < 1e-12
    assert np.max(np.abs(b.invariants["constraint_rod_2"])) < 1e-12


def test_hanging_at_rest_tensions() -> None:
    r = mechsim.simulate(model(**{"initial.angle_1": 0.0, "initial.angle_2": 0.0}), 1.0, 0.5)
    np.testing.assert_allclose(r.observables["tension_2"], 0.7 * 9.81, rtol=1e-12)
    np.testing.assert_allclose(r.observables["tension_1"], 2.0 * 9.81, rtol=1e-12)
    # V's zero is l₁ + l₂ below the pivot for both bobs (document L738): V = m₁ g l₂ here
    np.testing.assert_allclose(r.total, 1.3 * 9.81 * 1.4, rtol=1e-14)


def test_small_oscillation_modes() -> None:
    """Equal masses and lengths: ω² = (2 ∓ √2) g/l, A₂/A₁ = ±√2 (L772–805); a small start
    in the slow mode stays single-frequency. General masses: |V − ω²T| = 0 by sympy."""
    g, l = 9.81, 0.8
    eq = model(mass_1=1.0, mass_2=1.0, length_1=l, length_2=l)
    w = eq.small_oscillation_frequencies()
    np.testing.assert_allclose(w**2, [(2 - math.sqrt(2)) * g / l, (2 + math.sqrt(2)) * g / l],
                               rtol=1e-13)
    np.testing.assert_allclose(eq.mode_ratios(), [math.sqrt(2), -math.sqrt(2)], rtol=1e-12)
    w2 = sp.Symbol("w2")
    m1, m2, l1, l2 = (sp.nsimplify(P[k]) for k in ("mass_1", "mass_2", "length_1", "length_2"))
    G = sp.nsimplify(9.81)
    Tm = sp.Matrix([[(m1 + m2) * l1**2, m2 * l1 * l2], [m2 * l1 * l2, m2 * l2**2]])
    Vm = sp.diag((m1 + m2) * G * l1, m2 * G * l2)
    roots = sorted(float(x) for x in sp.solve((Vm - w2 * Tm).det(), w2))
    np.testing.assert_allclose(model().small_oscillation_frequencies() ** 2, roots, rtol=1e-12)
    th = 1e-4
    mod = eq.with_values(**{"initial.angle_1": th, "initial.angle_2": math.sqrt(2) * th})
    r = mechsim.simulate(mod, 3 * 2 * math.pi / w[0], 0.01, tolerance=1e-13)
    np.testing.assert_allclose(r.coordinate("angle_1"), th * np.cos(w[0] * r.t), atol=th * 1e-6)
    np.testing.assert_allclose(r.coordinate("angle_2"), math.sqrt(2) * th * np.cos(w[0] * r.t),
                               atol=th * 1e-6)


def test_long_chaotic_run_conserves_energy() -> None:
    r = mechsim.simulate(model(), 200.0, 0.1, tolerance=1e-12)
    E = r.total
    assert np.ptp(r.coordinate("angle_2")) > 2 * math.pi  # it flips: chaotic regime
    assert np.max(np.abs(E - E[0])) / E[0] < 2e-9
    np.testing.assert_allclose(r.energy_function, E, rtol=1e-12)
    assert np.max(np.abs(r.balance_residual)) < 1e-8


def test_frames() -> None:
    assert [(f.child, f.parent, f.static) for f in model().frames] == [
        ("pivot", "world", True), ("bob_1", "pivot", False), ("bob_2", "bob_1", False)]
    r = mechsim.simulate(model(), 1.0, 0.5)
    fr = r.outputs.frames[-1]
    # bob_2's world position = bob_1 + R_x(θ₁)·(relative translation) = p₂
    t1, t2 = r.q[-1]
    c, s = math.cos(t1), math.sin(t1)
    y2 = fr[1, 1] + c * fr[2, 1] - s * fr[2, 2]
    z2 = fr[1, 2] + s * fr[2, 1] + c * fr[2, 2]
    assert y2 == pytest.approx(0.9 * math.sin(t1) + 1.4 * math.sin(t2), abs=1e-12)
    assert z2 == pytest.approx(-0.9 * math.cos(t1) - 1.4 * math.cos(t2), abs=1e-12)


@pytest.mark.parametrize("kw,field", [({"mass_2": 0.0}, "mass_2"),
                                      ({"initial.angle_1": 3.5}, "initial.angle_1"),
                                      ({"formulation": "euler_angles"}, "formulation")])
def test_parameter_validation(kw: dict, field: str) -> None:
    with pytest.raises(ParameterError) as err:
        model(**kw)
    assert err.value.field == field
