"""Particle under V = x F(t) (“Energy and Hamiltonians: Part 3 – Examples”, Case 6): exact motion of
m ẍ = −F(t) (the document's sign is corrected), E = h, dE/dt = x Ḟ."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import quad

import mechsim
from mechsim.errors import ParameterError

PARAMS = {"mass": 1.5, "force_amplitude": 0.8, "force_rate": -0.6, "force_frequency": 1.7,
          "initial.x": 0.2, "initial_rate.x": 0.9}


def model(**kw):
    return mechsim.load_system("forced_particle", **{**PARAMS, **kw})


def sympy_profile(name: str, t: sp.Symbol) -> sp.Expr:
    F0, rate, w = sp.Rational(4, 5), -sp.Rational(3, 5), sp.Rational(17, 10)
    return {"constant": F0, "ramp": F0 + rate * t, "sinusoid": F0 * sp.sin(w * t)}[name]


@pytest.mark.parametrize("profile", ["constant", "ramp", "sinusoid"])
def test_exact_solution(profile: str) -> None:
    t = sp.Symbol("t", real=True)
    xf = sp.Function("x")
    m = sp.Rational(3, 2)
    F = sympy_profile(profile, t)
    L = m * xf(t).diff(t) ** 2 / 2 - xf(t) * F
    el = sp.diff(L.diff(xf(t).diff(t)), t) - L.diff(xf(t))
    assert sp.simplify(el - (m * xf(t).diff(t, 2) + F)) == 0  # m ẍ = −F, not +F (L545)
    sol = sp.dsolve(el, ics={xf(0): sp.Rational(1, 5), xf(t).diff(t).subs(t, 0):
                             sp.Rational(9, 10)}).rhs
    mod = model(force=profile)
    r = mechsim.simulate(mod, 10.0, 0.05, tolerance=1e-12)
    exact = sp.lambdify(t, sol, "numpy")(r.t) + 0 * r.t
    np.testing.assert_allclose(r.coordinate("x"), exact, atol=1e-9)
    np.testing.assert_allclose(mod.exact_solution(r.t)[0], exact, atol=1e-12)
    np.testing.assert_allclose(mod.exact_solution(r.t)[1],
                               sp.lambdify(t, sol.diff(t), "numpy")(r.t) + 0 * r.t,
                               atol=1e-12)
    np.testing.assert_allclose(r.observables["force_field"], mod.force_at(r.t), atol=1e-14)


@pytest.mark.parametrize("profile", ["ramp", "sinusoid"])
def test_energy_equals_h_and_power(profile: str) -> None:
    """E = h = ½mẋ² + xF(t) and E(t) − E(0) = ∫ x Ḟ dt (quadrature on the exact x)."""
    mod = model(force=profile)
    r = mechsim.simulate(mod, 8.0, 0.1, tolerance=1e-12)
    x, v = r.coordinate("x"), r.rate("x")
    E = 0.5 * 1.5 * v**2 + x * mod.force_at(r.t)
    np.testing.assert_allclose(r.total, E, atol=1e-12)
    np.testing.assert_allclose(r.energy_function, r.total, atol=1e-12)
    if profile == "ramp":
        def power(s: float) -> float:
            return float(mod.exact_solution(np.array(s))[0]) * -0.6
    else:
        def power(s: float) -> float:
            return float(mod.exact_solution(np.array(s))[0]) * 0.8 * 1.7 * np.cos(1.7 * s)
    for i in (10, 40, 80):
        W = quad(power, 0, r.t[i], epsabs=1e-13, epsrel=1e-12, limit=200)[0]
        assert r.total[i] - r.total[0] == pytest.approx(W, abs=1e-9)
        assert r.work_external[i] == pytest.approx(W, abs=1e-9)
    assert np.max(np.abs(r.balance_residual)) < 1e-10
    assert abs(np.ptp(r.total)) > 0.1  # not conserved
    assert [law.key for law in mod.laws()] == ["work_balance"]


def test_constant_force_conserves_energy() -> None:
    """With Ḟ = 0 the same system conserves E = h (a check of the power bookkeeping)."""
    r = mechsim.simulate(model(force="constant"), 20.0, 0.1, tolerance=1e-12)
    np.testing.assert_allclose(r.total, r.total[0], atol=1e-10)
    assert np.max(np.abs(r.work_external)) < 1e-10


def test_long_run_balance() -> None:
    mod = model(force="sinusoid")
    r = mechsim.simulate(mod, 500.0, 0.5, tolerance=1e-12)
    rel = np.max(np.abs(r.balance_residual)) / np.max(np.abs(r.total))
    assert rel < 1e-10
    np.testing.assert_allclose(r.coordinate("x"), mod.exact_solution(r.t)[0],
                               rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("field,value", [("force", "square"), ("mass", -1.0),
                                         ("force_frequency", -2.0)])
def test_parameter_validation(field: str, value: object) -> None:
    with pytest.raises(ParameterError) as err:
        model(**{field: value})
    assert err.value.field == field
