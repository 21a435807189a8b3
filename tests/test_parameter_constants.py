"""Parameter constants: a generated kernel reads the subexpressions of the parameters alone
(the CR3BP's ω = √(G(m₁ + m₂)/L³), G m₁, …) from slots of the parameter vector that are filled
once per vector, instead of computing them at every call. A changed parameter must reach
them, through a new model or through a vector in which a caller changed the parameter, and
they keep the kernels' IEEE arithmetic (a division by zero gives inf, not an exception)."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from mechsim.integrators import make_stepper
from mechsim.systems import load_system
from mechsim.systems.lagrangian_kernels import _ParameterConstants
from mechsim.systems.layout import ParameterLayout


def _index(model, name: str) -> int:  # type: ignore[no-untyped-def]
    return [p.name for p in model.parameter_spec() if p.is_numeric].index(name)


def test_a_parameter_changed_in_the_vector_reaches_its_constants() -> None:
    model = load_system("cr3bp")
    assert model.kernels.n_p > model.effort_slice().stop  # ω and the G m's are constants
    t = np.linspace(0.0, 5.0, 6)
    before = make_stepper(model, "dop853", 1e-10).advance(t)
    wider = make_stepper(model.with_values(separation=1.2), "dop853", 1e-10).advance(t)
    assert np.abs(wider - before).max() > 1e-3  # the separation matters here

    p = model.parameter_vector()
    p[_index(model, "separation")] = 1.2  # the constants in p are still the old ones
    st = make_stepper(model, "dop853", 1e-10)
    st.set_parameters(p)
    np.testing.assert_array_equal(st.advance(t), wider)


def test_a_restart_with_a_changed_parameter_reaches_its_constants() -> None:
    """``restart`` (the simulator node's path for a new effort) takes a whole vector too."""
    model = load_system("cr3bp")
    t = np.linspace(0.0, 5.0, 6)
    wider = make_stepper(model.with_values(separation=1.2), "dop853", 1e-10)
    wider.advance(t[:1])
    p = model.parameter_vector()
    p[_index(model, "separation")] = 1.2
    st = make_stepper(model, "dop853", 1e-10)
    st.advance(t[:1])
    st.restart(0.0, model.initial_y(), p)
    wider.restart(0.0, model.initial_y(), wider.p)
    np.testing.assert_array_equal(st.advance(t), wider.advance(t))


def test_a_vector_of_another_layout_is_refused() -> None:
    model = load_system("cr3bp")
    st = make_stepper(model, "dop853", 1e-8)
    with pytest.raises(ValueError, match="parameter vector has"):
        st.set_parameters(model.parameter_vector()[:-1])


def test_constants_are_taken_out_and_computed_with_ieee_arithmetic() -> None:
    a, b = sp.symbols("p_a p_b", real=True)
    x = sp.Symbol("x", real=True)
    pc = _ParameterConstants({"a": a, "b": b}, ParameterLayout(("a", "b")))
    expr = x * sp.sqrt(a) / b + sp.log(a - b) + sp.sin(x + a * b)
    hoisted = pc.hoist(expr)
    assert hoisted.free_symbols == {x, *pc.found.values()}  # no parameter read directly
    namespace: dict[str, object] = {}
    exec(pc.source(), namespace)  # noqa: S102 - the generated source under test
    fill = namespace["parameter_constants"]

    p = np.array([4.0, 2.0] + [np.nan] * len(pc.found))
    fill(p)  # type: ignore[operator]
    values = dict(zip(pc.found.values(), p[2:], strict=True))
    for xv in (-0.7, 0.3, 2.0):
        want = float(expr.subs({a: 4.0, b: 2.0, x: xv}))
        assert float(hoisted.subs(values).subs(x, xv)) == pytest.approx(want, rel=1e-15)

    p = np.array([0.0, 0.0] + [np.nan] * len(pc.found))
    fill(p)  # type: ignore[operator]  # sqrt(0)/0 and log(0): no exception
    assert np.isnan(p[2:]).any() and np.isneginf(p[2:]).any()
