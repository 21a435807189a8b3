"""Projectile with linear drag (Introduction to analytical mechanics, “Lagrange's equation of motion
with frictional forces”): closed-form trajectory, terminal velocity,
dE/dt = −2D, decaying momentum of the cyclic coordinates."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import quad

import mechsim
from mechsim.errors import ParameterError

P = {"mass": 0.8, "drag_coefficient": 0.3, "gravity": 9.81, "initial.x": 1.0, "initial.y": -2.0,
     "initial.z": 0.5, "initial_rate.x": 10.0, "initial_rate.y": 3.0, "initial_rate.z": 12.0}


def model(**kw):
    return mechsim.load_system("drag_projectile", **{**P, **kw})


def test_equations_and_closed_form() -> None:
    """sympy: d/dt ∂L/∂q̇ − ∂L/∂q + ∂D/∂q̇ = 0 gives the document's three equations, E decays
    at −2D on them, and the closed form solves the z equation with its initial values."""
    t = sp.Symbol("t")
    m, a, g = sp.symbols("m alpha g", positive=True)
    q = [sp.Function(n)(t) for n in "xyz"]
    v = [qi.diff(t) for qi in q]
    L = m * sum(vi**2 for vi in v) / 2 - m * g * q[2]
    D = a * sum(vi**2 for vi in v) / 2
    eqs = [sp.diff(L.diff(vi), t) - L.diff(qi) + D.diff(vi) for qi, vi in zip(q, v, strict=True)]
    assert sp.simplify(eqs[0] - (m * q[0].diff(t, 2) + a * v[0])) == 0
    assert sp.simplify(eqs[2] - (m * q[2].diff(t, 2) + a * v[2] + m * g)) == 0
    E = m * sum(vi**2 for vi in v) / 2 + m * g * q[2]
    acc = {q[i].diff(t, 2): sp.solve(eqs[i], q[i].diff(t, 2))[0] for i in range(3)}
    assert sp.simplify(E.diff(t).subs(acc) + 2 * D) == 0
    z0, w0 = sp.symbols("z0 w0", real=True)
    tau = m / a
    z = z0 - g * tau * t + tau * (w0 + g * tau) * (1 - sp.exp(-t / tau))
    assert sp.simplify(m * z.diff(t, 2) + a * z.diff(t) + m * g) == 0
    assert sp.simplify(z.subs(t, 0) - z0) == 0 and sp.simplify(z.diff(t).subs(t, 0) - w0) == 0


def test_trajectory() -> None:
    mod = model()
    r = mechsim.simulate(mod, 10.0, 0.05, tolerance=1e-12)
    pos, vel = mod.exact_solution(r.t)
    np.testing.assert_allclose(r.q, pos, atol=1e-9)
    np.testing.assert_allclose(r.v, vel, atol=1e-9)
    tau = 0.8 / 0.3
    np.testing.assert_allclose(r.observables["momentum_x"], 0.8 * 10.0 * np.exp(-r.t / tau),
                               rtol=1e-10)  # x cyclic, p_x not conserved
    assert mod.horizontal_asymptote() == pytest.approx((1.0 + 10.0 * tau, -2.0 + 3.0 * tau))


def test_terminal_velocity() -> None:
    mod = model()
    tau = 0.8 / 0.3
    assert mod.terminal_velocity() == pytest.approx(-0.8 * 9.81 / 0.3, rel=1e-15)
    r = mechsim.simulate(mod, 30 * tau, tau, tolerance=1e-12)
    assert r.rate("z")[-1] == pytest.approx(mod.terminal_velocity(), rel=1e-11)
    assert r.coordinate("x")[-1] == pytest.approx(mod.horizontal_asymptote()[0], rel=1e-11)


def test_dissipation_is_twice_rayleigh() -> None:
    """E(t) − E(0) = −∫ 2D dt with 2D = α|v|² integrated on the closed form."""
    mod = model()
    r = mechsim.simulate(mod, 6.0, 0.5, tolerance=1e-12)
    np.testing.assert_allclose(r.observables["power_dissipated"],
                               2 * r.observables["rayleigh_function"], rtol=1e-15)

    def two_d(s: float) -> float:
        return 0.3 * float(np.sum(mod.exact_solution(np.array(s))[1] ** 2))

    for i in (3, 8, 12):
        W = quad(two_d, 0, r.t[i], epsabs=1e-12, epsrel=1e-13)[0]
        assert r.work_dissipated[i] == pytest.approx(W, rel=1e-10)
        assert r.total[i] - r.total[0] == pytest.approx(-W, rel=1e-9)
    assert np.max(np.abs(r.balance_residual)) < 1e-9
    assert [law.key for law in mod.laws()] == ["work_balance"]


def test_no_drag_is_the_parabola() -> None:
    mod = model(drag_coefficient=0.0)
    r = mechsim.simulate(mod, 3.0, 0.1, tolerance=1e-12)
    t = r.t
    np.testing.assert_allclose(r.coordinate("z"), 0.5 + 12.0 * t - 0.5 * 9.81 * t**2, atol=1e-10)
    np.testing.assert_allclose(r.total, r.total[0], atol=1e-10)


def test_long_run_balance() -> None:
    r = mechsim.simulate(model(), 300.0, 0.5, tolerance=1e-12)
    assert np.max(np.abs(r.balance_residual)) / np.max(np.abs(r.work_dissipated)) < 1e-11


@pytest.mark.parametrize("kw,field", [({"drag_coefficient": -0.1}, "drag_coefficient"),
                                      ({"mass": 0.0}, "mass"),
                                      ({"initial.w": 1.0}, "initial.w")])
def test_parameter_validation(kw: dict, field: str) -> None:
    with pytest.raises(ParameterError) as err:
        model(**kw)
    assert err.value.field == field
