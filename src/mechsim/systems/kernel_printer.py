"""How sympy expressions are printed into numba kernel source: half-integer powers as square
roots and small integer powers as the products numba evaluates for them, so a kernel's value is
the same to the last bit as numba's own ``**``. Part of every derivation's cache key
(``mechsim.systems.lagrangian.GENERATOR_SOURCE``)."""

from __future__ import annotations

import sympy as sp
from sympy.printing.precedence import PRECEDENCE
from sympy.printing.pycode import PythonCodePrinter

#: Largest |n| of an integer power x**n written out as products (``_binary_power``).
POWER_PRODUCT_MAX = 16


def _binary_power(base: str, n: int) -> str:
    """``base**n`` (n ≥ 1) written out as the products numba evaluates for it: repeated
    squaring, the powers of the set bits of n multiplied in increasing order (numba's
    ``int_power``), so the value is the same to the last bit. Numba compiles ``int_power`` as
    a subroutine in every process that compiles a kernel using ``**``."""
    result = ""
    square = base
    while n:
        if n & 1:
            result = f"({result}*{square})" if result else square
        n >>= 1
        if n:
            square = f"({square}*{square})"
    return result


class _KernelPrinter(PythonCodePrinter):
    """Python printer for numba kernels: half-integer powers as square roots (x**1.5 is a
    general pow call, x*sqrt(x) is two instructions), small integer powers as the products
    numba would evaluate (``_binary_power``)."""

    def _print_Pow(self, expr: sp.Pow, rational: bool = False) -> str:
        b, e = expr.as_base_exp()
        base = self.parenthesize(b, PRECEDENCE["Pow"], strict=False)  # a factor of a product
        if isinstance(e, sp.Rational) and e.q == 2 and abs(e.p) <= 7:
            root = f"math.sqrt({self._print(b)})"
            whole = abs(e.p) // 2
            text = root if whole == 0 else f"({_binary_power(base, whole)}*{root})"
            return f"(1.0/{text})" if e.p < 0 else text
        if isinstance(e, sp.Integer) and 2 <= abs(int(e)) <= POWER_PRODUCT_MAX:
            text = _binary_power(base, abs(int(e)))
            return f"(1.0/{text})" if e < 0 else text
        return super()._print_Pow(expr, rational=rational)


def _printer() -> PythonCodePrinter:
    return _KernelPrinter({"fully_qualified_modules": True})
