"""Atwood machine and compound wheel (Introduction to analytical mechanics, “Atwood's machine –
equation of motion Lagrangian” and “Conditions of balance”): acceleration and string tensions
(multipliers), massive pulley, equilibrium m₁R₁ = m₂R₂."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import mechsim
from mechsim.errors import ParameterError

WHEEL = {"mass_1": 1.5, "mass_2": 2.5, "radius_1": 0.3, "radius_2": 0.12,
         "pulley_inertia": 0.04, "gravity": 9.81, "initial_rate.angle": -0.5}


def model(formulation: str = "reduced", **kw):
    return mechsim.load_system("atwood", formulation=formulation, **kw)


def newton(m1: float, m2: float, R1: float, R2: float, I: float, g: float):
    """Free bodies (z up): m₁z̈₁ = T₁ − m₁g, m₂z̈₂ = T₂ − m₂g, Iφ̈ = T₁R₁ − T₂R₂, with
    z̈₁ = −R₁φ̈, z̈₂ = R₂φ̈ — a linear solve for (φ̈, T₁, T₂), independent of the Lagrangian."""
    A = np.array([[-m1 * R1, -1.0, 0.0], [m2 * R2, 0.0, -1.0], [I, -R1, R2]])
    phi_dd, T1, T2 = np.linalg.solve(A, np.array([-m1 * g, -m2 * g, 0.0]))
    return phi_dd, T1, T2


def test_newton_and_lagrangian_agree() -> None:
    """sympy: EL of the wheel L gives φ̈ = g(m₁R₁ − m₂R₂)/(I + m₁R₁² + m₂R₂²); the document's
    Atwood L gives ẍ = (M₁ − M₂)g/(M₁ + M₂)."""
    t = sp.Symbol("t")
    m1, m2, R1, R2, I, g, l = sp.symbols("m1 m2 R1 R2 I g l", positive=True)
    phi = sp.Function("phi")(t)
    L = (I + m1 * R1**2 + m2 * R2**2) * phi.diff(t) ** 2 / 2 - g * (
        m1 * (-R1 * phi) + m2 * (R2 * phi))
    el = sp.diff(L.diff(phi.diff(t)), t) - L.diff(phi)
    acc = sp.solve(el, phi.diff(t, 2))[0]
    assert sp.simplify(acc - g * (m1 * R1 - m2 * R2) / (I + m1 * R1**2 + m2 * R2**2)) == 0
    x = sp.Function("x")(t)
    La = (m1 + m2) * x.diff(t) ** 2 / 2 + m1 * g * x + m2 * g * (l - x)
    ela = sp.diff(La.diff(x.diff(t)), t) - La.diff(x)
    assert sp.simplify(sp.solve(ela, x.diff(t, 2))[0] - (m1 - m2) * g / (m1 + m2)) == 0
    mod = model(**WHEEL)
    a, T1, T2 = newton(1.5, 2.5, 0.3, 0.12, 0.04, 9.81)
    vals = {m1: 1.5, m2: 2.5, R1: 0.3, R2: 0.12, I: 0.04, g: 9.81}
    assert mod.angular_acceleration() == pytest.approx(float(acc.subs(vals)), rel=1e-14)
    assert a == pytest.approx(float(acc.subs(vals)), rel=1e-12)
    assert mod.tensions() == pytest.approx((T1, T2), rel=1e-12)


@pytest.mark.parametrize("formulation", ["reduced", "multiplier"])
def test_compound_wheel_motion_and_tensions(formulation: str) -> None:
    mod = model(formulation, **WHEEL)
    a, T1, T2 = newton(1.5, 2.5, 0.3, 0.12, 0.04, 9.81)
    r = mechsim.simulate(mod, 3.0, 0.05, tolerance=1e-12)
    np.testing.assert_allclose(r.coordinate("angle"), -0.5 * r.t + 0.5 * a * r.t**2,
                               atol=1e-10)
    np.testing.assert_allclose(mod.angle_at(r.t), -0.5 * r.t + 0.5 * a * r.t**2, atol=1e-12)
    np.testing.assert_allclose(r.observables["tension_1"], T1, rtol=1e-10)
    np.testing.assert_allclose(r.observables["tension_2"], T2, rtol=1e-10)
    np.testing.assert_allclose(r.observables["net_torque"], 0.04 * a, atol=1e-9)
    np.testing.assert_allclose(r.total, r.total[0], atol=1e-10)
    assert np.max(np.abs(r.balance_residual)) < 1e-10
    if formulation == "multiplier":
        np.testing.assert_allclose(r.coordinate("z_1"), -1.0 - 0.3 * r.coordinate("angle"),
                                   atol=1e-12)
        assert np.max(np.abs(r.invariants["constraint_string_2"])) < 1e-13


@pytest.mark.parametrize("formulation", ["reduced", "multiplier"])
def test_classic_atwood(formulation: str) -> None:
    """R₁ = R₂, I = 0: the document's x (string on M₁'s side) has ẍ = (M₁ − M₂)g/(M₁ + M₂),
    the tension is 2M₁M₂g/(M₁ + M₂)."""
    M1, M2, g = 3.0, 1.2, 9.81
    mod = model(formulation, mass_1=M1, mass_2=M2, radius_1=0.25, radius_2=0.25)
    r = mechsim.simulate(mod, 2.0, 0.1, tolerance=1e-12)
    x = r.observables["string_length_1"]
    np.testing.assert_allclose(x, 1.0 + 0.5 * (M1 - M2) / (M1 + M2) * g * r.t**2, atol=1e-10)
    T = 2 * M1 * M2 * g / (M1 + M2)
    np.testing.assert_allclose(r.observables["tension_1"], T, rtol=1e-10)
    np.testing.assert_allclose(r.observables["tension_2"], T, rtol=1e-10)


@pytest.mark.parametrize("formulation", ["reduced", "multiplier"])
def test_balance_condition(formulation: str) -> None:
    """m₁R₁ = m₂R₂ (L409) with unequal radii: the wheel stays put, T_i = m_i g, T₁R₁ = T₂R₂."""
    mod = model(formulation, mass_1=1.0, mass_2=2.5, radius_1=0.25, radius_2=0.1,
                pulley_inertia=0.01, **{"initial.angle": 0.3})
    assert mod.is_balanced()
    assert not model(mass_1=1.0, mass_2=2.4, radius_1=0.25, radius_2=0.1).is_balanced()
    r = mechsim.simulate(mod, 5.0, 0.5, tolerance=1e-12)
    np.testing.assert_allclose(r.coordinate("angle"), 0.3, atol=1e-12)
    np.testing.assert_allclose(r.observables["tension_1"], 9.81, rtol=1e-12)
    np.testing.assert_allclose(r.observables["tension_2"], 2.5 * 9.81, rtol=1e-12)
    np.testing.assert_allclose(r.observables["net_torque"], 0.0, atol=1e-12)


def test_long_run_energy() -> None:
    mod = model("multiplier", **WHEEL)
    r = mechsim.simulate(mod, 30.0, 0.1, tolerance=1e-12)
    scale = np.max(np.abs(r.kinetic))
    assert np.max(np.abs(r.total - r.total[0])) / scale < 1e-11
    np.testing.assert_allclose(r.energy_function, r.total, rtol=1e-12, atol=1e-9)


def test_frames() -> None:
    mod = model()
    assert [(f.child, f.parent, f.static) for f in mod.frames] == [
        ("axle", "world", True), ("wheel", "axle", False), ("drum_1_tangent", "axle", True),
        ("drum_2_tangent", "axle", True), ("mass_1", "axle", False), ("mass_2", "axle", False)]


@pytest.mark.parametrize("kw,field", [({"radius_1": 0.0}, "radius_1"),
                                      ({"pulley_inertia": -0.1}, "pulley_inertia"),
                                      ({"mass_2": "heavy"}, "mass_2")])
def test_parameter_validation(kw: dict, field: str) -> None:
    with pytest.raises(ParameterError) as err:
        model(**kw)
    assert err.value.field == field
