"""What generated kernel code relies on instead of numba's per-process library code: integer
powers written out as products must give what numba computes for ``x ** n`` (to the bit), and
the compiled helpers of ``mechsim.codegen.support`` must stand for the numpy calls they replace
(``np.max(np.abs(r)) < bound`` with its nan behaviour, ``np.empty``/``np.zeros`` shapes)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from numba import njit

from mechsim.codegen import support
from mechsim.systems.kernel_printer import POWER_PRODUCT_MAX, _binary_power, _printer

EXPONENTS = [n for n in range(-POWER_PRODUCT_MAX, POWER_PRODUCT_MAX + 1) if abs(n) >= 2]


@njit(cache=False, error_model="numpy")
def _numba_power(x, n):  # type: ignore[no-untyped-def]
    return x ** n  # numba's integer power (repeated squaring), what kernels computed before


def _expected(x: float, n: int) -> float:
    """numba's x**n; for n < 0 that is 1.0 / x**|n|, where numba raises ZeroDivisionError on a
    zero denominator and the products give IEEE's ±inf (a non-finite state the loops report,
    as for every other division in a kernel)."""
    if n > 0:
        return float(_numba_power(x, n))
    r = _numba_power(x, -n)
    if r == 0.0:
        return math.copysign(math.inf, r)
    assert np.float64(_numba_power(x, n)).tobytes() == np.float64(1.0 / r).tobytes()
    return 1.0 / r


def _printed(n: int) -> object:
    """A numba function evaluating the printer's text for x**n."""
    x = sp.Symbol("x", real=True)
    text = _printer().doprint(x**n)
    assert "**" not in text
    namespace: dict[str, object] = {"math": math}
    exec(f"def f(x):\n    return {text}\n", namespace)  # noqa: S102 - generated test code
    return njit(cache=False, error_model="numpy")(namespace["f"])


@pytest.mark.parametrize("n", EXPONENTS)
def test_integer_power_products_equal_numbas_power_to_the_bit(n: int) -> None:
    rng = np.random.default_rng(abs(n))
    xs = np.concatenate([rng.uniform(-3.0, 3.0, 200), 10.0 ** rng.uniform(-150, 150, 200),
                         [0.0, -0.0, 1.0, -1.0, math.inf, -math.inf, math.nan, 1e-310]])
    f = _printed(n)
    for x in xs:
        expected, got = _expected(x, n), f(x)
        assert np.float64(got).tobytes() == np.float64(expected).tobytes() or (
            math.isnan(got) and math.isnan(expected)), (x, n, got, expected)


def test_binary_power_spells_repeated_squaring() -> None:
    assert _binary_power("x", 2) == "(x*x)"
    assert _binary_power("x", 3) == "(x*(x*x))"
    assert _binary_power("x", 6) == "((x*x)*((x*x)*(x*x)))"


def test_compound_bases_are_parenthesised() -> None:
    x, y = sp.symbols("x y", real=True)
    pr = _printer()
    assert pr.doprint((x + y) ** 2) == "((x + y)*(x + y))"
    assert pr.doprint((x + y) ** sp.Rational(5, 2)) == "(((x + y)*(x + y))*math.sqrt(x + y))"
    assert pr.doprint(x ** (POWER_PRODUCT_MAX + 1)) == f"x**{POWER_PRODUCT_MAX + 1}"


@pytest.mark.parametrize("r", [[0.0], [1e-16, -1e-16], [1e-15], [0.0, -2e-15], [math.nan],
                               [0.0, math.nan], [math.inf], [-1e-300, 5e-16]])
def test_all_below_is_the_max_abs_test(r: list[float]) -> None:
    a = np.array(r)
    assert support.all_below(a, 1e-15) == bool(np.max(np.abs(a)) < 1e-15)


def test_allocators_give_the_numpy_arrays() -> None:
    for made, shape in ((support.vector(3), (3,)), (support.matrix(2, 5), (2, 5)),
                        (support.tensor(3, 3, 3), (3, 3, 3))):
        assert made.shape == shape and made.dtype == np.float64 and made.flags.c_contiguous
    for made in (support.zero_vector(4), support.zero_matrix(3, 2)):
        assert made.dtype == np.float64 and not made.any()
