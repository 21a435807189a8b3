"""Motor-driven rotating spring (“Energy and Hamiltonians: Part 3 – Examples”, Case 4): h_r
conserved, E not, E − h_r = mr²ω², motor work balance, multiplier = motor torque, co-rotating
frame."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import mechsim
from mechsim.errors import ParameterError

P = {"mass": 1.5, "spring_constant": 6.0, "rest_length": 0.8, "angular_velocity": 1.2,
     "initial.r": 1.1, "initial_rate.r": 0.3, "initial.theta": 0.4}


def model(formulation: str = "reduced", **kw):
    return mechsim.load_system("rotating_spring", formulation=formulation, **{**P, **kw})


def test_radial_equation_and_solution() -> None:
    """sympy: EL of L = ½m(ṙ² + r²ω²) − ½k(r − ℓ₀)² and its solution with the given ICs."""
    t = sp.Symbol("t", real=True)
    m, k, l0, w = sp.Rational(3, 2), 6, sp.Rational(4, 5), sp.Rational(6, 5)
    r = sp.Function("r")
    L = m * (r(t).diff(t) ** 2 + r(t) ** 2 * w**2) / 2 - k * (r(t) - l0) ** 2 / 2
    el = sp.diff(L.diff(r(t).diff(t)), t) - L.diff(r(t))
    w0sq = sp.Rational(k) / m
    assert sp.simplify(el / m - (r(t).diff(t, 2) - (w**2 - w0sq) * r(t) - w0sq * l0)) == 0
    sol = sp.dsolve(el, ics={r(0): sp.Rational(11, 10),
                             r(t).diff(t).subs(t, 0): sp.Rational(3, 10)}).rhs
    mod = model()
    assert mod.equilibrium_radius() == pytest.approx(float(w0sq * l0 / (w0sq - w**2)),
                                                     rel=1e-15)
    ts = np.linspace(0, 10, 41)
    np.testing.assert_allclose(mod.exact_radius(ts)[0],
                               sp.lambdify(t, sol, "numpy")(ts), atol=1e-12)


@pytest.mark.parametrize("formulation", ["reduced", "multiplier"])
def test_energy_function_and_motor_work(formulation: str) -> None:
    mod = model(formulation)
    r = mechsim.simulate(mod, 20.0, 0.05, tolerance=1e-12)
    rr, rd = mod.exact_radius(r.t)
    np.testing.assert_allclose(r.coordinate("r"), rr, atol=1e-9)
    m, k, l0, w = 1.5, 6.0, 0.8, 1.2
    E = 0.5 * m * (rd**2 + rr**2 * w**2) + 0.5 * k * (rr - l0) ** 2
    h_r = 0.5 * m * (rd**2 - rr**2 * w**2) + 0.5 * k * (rr - l0) ** 2
    np.testing.assert_allclose(r.total, E, atol=1e-9)
    if formulation == "reduced":
        h = r.energy_function
    else:
        h = r.invariants["reduced_energy_function"]
        np.testing.assert_allclose(r.energy_function, r.total, atol=1e-12)
        assert np.max(np.abs(r.invariants["constraint_motor"])) < 1e-12
        np.testing.assert_allclose(r.coordinate("theta"), 0.4 + w * r.t, atol=1e-11)
    np.testing.assert_allclose(h, h_r, atol=1e-9)
    assert np.ptp(h) < 1e-9 and np.ptp(r.total) > 0.1
    np.testing.assert_allclose(r.total - h, m * r.coordinate("r") ** 2 * w**2, atol=1e-9)
    # motor work ∫τω dt = mω²(r² − r₀²), torque τ = 2 m r ṙ ω
    np.testing.assert_allclose(r.work_external, m * w**2 * (rr**2 - 1.1**2), atol=1e-9)
    np.testing.assert_allclose(r.observables["motor_torque"], 2 * m * rr * rd * w, atol=1e-8)
    assert np.max(np.abs(r.balance_residual)) < 1e-9


def test_formulations_agree_and_frames() -> None:
    a = mechsim.simulate(model("reduced"), 15.0, 0.1, tolerance=1e-12)
    b = mechsim.simulate(model("multiplier"), 15.0, 0.1, tolerance=1e-12)
    np.testing.assert_allclose(a.coordinate("r"), b.coordinate("r"), atol=1e-9)
    np.testing.assert_allclose(a.observables["motor_torque"], b.observables["motor_torque"],
                               atol=1e-8)
    np.testing.assert_allclose(a.outputs.frames, b.outputs.frames, atol=1e-9)
    # co-rotating frame: yaw θ₀ + ωt about world z
    yaw = 2 * np.arctan2(a.outputs.frames[:, 0, 5], a.outputs.frames[:, 0, 6])
    np.testing.assert_allclose(np.cos(yaw), np.cos(0.4 + 1.2 * a.t), atol=1e-12)
    assert [(f.child, f.parent, f.static) for f in model().frames] == [
        ("rotating_frame", "world", False), ("mass", "rotating_frame", False)]


def test_catalog_run() -> None:
    """Catalog 000 S7 run (m = 1, k = 4, ℓ₀ = 1, ω = 1, r₀ = 1, ṙ₀ = 0): r_eq = 4/3, E varies
    by 16/9 peak to peak (E − h_r = r²: r oscillates in [1, 5/3])."""
    mod = mechsim.load_system("rotating_spring")
    assert mod.equilibrium_radius() == pytest.approx(4 / 3, rel=1e-15)
    r = mechsim.simulate(mod, 2 * math.pi / math.sqrt(3), 1e-3, tolerance=1e-12)
    assert np.ptp(r.total) == pytest.approx(25 / 9 - 1, rel=1e-6)


def test_laws() -> None:
    assert [law.key for law in model("reduced").laws()] == ["energy_function", "work_balance"]
    assert [law.key for law in model("multiplier").laws()] == [
        "work_balance", "invariant:reduced_energy_function", "constraint:constraint_motor"]


def test_supercritical_drive_runs_away() -> None:
    mod = model(angular_velocity=2.5)  # ω > ω₀ = 2
    r = mechsim.simulate(mod, 3.0, 0.05, tolerance=1e-12)
    np.testing.assert_allclose(r.coordinate("r"), mod.exact_radius(r.t)[0], rtol=1e-9)


def test_long_run() -> None:
    r = mechsim.simulate(model("reduced"), 1000.0, 0.5, tolerance=1e-12)
    assert np.ptp(r.energy_function) / abs(r.energy_function[0]) < 1e-8
    assert np.max(np.abs(r.balance_residual)) < 1e-8


@pytest.mark.parametrize("field,value", [("initial.r", 0.0), ("rest_length", -1.0),
                                         ("formulation", "cartesian")])
def test_parameter_validation(field: str, value: object) -> None:
    with pytest.raises(ParameterError) as err:
        model(**{field: value})
    assert err.value.field == field
