"""Damped oscillator (PHYS0500 §1.3, “Energy and Hamiltonians: Part 3 – Examples”, Case 5): exact
motion in the three regimes, the dissipation balance dE/dt = −bẋ², and the Caldirola–Kanai energy
function h = e^{bt/m}E."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import quad

import mechsim
from mechsim.errors import ParameterError
from mechsim.systems._oscillator import free_solution


def model(**kw):
    return mechsim.load_system("damped_oscillator", **kw)


def test_oracle_formulas_solve_the_equation() -> None:
    """The closed forms (all regimes) satisfy ẍ + 2βẋ + ω₀²x = 0 and the initial conditions,
    checked on sympy expressions written out independently of the code."""
    t, x0, v0 = sp.symbols("t x0 v0", real=True)
    b, w = sp.symbols("beta omega", positive=True)
    c = v0 + b * x0
    forms = {
        "under": (sp.exp(-b * t) * (x0 * sp.cos(w * t) + c / w * sp.sin(w * t)), b**2 + w**2),
        "critical": (sp.exp(-b * t) * (x0 + c * t), b**2),
        "over": (sp.exp(-b * t) * (x0 * sp.cosh(w * t) + c / w * sp.sinh(w * t)), b**2 - w**2),
    }
    for x, w0sq in forms.values():
        assert sp.simplify(x.diff(t, 2) + 2 * b * x.diff(t) + w0sq * x) == 0
        assert sp.simplify(x.subs(t, 0) - x0) == 0
        assert sp.simplify(x.diff(t).subs(t, 0) - v0) == 0
    # and the numeric helper reproduces them
    ts = np.linspace(0, 3, 5)
    for name, (x, w0sq) in forms.items():
        vals = {x0: 0.3, v0: -1.2, b: 0.7, w: 0.4 if name == "over" else 1.1}
        w0 = math.sqrt(float(w0sq.subs(vals)))
        f = sp.lambdify(t, x.subs(vals), "numpy")
        fv = sp.lambdify(t, x.diff(t).subs(vals), "numpy")
        got = free_solution(ts, 0.3, -1.2, w0, 0.7)
        np.testing.assert_allclose(got[0], f(ts) + 0 * ts, atol=1e-14, err_msg=name)
        np.testing.assert_allclose(got[1], fv(ts) + 0 * ts, atol=1e-14, err_msg=name)


def test_caldirola_kanai_lagrangian() -> None:
    """L = e^{γt/m}[½mẋ² − ½kx²] gives e^{γt/m}(mẍ + γẋ + kx) = 0 and h = e^{γt/m}E,
    E = ½mẋ² + ½kx² (“Energy and Hamiltonians: Part 3 – Examples”, Case 5, with the m its text
    drops)."""
    t = sp.Symbol("t")
    m, k, g = sp.symbols("m k gamma", positive=True)
    x = sp.Function("x")(t)
    xd = x.diff(t)
    L = sp.exp(g * t / m) * (m * xd**2 / 2 - k * x**2 / 2)
    el = sp.diff(L.diff(xd), t) - L.diff(x)
    assert sp.simplify(el - sp.exp(g * t / m) * (m * x.diff(t, 2) + g * xd + k * x)) == 0
    h = xd * L.diff(xd) - L
    assert sp.simplify(h - sp.exp(g * t / m) * (m * xd**2 / 2 + k * x**2 / 2)) == 0


@pytest.mark.parametrize("damping,kind", [(0.0, "underdamped"), (0.6, "underdamped"),
                                          (4.0, "critical"), (9.0, "overdamped")])
def test_exact_solution(damping: float, kind: str) -> None:
    m = model(damping=damping, **{"initial.x": 0.8, "initial_rate.x": -0.5})
    assert m.regime() == kind
    assert m.critical_damping() == pytest.approx(4.0, rel=1e-15)
    r = mechsim.simulate(m, 12.0, 0.02, tolerance=1e-12, method="dop853")
    x, v = m.exact_solution(r.t)
    np.testing.assert_allclose(r.coordinate("x"), x, atol=1e-10)
    np.testing.assert_allclose(r.rate("x"), v, atol=1e-10)
    assert np.max(np.abs(r.balance_residual)) < 1e-10


def test_dissipation_balance() -> None:
    """E(t) − E(0) = −∫ b ẋ² dt; the integral is evaluated by quadrature of the exact ẋ."""
    m = model(damping=0.5, mass=2.0, spring_constant=3.0,
              **{"initial.x": 1.0, "initial_rate.x": 0.4})
    r = mechsim.simulate(m, 10.0, 0.5, tolerance=1e-12)
    for i in (5, 12, 20):
        W = quad(lambda s: 0.5 * m.exact_solution(np.array(s))[1] ** 2, 0, r.t[i],
                 epsabs=1e-14, epsrel=1e-13, limit=200)[0]
        assert r.work_dissipated[i] == pytest.approx(W, rel=1e-9)
        assert r.total[i] - r.total[0] == pytest.approx(-W, abs=1e-10)
    np.testing.assert_allclose(r.observables["power_dissipated"], 0.5 * r.rate("x") ** 2)
    assert np.max(np.abs(r.work_external)) < 1e-12  # round-off only
    assert [law.key for law in m.laws()] == ["work_balance"]


def test_caldirola_kanai_observable() -> None:
    """h = e^{bt/m}E and h(t) − h(0) = −(b/m)∫ e^{bs/m}(T − V) ds (quadrature, exact x)."""
    mass, k, b = 1.5, 4.0, 0.6
    m = model(mass=mass, spring_constant=k, damping=b)
    r = mechsim.simulate(m, 8.0, 0.5, tolerance=1e-12)
    h = r.observables["caldirola_kanai_energy_function"]
    np.testing.assert_allclose(h, np.exp(b * r.t / mass) * r.total, rtol=1e-13)

    def lag(s: float) -> float:
        x, v = m.exact_solution(np.array(s))
        return math.exp(b * s / mass) * (0.5 * mass * v**2 - 0.5 * k * x**2)

    for i in (4, 16):
        integral = quad(lag, 0, r.t[i], epsabs=1e-13, epsrel=1e-12, limit=200)[0]
        assert h[i] - h[0] == pytest.approx(-b / mass * integral, abs=1e-9)


def test_successive_maxima() -> None:
    """Maxima T₁ = 2π/ω₁ apart, ratio e^{βT₁} (PHYS0500 lines 143–145)."""
    m = model(damping=0.3)
    w1, beta = m.damped_frequency(), m.beta()
    assert w1 == pytest.approx(math.sqrt(4.0 - 0.15**2), rel=1e-15)
    r = mechsim.simulate(m, 20.0, 1e-3, tolerance=1e-12)
    x, v = r.coordinate("x"), r.rate("x")
    idx = np.where((v[:-1] > 0) & (v[1:] <= 0))[0]
    # refine each maximum by linear interpolation of ẋ = 0
    tm = r.t[idx] + v[idx] / (v[idx] - v[idx + 1]) * (r.t[idx + 1] - r.t[idx])
    np.testing.assert_allclose(np.diff(tm), 2 * math.pi / w1, atol=1e-6)
    peaks = x[idx]
    ratio = peaks[:-1] / peaks[1:]
    np.testing.assert_allclose(np.log(ratio), m.logarithmic_decrement(), atol=1e-5)
    assert m.logarithmic_decrement() == pytest.approx(beta * 2 * math.pi / w1, rel=1e-15)


def test_long_run_balance() -> None:
    m = model(damping=0.05)
    r = mechsim.simulate(m, 400.0, 0.25, tolerance=1e-12)
    assert np.max(np.abs(r.balance_residual)) < 1e-9
    assert r.total[-1] < 1e-8 * r.total[0]
    x, _ = m.exact_solution(r.t)
    np.testing.assert_allclose(r.coordinate("x"), x, atol=1e-8)


@pytest.mark.parametrize("field,value", [("mass", 0.0), ("damping", -0.1),
                                         ("spring_constant", float("nan"))])
def test_parameter_validation(field: str, value: float) -> None:
    with pytest.raises(ParameterError) as err:
        model(**{field: value})
    assert err.value.field == field
