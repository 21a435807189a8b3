"""Bead sliding without friction on a fixed planar wire under gravity.

Sources: seed 000 S2 ("Dynamical Systems and Constraints: Part 2 – Bead on a Wire", L99–256);
seed 001 §2.12 (brachistochrone, the cycloid); PHYS0500 ch. 2 (calculus of variations: the
cycloid as the curve of quickest descent and the tautochrone are the catalog's supplement).

Wire shapes (``shape``), in the x–z plane of the ``wire`` frame (REP-103: z up; the document's
y is our z): ``line`` z = slope·x, ``parabola`` z = c x² (the document's y = x² is c = 1 m⁻¹),
``custom`` z = f(x) from the string parameter ``curve`` (a sympy expression in x, parsed from
a whitelist of names and operators, never evaluated as Python), and ``cycloid`` of generating
radius a with its cusp at (0, 2a) and its lowest point at (πa, 0): x = a(θ − sin θ),
z = a(1 + cos θ). On the cycloid the coordinate is the arc length s from the lowest point,
s = 4a cos(θ/2) (s = 4a at the cusp), in which z = s²/(8a) and the motion is exactly harmonic
with ω = √(g/4a): from rest anywhere the bead reaches the bottom after π√(a/g) (tautochrone;
from the cusp it is the brachistochrone). The event ``lowest_point`` records each passage.
V = m g z (zero at z = 0 of the wire frame).

Formulations:
- ``reduced``: the constraint substituted, L = ½ m(1 + f′²)ẋ² − m g f (the document's B2, L215–
  235; s on the cycloid). The normal force is an observable from the exact formula
  N = m(g + f″ẋ²)/√(1 + f′²) along N̂ = (−f′, 1)/√(1 + f′²) (positive: the wire pushes up).
- ``multiplier``: Cartesian (x, z) with the constraint z − f(x) = 0 and its multiplier λ; the
  constraint force is λ(−f′, 1), so N = λ√(1 + f′²) (the catalog's "formulation C", the
  correct Cartesian form). On the cycloid: (x, z, s) with x − X(s) = 0 and z − Z(s) = 0 (s has
  no mass; it cannot start exactly at the cusp, where the curvature is infinite).
- ``naive``: the document's "Newtonian" form A (L145–163): free Cartesian motion plus the
  *static* normal force m g τ (−f′, 1), τ = 1/(1 + f′²). It omits the centripetal part m τ f″ẋ²
  of the normal force, so on any curved wire the bead leaves the wire and energy is not
  conserved — a modelling error, not a numerical one (the document blames the solver, L188).
  Kept as a deliberate negative example: its laws still list energy and the wire constraint,
  and the diagnostics flag both; the work of the static force closes the work balance. Exact
  on a straight line. Graph wires only (not the cycloid).

Document typos corrected: τ = 1/(1 + f′²) (L141 prints ``f'2``); the document's diagnosis of
form A's failure as numerical (L188) is wrong (see above).
"""

from __future__ import annotations

import ast
import io
import math
import operator
import tokenize
from collections.abc import Callable
from typing import Any

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Law, Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

SHAPES = ("parabola", "line", "cycloid", "custom")

#: The names a curve may use besides x, and the sympy objects they stand for (``_symbols``).
_FUNCTIONS = ("sin", "cos", "tan", "exp", "log", "sqrt", "sinh", "cosh", "tanh", "atan", "asin",
              "acos", "asinh", "acosh", "atanh", "pi", "E", "abs")


def _symbols() -> dict[str, Any]:
    return {name: sp.Abs if name == "abs" else getattr(sp, name) for name in _FUNCTIONS}


_OPERATORS = {"+", "-", "*", "/", "**", "^", "(", ")"}

# Bounds checked before sympy sees a curve (sympy evaluates constant parts exactly or with
# mpmath's unbounded exponents: 9**9**9 or exp(exp(exp(1e6))) would not finish).
MAX_CURVE_CHARS = 200
MAX_CURVE_DEPTH = 40  # nesting of operations and calls
MAX_LITERAL = 1e6  # magnitude of any number written in the expression
MAX_POWER_DEPTH = 2  # powers nested in powers, e.g. (x**2)**3
MAX_CONSTANT_EXPONENT = 100.0  # |n| of x**n when n is a constant

_BINARY: dict[type, Callable[[float, float], float]] = {
    ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
    ast.Div: operator.truediv, ast.Pow: operator.pow}
_MATH: dict[str, Callable[[float], float]] = {
    "sin": math.sin, "cos": math.cos, "tan": math.tan, "exp": math.exp, "log": math.log,
    "sqrt": math.sqrt, "sinh": math.sinh, "cosh": math.cosh, "tanh": math.tanh,
    "atan": math.atan, "asin": math.asin, "acos": math.acos, "asinh": math.asinh,
    "acosh": math.acosh, "atanh": math.atanh, "abs": abs}


def _bounded(node: ast.AST, text: str, depth: int = 0, powers: int = 0) -> float | None:
    """Check one node of a curve's syntax tree against the bounds above; return its value in
    floating point if it is constant (no x), else None. ParameterError("curve", ...) if a
    bound is broken or a constant part is not a finite real number."""
    if depth > MAX_CURVE_DEPTH:
        raise ParameterError("curve", f"nested deeper than {MAX_CURVE_DEPTH} levels")
    try:
        value = _node_value(node, text, depth, powers)
    except (OverflowError, ZeroDivisionError, ValueError, TypeError) as e:
        if isinstance(e, ParameterError):
            raise
        raise ParameterError("curve", "a constant part is not a finite real number") from None
    if value is None:
        return None
    if not (isinstance(value, float | int) and math.isfinite(value)):
        raise ParameterError("curve", "a constant part is not a finite real number")
    return float(value)


#: The names a curve may use, and their values (None: the variable).
_NAMES: dict[str, float | None] = {"x": None, "pi": math.pi, "E": math.e}


def _node_value(node: ast.AST, text: str, depth: int, powers: int) -> Any:
    """The value of ``node`` (see ``_bounded``; not yet checked to be finite and real)."""
    if isinstance(node, ast.Expression):
        return _bounded(node.body, text, depth, powers)
    if isinstance(node, ast.Constant) and isinstance(node.value, int | float) \
            and not isinstance(node.value, bool):
        if abs(node.value) > MAX_LITERAL:
            raise ParameterError("curve", f"number {node.value:g} larger than "
                                 f"{MAX_LITERAL:g} in magnitude")
        return float(node.value)
    if isinstance(node, ast.Name) and node.id in _NAMES:
        return _NAMES[node.id]
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.UAdd | ast.USub):
        v = _bounded(node.operand, text, depth + 1, powers)
        return None if v is None else (-v if isinstance(node.op, ast.USub) else v)
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        return _binary_value(node, text, depth, powers)
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
            and node.func.id in _MATH and len(node.args) == 1 and not node.keywords:
        v = _bounded(node.args[0], text, depth + 1, powers)
        return None if v is None else _MATH[node.func.id](v)
    raise ParameterError("curve", f"cannot read {text!r} as an expression in x")


def _binary_value(node: ast.BinOp, text: str, depth: int, powers: int) -> Any:
    """The value of a binary operation (see ``_bounded``), its powers bounded."""
    power = isinstance(node.op, ast.Pow)
    if power:
        powers += 1
        if powers > MAX_POWER_DEPTH:
            raise ParameterError("curve", f"powers nested more than {MAX_POWER_DEPTH} deep")
        if any(isinstance(n, ast.BinOp) and isinstance(n.op, ast.Pow)
               for n in ast.walk(node.right)):
            raise ParameterError("curve", "a power in an exponent (a**b**c) is not allowed")
    a = _bounded(node.left, text, depth + 1, powers)
    b = _bounded(node.right, text, depth + 1, powers)
    if power and b is not None and abs(b) > MAX_CONSTANT_EXPONENT:
        raise ParameterError("curve", f"exponent {b:g} larger than "
                             f"{MAX_CONSTANT_EXPONENT:g} in magnitude")
    if a is None or b is None:
        return None
    return _BINARY[type(node.op)](a, b)


def parse_curve(text: str) -> sp.Expr:
    """z = f(x) from a string: numbers, x, + − * / ** ^ ( ) and the functions in _FUNCTIONS.

    Every token is checked against that whitelist, and the syntax tree against the bounds
    above, before sympy sees the text, so nothing but bounded arithmetic can run. Raises
    ParameterError("curve", reason) with a one-line reason."""
    if len(text) > MAX_CURVE_CHARS:
        raise ParameterError("curve", f"longer than {MAX_CURVE_CHARS} characters")
    x = sp.Symbol("x", real=True)
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(text).readline))
    except (tokenize.TokenError, IndentationError, SyntaxError):
        raise ParameterError("curve", f"cannot read {text!r} as an expression in x") from None
    for tok in tokens:
        if tok.type in (tokenize.NEWLINE, tokenize.NL, tokenize.ENDMARKER):
            continue
        if tok.type == tokenize.NUMBER and "j" not in tok.string.lower():
            continue
        if tok.type == tokenize.NAME and (tok.string == "x" or tok.string in _FUNCTIONS):
            continue
        if tok.type == tokenize.OP and tok.string in _OPERATORS:
            continue
        raise ParameterError("curve", f"{tok.string!r} is not allowed (use x, numbers, "
                             "+ - * / ** ( ) and " + ", ".join(sorted(_FUNCTIONS)) + ")")
    source = text.replace("^", "**")
    try:
        tree = ast.parse(source.strip(), mode="eval")
    except (SyntaxError, ValueError, RecursionError):
        raise ParameterError("curve", f"cannot read {text!r} as an expression in x") from None
    _bounded(tree, text)
    try:
        expr = sp.sympify(source, locals={"x": x, **_symbols()}, rational=False)
    except (sp.SympifyError, SyntaxError, TypeError, ValueError, ZeroDivisionError):
        raise ParameterError("curve", f"cannot read {text!r} as an expression in x") from None
    if not isinstance(expr, sp.Expr) or expr.free_symbols - {x}:
        raise ParameterError("curve", f"must be an expression in x only (got {text!r})")
    return expr


def _numeric(expr: sp.Expr) -> Callable[[float], float]:
    """``expr`` (in x) as a function of a float, evaluated in floating point: an overflow is
    an error or inf, never mpmath's unbounded exponents."""
    x = sp.Symbol("x", real=True)
    f = sp.lambdify(x, expr, modules=[{"DiracDelta": lambda *a: 0.0,
                                       "Heaviside": lambda a, *h: float(a > 0)}, "math"])

    def value(x0: float) -> float:
        try:
            v = f(x0)
            return float(v) if not isinstance(v, complex) else math.nan
        except (ArithmeticError, ValueError, TypeError, NameError):
            return math.nan
    return value


class BeadOnWire(LagrangianModel):
    id = "bead_on_wire"
    title = "Bead on a wire: line, parabola, cycloid (brachistochrone/tautochrone), any z = f(x)"
    source = ("“Dynamical Systems and Constraints: Part 2 – Bead on a Wire” (blog post); "
              "Introduction to analytical mechanics, “Brachistochrone problem – shortest time "
              "problem”; PHYS0500 – Advanced Classical Mechanics, ch. 2 (Calculus of Variations)")
    formulations = ("reduced", "multiplier", "naive")
    oracles = ("line: uniform acceleration −gs/(1+s²), chord time √((π²+4)a/g); parabola: exact "
               "period by quadrature, √(2gc) small; cycloid: π√(a/g) to the bottom from any "
               "start; normal force; naive form violates E and the constraint")
    parameters = (
        Parameter("shape", "parabola", "", "wire shape", choices=SHAPES),
        Parameter("curve", "cosh(x) - 1", "", "wire height z = f(x) in m for shape custom "
                  "(x in m; names: x, pi, E, sin, cos, tan, exp, log, sqrt, sinh, cosh, tanh, "
                  "atan, asin, acos, asinh, acosh, atanh, abs)"),
        number("slope", -0.5, "", "slope s of the line z = s x"),
        number("curvature", 1.0, "1/m", "c of the parabola z = c x²"),
        positive("cycloid_radius", 1.0, "m", "generating-circle radius a of the cycloid"),
        positive("mass", 1.0, "kg", "bead mass m"),
        positive("gravity", 9.81, "m/s^2", "gravitational acceleration g"),
        number("initial.x", 1.0, "m", "initial horizontal position x (on the cycloid: "
               "0 ≤ x ≤ 2πa, 0 is the cusp)"),
        number("initial_rate.x", 0.0, "m/s", "initial horizontal velocity ẋ"),
    )

    def check(self) -> None:
        shape, form = str(self.values["shape"]), self.formulation
        if shape == "custom":
            f = parse_curve(str(self.values["curve"]))
            x = sp.Symbol("x", real=True)
            x0 = self.value("initial.x")
            for label, e in (("f", f), ("f′", f.diff(x)), ("f″", f.diff(x, 2))):
                if not math.isfinite(_numeric(e)(x0)):
                    raise ParameterError("curve", f"{label}(x) is not finite and real at "
                                         f"initial.x = {x0:g}")
        if shape == "cycloid":
            a, x0 = self.value("cycloid_radius"), self.value("initial.x")
            if form == "naive":
                raise ParameterError("formulation", "naive needs a wire z = f(x); the cycloid "
                                     "has reduced and multiplier forms")
            if not 0.0 <= x0 <= 2 * math.pi * a:
                raise ParameterError("initial.x", f"must be in [0, 2πa] = [0, "
                                     f"{2 * math.pi * a:.6g}] on the cycloid (got {x0:g})")
            s0 = self._cycloid_arc(x0)
            if abs(abs(s0) - 4 * a) < 1e-12 * a:
                if self.value("initial_rate.x") != 0.0:
                    raise ParameterError("initial_rate.x", "must be 0 at a cusp (vertical "
                                         "tangent)")
                if form == "multiplier":
                    raise ParameterError("initial.x", "the multiplier form cannot start at the "
                                         "cusp (infinite curvature): use initial.x > 0 or the "
                                         "reduced form")

    # --- geometry ---------------------------------------------------------------------------
    def _graph(self, b: LagrangianBuilder, x: sp.Expr) -> sp.Expr:
        shape = str(self.values["shape"])
        if shape == "line":
            return b.param("slope") * x
        if shape == "parabola":
            return b.param("curvature") * x**2
        return parse_curve(str(self.values["curve"])).subs(sp.Symbol("x", real=True), x)

    def _cycloid_arc(self, x0: float) -> float:
        """Arc length s from the lowest point of the cycloid point with abscissa x0."""
        a = self.value("cycloid_radius")
        if x0 <= 0.0:
            th = 0.0
        elif x0 >= 2 * math.pi * a:
            th = 2 * math.pi
        else:
            from scipy.optimize import brentq  # here: importing it costs 0.2-0.4 s

            th = brentq(lambda t: a * (t - math.sin(t)) - x0, 0.0, 2 * math.pi, xtol=1e-15,
                        rtol=1e-15)
        return 4 * a * math.cos(th / 2)

    def declare(self, b: LagrangianBuilder) -> None:
        m, g = b.param("mass"), b.param("gravity")
        form = self.formulation
        if str(self.values["shape"]) == "cycloid":
            self._declare_cycloid(b, m, g)
            return
        if form == "reduced":
            x, dx = b.coordinate("x", "m")
            f = self._graph(b, x)
            f1, f2 = f.diff(x), f.diff(x, 2)
            b.kinetic = m * (1 + f1**2) * dx**2 / 2
            b.potential = m * g * f
            b.observable("normal_force", "N", m * (g + f2 * dx**2) / sp.sqrt(1 + f1**2))
            z = f
        else:
            x, dx = b.coordinate("x", "m")
            z, dz = b.coordinate("z", "m")
            f = self._graph(b, x)
            f1 = f.diff(x)
            b.kinetic = m * (dx**2 + dz**2) / 2
            b.potential = m * g * z
            if form == "multiplier":
                b.constraint("wire", z - f)
                lam = b.multiplier(0)
                b.observable("normal_force", "N", lam * sp.sqrt(1 + f1**2))
                b.observable("multiplier", "N", lam)
            else:
                tau = 1 / (1 + f1**2)
                b.forces = [-m * g * tau * f1, m * g * tau]
                b.invariant("constraint_wire", "m", z - f)
                b.observable("normal_force", "N", m * g * sp.sqrt(tau))
        b.frame("wire", "world", (0, 0, 0))
        b.frame("bead", "wire", (x, 0, z),
                (0, -sp.sin(sp.atan(f1) / 2), 0, sp.cos(sp.atan(f1) / 2)))

    def _declare_cycloid(self, b: LagrangianBuilder, m: sp.Expr, g: sp.Expr) -> None:
        a = b.param("cycloid_radius")
        if self.formulation == "reduced":
            s, ds = b.coordinate("s", "m")
        else:
            x, dx = b.coordinate("x", "m")
            z, dz = b.coordinate("z", "m")
            s, ds = b.coordinate("s", "m")
        c = s / (4 * a)
        root = sp.sqrt(sp.Max(16 * a**2 - s**2, 0))
        X = a * (2 * sp.acos(c) - 2 * c * sp.sqrt(1 - c**2))
        Z = s**2 / (8 * a)
        # Upward unit normal n = (Z′, −X′) = (s, √(16a² − s²)) / 4a (X′ = −√(16a²−s²)/4a).
        nx, nz = s / (4 * a), root / (4 * a)
        if self.formulation == "reduced":
            b.kinetic = m * ds**2 / 2  # s is arc length: |dr/ds| = 1
            b.potential = m * g * Z
            # N = m (g n_z + κ ṡ²), curvature κ = 1/√(16a² − s²) (guarded at the cusp, ṡ = 0).
            b.observable("normal_force", "N",
                         m * (g * nz + ds**2 / sp.Max(root, sp.Float(1e-150))))
            b.observable("x", "m", X)
            pos = (X, 0, Z)
        else:
            b.kinetic = m * (dx**2 + dz**2) / 2
            b.potential = m * g * z
            b.constraint("wire_x", x - X)
            b.constraint("wire_z", z - Z)
            b.observable("normal_force", "N", b.multiplier(0) * nx + b.multiplier(1) * nz)
            pos = (x, 0, z)
        b.observable("theta", "rad", 2 * sp.acos(c))
        b.event("lowest_point", s, 0, "the bead passes the bottom of the cycloid (s = 0)")
        slope_angle = sp.atan2(-s, root)  # tangent direction angle in the x–z plane
        b.frame("wire", "world", (0, 0, 0))
        b.frame("bead", "wire", pos, (0, -sp.sin(slope_angle / 2), 0, sp.cos(slope_angle / 2)))

    def on_lowest_point(self, t: float, y: np.ndarray) -> np.ndarray:
        return y  # recorded only

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        x0, v0 = self.value("initial.x"), self.value("initial_rate.x")
        shape = str(self.values["shape"])
        if shape == "cycloid":
            a = self.value("cycloid_radius")
            s0 = self._cycloid_arc(x0)
            root = math.sqrt(max(16 * a * a - s0 * s0, 0.0))
            ds0 = 0.0 if root == 0.0 else -v0 * 4 * a / root  # ẋ = X′(s) ṡ
            if self.formulation == "reduced":
                return np.array([s0]), np.array([ds0])
            return (np.array([x0, s0**2 / (8 * a), s0]),
                    np.array([v0, s0 / (4 * a) * ds0, ds0]))
        f, f1 = self.height(x0)
        if self.formulation == "reduced":
            return np.array([x0]), np.array([v0])
        return np.array([x0, f]), np.array([v0, f1 * v0])

    def height(self, x: float) -> tuple[float, float]:
        """(f(x), f′(x)) of a graph wire, numerically."""
        shape = str(self.values["shape"])
        if shape == "line":
            s = self.value("slope")
            return s * x, s
        if shape == "parabola":
            c = self.value("curvature")
            return c * x * x, 2 * c * x
        xs = sp.Symbol("x", real=True)
        f = parse_curve(str(self.values["curve"]))
        return _numeric(f)(x), _numeric(f.diff(xs))(x)

    def laws(self) -> tuple[Law, ...]:
        if self.formulation == "naive":
            # What the document's form claims and violates: listed so that diagnostics flag it.
            return (Law("energy", "energy"), Law("work_balance", "work_balance"),
                    Law("constraint", "constraint_wire"))
        return super().laws()

    def time_scale(self) -> float:
        g = self.value("gravity")
        shape = str(self.values["shape"])
        if shape == "cycloid":
            return 2 * math.pi * math.sqrt(4 * self.value("cycloid_radius") / g)
        if shape == "parabola" and self.value("curvature") > 0:
            return 2 * math.pi / math.sqrt(2 * g * self.value("curvature"))
        return 1.0

    def visuals(self) -> tuple[Visual, ...]:
        shape = str(self.values["shape"])
        if shape == "cycloid":
            a = self.value("cycloid_radius")
            pts = tuple((a * (t - math.sin(t)), 0.0, a * (1 + math.cos(t)))
                        for t in np.linspace(0, 2 * math.pi, 121))
        else:
            x0 = abs(self.value("initial.x")) + 1.0
            pts = tuple((float(x), 0.0, self.height(float(x))[0])
                        for x in np.linspace(-x0, x0, 121))
        return (Visual("polyline", "wire", points=pts, radius=0.01, color=(180, 180, 190)),
                Visual("sphere", "bead", radius=0.05, color=(230, 120, 60)),
                Visual("trail", "bead", color=(120, 170, 255)))


MODEL = BeadOnWire
