"""Spring pendulum (Introduction to analytical mechanics, “Spring pendulum”): equations of motion,
equilibrium stretch mg/k, the two small-oscillation frequencies, exact vertical SHM, energy
conservation, both forms agree."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import mechsim
from mechsim.errors import ParameterError

P = {"mass": 0.8, "length": 1.2, "spring_constant": 30.0, "gravity": 9.81}


def model(formulation: str = "polar", **kw):
    return mechsim.load_system("spring_pendulum", formulation=formulation, **{**P, **kw})


def test_equations_and_small_oscillation_frequencies() -> None:
    """sympy: EL equations of the document's L (corrected L669) and the Hessian of V at the
    equilibrium against T at rest, giving mg/k, k/m and g/(l + mg/k)."""
    t = sp.Symbol("t")
    m, l, k, g = sp.symbols("m l k g", positive=True)
    x, th = sp.Function("x")(t), sp.Function("theta")(t)
    T = m * (x.diff(t) ** 2 + (l + x) ** 2 * th.diff(t) ** 2) / 2
    V = -m * g * (l + x) * sp.cos(th) + k * x**2 / 2
    L = T - V

    def el(q):
        return sp.diff(L.diff(q.diff(t)), t) - L.diff(q)

    assert sp.simplify(el(x) - (m * x.diff(t, 2) - m * (l + x) * th.diff(t) ** 2
                                - m * g * sp.cos(th) + k * x)) == 0
    assert sp.simplify(el(th) / (m * (l + x)) - ((l + x) * th.diff(t, 2)
                                                 + 2 * x.diff(t) * th.diff(t)
                                                 + g * sp.sin(th))) == 0
    X, Th = sp.symbols("X Theta")
    Vs = -m * g * (l + X) * sp.cos(Th) + k * X**2 / 2
    xe = sp.solve(sp.diff(Vs, X).subs(Th, 0), X)[0]
    assert sp.simplify(xe - m * g / k) == 0
    H = sp.hessian(Vs, (X, Th)).subs({X: xe, Th: 0})
    Mm = sp.diag(m, m * (l + xe) ** 2)
    w2 = sp.solve((H - sp.Symbol("w2") * Mm).det(), sp.Symbol("w2"))
    assert {sp.simplify(w) for w in w2} == {k / m, sp.simplify(g / (l + m * g / k))}
    mod = model()
    vals = {m: 0.8, l: 1.2, k: 30.0, g: 9.81}
    assert mod.equilibrium_extension() == pytest.approx(float(xe.subs(vals)), rel=1e-15)
    assert mod.swing_frequency() == pytest.approx(
        math.sqrt(9.81 / (1.2 + 0.8 * 9.81 / 30.0)), rel=1e-15)
    assert mod.radial_frequency() == pytest.approx(math.sqrt(30.0 / 0.8), rel=1e-15)


@pytest.mark.parametrize("formulation", ["polar", "cartesian"])
def test_pure_vertical_shm(formulation: str) -> None:
    mod = model(formulation, **{"initial.angle": 0.0, "initial.extension": 0.5,
                                "initial_rate.extension": -0.3})
    r = mechsim.simulate(mod, 10.0, 0.02, tolerance=1e-13 if formulation == "polar" else 1e-14)
    xv, _ = mod.vertical_solution(r.t)
    x = (r.coordinate("extension") if formulation == "polar" else r.observables["extension"])
    np.testing.assert_allclose(x, xv, atol=1e-9)
    th = r.coordinate("angle") if formulation == "polar" else r.observables["angle"]
    assert np.max(np.abs(th)) < 1e-12


def test_equilibrium_is_at_rest() -> None:
    mod = model(**{"initial.angle": 0.0, "initial.extension": 0.8 * 9.81 / 30.0})
    r = mechsim.simulate(mod, 5.0, 0.5, tolerance=1e-12)
    np.testing.assert_allclose(r.coordinate("extension"), 0.8 * 9.81 / 30.0, atol=1e-13)
    np.testing.assert_allclose(r.observables["spring_tension"], 0.8 * 9.81, rtol=1e-11)


def test_small_swing_frequency() -> None:
    """Tiny swing at the equilibrium stretch: θ = θ₀ cos ω_θ t up to O(θ₀²) corrections."""
    th0 = 1e-4
    mod = model(**{"initial.angle": th0, "initial.extension": 0.8 * 9.81 / 30.0})
    w = mod.swing_frequency()
    r = mechsim.simulate(mod, 4 * 2 * math.pi / w, 0.01, tolerance=1e-13)
    np.testing.assert_allclose(r.coordinate("angle"), th0 * np.cos(w * r.t), atol=th0 * 1e-6)


def test_formulations_agree() -> None:
    a = mechsim.simulate(model("polar"), 8.0, 0.05, tolerance=1e-13)
    b = mechsim.simulate(model("cartesian"), 8.0, 0.05, tolerance=1e-14, method="dop853")
    np.testing.assert_allclose(a.coordinate("extension"), b.observables["extension"],
                               atol=1e-7)
    np.testing.assert_allclose(a.coordinate("angle"), b.observables["angle"], atol=1e-7)
    np.testing.assert_allclose(a.total, b.total, rtol=1e-10)
    np.testing.assert_allclose(a.outputs.frames, b.outputs.frames, atol=1e-7)


def test_long_run_energy() -> None:
    polar = mechsim.simulate(model("polar"), 300.0, 0.1, tolerance=1e-12)
    assert np.max(np.abs(polar.total / polar.total[0] - 1)) < 1e-9
    cart = mechsim.simulate(model("cartesian"), 300.0, 0.1, tolerance=1e-14)
    assert cart.method == "radau15"  # auto at 1e-14: the machine-precision method
    rel = np.abs(cart.total / cart.total[0] - 1)
    assert rel.max() < 1e-9


@pytest.mark.parametrize("kw,field", [({"initial.extension": -1.5}, "initial.extension"),
                                      ({"spring_constant": 0.0}, "spring_constant"),
                                      ({"initial.angle": 4.0}, "initial.angle")])
def test_parameter_validation(kw: dict, field: str) -> None:
    with pytest.raises(ParameterError) as err:
        model(**kw)
    assert err.value.field == field
