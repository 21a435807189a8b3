"""Simple harmonic oscillator (PHYS0500 §1.1, Introduction to analytical mechanics, “Conservation of
energy”): exact solution, E = h, and the period averages ⟨T⟩ = ⟨V⟩ = E/2."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import mechsim
from mechsim.errors import ParameterError


def model(**kw):
    return mechsim.load_system("harmonic_oscillator", **kw)


def test_oracle_solves_the_equation_of_motion() -> None:
    """x(t) = x₀cos ω₀t + (v₀/ω₀)sin ω₀t solves m ẍ = −kx (sympy dsolve, independent)."""
    t, m, k, x0, v0 = sp.symbols("t m k x0 v0", positive=True)
    x = sp.Function("x")
    sol = sp.dsolve(m * x(t).diff(t, 2) + k * x(t), ics={x(0): x0, x(t).diff(t).subs(t, 0): v0})
    w = sp.sqrt(k / m)
    assert sp.simplify(sol.rhs - (x0 * sp.cos(w * t) + v0 / w * sp.sin(w * t))) == 0
    mod = model(mass=2.0, spring_constant=3.0, **{"initial.x": 0.3, "initial_rate.x": -0.7})
    ts = np.linspace(0, 5, 7)
    f = sp.lambdify(t, sol.rhs.subs({m: 2, k: 3, x0: sp.Rational(3, 10),
                                      v0: -sp.Rational(7, 10)}), "numpy")
    np.testing.assert_allclose(mod.exact_solution(ts)[0], f(ts), rtol=0, atol=1e-14)


@pytest.mark.parametrize("method", ["yoshida8", "dop853"])
def test_exact_solution(method: str) -> None:
    m = model(mass=2.0, spring_constant=5.0, **{"initial.x": 0.4, "initial_rate.x": 1.1})
    r = mechsim.simulate(m, 20.0, 0.05, tolerance=1e-14 if method == "yoshida8" else 1e-12,
                         method=method)
    x, v = m.exact_solution(r.t)
    np.testing.assert_allclose(r.coordinate("x"), x, atol=1e-9)
    np.testing.assert_allclose(r.rate("x"), v, atol=1e-9)
    E = 0.5 * 2.0 * 1.1**2 + 0.5 * 5.0 * 0.4**2
    assert m.energy() == pytest.approx(E, rel=1e-14)
    np.testing.assert_allclose(r.total, E, rtol=1e-10)
    # h = E (Introduction to analytical mechanics)
    np.testing.assert_allclose(r.energy_function, r.total, rtol=1e-12)
    assert np.max(np.abs(r.balance_residual)) < 1e-9


def test_sine_form_and_period() -> None:
    """x = A sin(ω₀t − δ) (PHYS0500 line 49) and x(t + 2π√(m/k)) = x(t)."""
    m = model(**{"initial.x": -0.2, "initial_rate.x": 0.9})
    A, d, w = m.amplitude(), m.phase(), m.natural_frequency()
    assert m.period() == pytest.approx(2 * math.pi * math.sqrt(1.0 / 4.0), rel=1e-15)
    r = mechsim.simulate(m, m.period(), m.period() / 100, tolerance=1e-12)
    np.testing.assert_allclose(r.coordinate("x"), A * np.sin(w * r.t - d), atol=1e-10)
    assert r.coordinate("x")[-1] == pytest.approx(r.coordinate("x")[0], abs=1e-10)
    assert r.rate("x")[-1] == pytest.approx(r.rate("x")[0], abs=1e-10)


def test_period_averages_are_half_the_energy() -> None:
    """⟨T⟩ = ⟨V⟩ = E/2 over one period (equispaced samples average trig polynomials exactly)."""
    m = model(mass=1.5, spring_constant=2.5, **{"initial.x": 0.3, "initial_rate.x": 0.8})
    n = 256
    r = mechsim.simulate(m, m.period(), m.period() / n, tolerance=1e-12)
    assert r.t.size == n + 1
    E = m.energy()
    assert np.mean(r.kinetic[:n]) == pytest.approx(E / 2, rel=1e-10)
    assert np.mean(r.potential[:n]) == pytest.approx(E / 2, rel=1e-10)


def test_long_run_energy_is_bounded() -> None:
    """Symplectic run over 2000 periods: energy error bounded, no secular drift. (The
    composition's step heuristic gives a relative energy error well above ``tolerance``:
    ~1e-9 at 1e-14.)"""
    m = model()
    r = mechsim.simulate(m, 2000 * m.period(), m.period() / 4, tolerance=1e-14,
                         method="yoshida8")
    rel = np.abs(r.total / r.total[0] - 1)
    assert rel.max() < 3e-9
    half = rel.size // 2
    assert rel[half:].max() < 3 * rel[:half].max() + 1e-13


def test_laws_and_frames() -> None:
    m = model()
    assert [law.key for law in m.laws()] == ["energy", "energy_function", "work_balance"]
    assert [(f.child, f.parent, f.static) for f in m.frames] == [
        ("anchor", "world", True), ("mass", "anchor", False)]


@pytest.mark.parametrize("field,value", [("mass", 0.0), ("spring_constant", -1.0),
                                         ("initial.x", "abc")])
def test_parameter_validation(field: str, value: object) -> None:
    with pytest.raises(ParameterError) as err:
        model(**{field: value})
    assert err.value.field == field
    assert "\n" not in str(err.value)
