"""Systems declared by their Lagrangian; one engine derives everything else.

A system writes T and V in its generalized coordinates, its holonomic constraints g(q, t) = 0,
its Rayleigh dissipation function D(q, q̇, t) and any other generalized forces Q(q, q̇, t). From
that declaration sympy derives, once per declaration (the generated module is cached on disk):

- the mass matrix M = ∂²T/∂q̇², and the forcing f = ∂L/∂q − (∂²L/∂q̇∂q) q̇ − ∂²L/∂q̇∂t − ∂D/∂q̇ + Q
  + u, so that M q̈ = f + Gᵀλ, with G = ∂g/∂q and G q̈ = −γ (the constraints differentiated
  twice). u is the *effort*: one generalized force per coordinate (N for a length, N·m for an
  angle) applied from outside at run time, read from the parameter vector after the numeric
  parameters (``LagrangianModel.effort_slice``; zero unless a caller sets it, as the simulator
  node does from its ``effort`` topic); it enters only the right-hand side (``accel``,
  ``rhs``): the separable and canonical forms, for the symplectic methods, leave it out;
- the energy function h = Σ q̇ ∂L/∂q̇ − L;
- the power balance: dissipated power P_d = Σ q̇ ∂D/∂q̇, and the external power
  P_ext = dE/dt + P_d with dE/dt from the chain rule on E = T + V, so the integrated work terms
  close total − total₀ = W_ext − W_d by construction of the equations, not of the outputs (the
  effort's power u·q̇ is part of P_ext: q̈ includes it);
- constraint projection, invariants, observables (which may use the multipliers λ) and frames;
- the *parameter constants*: every subexpression of these that depends on the parameters alone
  (ω = √(G(m₁ + m₂)/L³), L/M, …) is computed once per parameter vector, into slots after the
  efforts (``_ParameterConstants``), instead of at every call of a kernel;
- state events (``b.event``: a sign change of an expression, which may use λ) with discrete
  modes (``b.mode``: extra state entries an expression may switch on, e.g. a constraint that is
  active only in contact, ``b.constraint(name, g, active=...)``); the model handles each event
  in a method ``on_<event name>(t, y) -> y`` (see ``mechsim.integrators``).

No equation of motion is typed by hand, so no typo of the source documents can reach the code.
"""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass, field
from functools import cached_property
from typing import ClassVar

import numpy as np
import sympy as sp
from sympy.printing.numpy import NumPyPrinter
from sympy.printing.precedence import PRECEDENCE
from sympy.printing.pycode import PythonCodePrinter

from mechsim import codegen
from mechsim.codegen import FUNCTIONS
from mechsim.systems.base import Event, FrameSpec, Law, Model, Quantity, Structure

Expr = sp.Expr

#: Part of every derivation's cache key, with this module's source text: any change to the
#: generator gives new kernel modules (see ``mechsim.codegen``).
GENERATOR_VERSION = 7
_GENERATOR_SOURCE = codegen.source_fingerprint([sys.modules[__name__]])


@dataclass
class _Frame:
    spec: FrameSpec
    translation: tuple[Expr, Expr, Expr]
    rotation: tuple[Expr, Expr, Expr, Expr]


@dataclass
class LagrangianBuilder:
    """What a system's ``declare`` fills in. Symbols: ``t``, coordinates, parameters, λ."""

    model: Model
    t: sp.Symbol = field(default_factory=lambda: sp.Symbol("t", real=True))
    coords: list[Quantity] = field(default_factory=list)
    q: list[sp.Symbol] = field(default_factory=list)
    v: list[sp.Symbol] = field(default_factory=list)
    qdd: list[sp.Symbol] = field(default_factory=list)  # accelerations (``acceleration``)
    efforts: list[sp.Symbol] = field(default_factory=list)  # applied generalized forces u
    kinetic: Expr = sp.Integer(0)
    potential: Expr = sp.Integer(0)
    rayleigh: Expr = sp.Integer(0)
    # Terms of L linear in q̇, Σ aᵢ(q, t) q̇ᵢ, that belong to neither T nor V (magnetic q q̇·A):
    # they enter L (and so the equations and h) but not E = T + V; static ones do no work.
    linear: Expr = sp.Integer(0)
    forces: list[Expr] = field(default_factory=list)
    constraints: list[tuple[str, Expr]] = field(default_factory=list)
    invariants: list[tuple[Quantity, Expr]] = field(default_factory=list)
    observables: list[tuple[Quantity, Expr]] = field(default_factory=list)
    frames: list[_Frame] = field(default_factory=list)
    params: dict[str, sp.Symbol] = field(default_factory=dict)
    active: dict[int, Expr] = field(default_factory=dict)  # constraint index -> activity 0/1
    events: list[tuple[Event, Expr]] = field(default_factory=list)
    modes: list[Quantity] = field(default_factory=list)
    mode_symbols: list[sp.Symbol] = field(default_factory=list)

    def coordinate(self, name: str, unit: str) -> tuple[sp.Symbol, sp.Symbol]:
        """Declare a generalized coordinate; returns (q, q̇) symbols."""
        q = sp.Symbol(f"q_{name}", real=True)
        v = sp.Symbol(f"v_{name}", real=True)
        self.coords.append(Quantity(name, unit))
        self.q.append(q)
        self.v.append(v)
        self.qdd.append(sp.Symbol(f"qdd_{name}", real=True))
        self.efforts.append(sp.Symbol(f"effort_{name}", real=True))
        return q, v

    def acceleration(self, coordinate: sp.Symbol) -> sp.Symbol:
        """q̈ of a declared coordinate (given by its symbol q), for observables and events that
        depend on the accelerations (e.g. a string tension m (g − R φ̈)): the generated kernel
        solves the equations of motion for it where such an expression is evaluated."""
        if coordinate not in self.q:
            raise KeyError(f"{coordinate} is not a declared coordinate")
        return self.qdd[self.q.index(coordinate)]

    def param(self, name: str) -> sp.Symbol:
        """The symbol of a numeric parameter (its value is read from the parameter vector)."""
        spec = {p.name: p for p in self.model.parameter_spec()}
        if name not in spec or not spec[name].is_numeric:
            raise KeyError(f"{type(self.model).__name__} has no numeric parameter {name!r}")
        if name not in self.params:
            p = spec[name]
            positive = p.minimum is not None and p.minimum >= 0 and p.exclusive_minimum
            self.params[name] = sp.Symbol("p_" + name.replace(".", "_"), real=True,
                                          positive=positive or None)
        return self.params[name]

    def multiplier(self, index: int) -> sp.Symbol:
        """λ of constraint ``index``: M q̈ = f + Gᵀλ, so λ·∂g/∂q is the constraint force."""
        return sp.Symbol(f"lam_{index}", real=True)

    def constraint(self, name: str, g: Expr, active: Expr | None = None) -> None:
        """Holonomic constraint g(q, t) = 0; its residual is published as constraint_<name>.

        ``active``: an expression of the modes that is 1 where the constraint holds and 0 where
        it is released (then its λ is 0 and its published residual is 0); None: always."""
        if active is not None:
            self.active[len(self.constraints)] = sp.sympify(active)
        self.constraints.append((name, g))

    def mode(self, name: str) -> sp.Symbol:
        """Declare a discrete mode entry of the state (constant between events, set by the
        model's event handlers; initial value from ``initial_modes``); returns its symbol."""
        sym = sp.Symbol(f"mode_{name}", real=True)
        self.modes.append(Quantity(name))
        self.mode_symbols.append(sym)
        return sym

    def event(self, name: str, expr: Expr, direction: int = 0, description: str = "") -> None:
        """A state event where ``expr`` (of t, q, q̇, modes, λ) changes sign in ``direction``
        (+1 rising, −1 falling, 0 either); the model's method ``on_<name>(t, y) -> y`` is
        called there."""
        if direction not in (-1, 0, 1):
            raise ValueError(f"event {name}: direction must be -1, 0 or +1")
        self.events.append((Event(name, direction, description), sp.sympify(expr)))

    def invariant(self, name: str, unit: str, expr: Expr) -> None:
        self.invariants.append((Quantity(name, unit), expr))

    def observable(self, name: str, unit: str, expr: Expr) -> None:
        self.observables.append((Quantity(name, unit), expr))

    def frame(self, child: str, parent: str, translation: tuple[Expr, Expr, Expr],
              rotation: tuple[Expr, Expr, Expr, Expr] | None = None) -> None:
        """A frame's pose in its parent; rotation is a quaternion (x, y, z, w), identity if None."""
        rot = rotation or (sp.Integer(0), sp.Integer(0), sp.Integer(0), sp.Integer(1))
        tr = tuple(sp.sympify(c) for c in translation)
        ro = tuple(sp.sympify(c) for c in rot)
        free = set().union(*(e.free_symbols for e in tr + ro))
        static = not (free & (set(self.q) | set(self.v) | {self.t}))
        self.frames.append(_Frame(FrameSpec(child, parent, static), tr, ro))  # type: ignore[arg-type]


class LagrangianModel(Model):
    """A model whose equations come from ``declare``; see the module docstring."""

    declaration_version: ClassVar[int] = 1

    def declare(self, b: LagrangianBuilder) -> None:
        raise NotImplementedError

    @cached_property
    def declaration(self) -> LagrangianBuilder:
        b = LagrangianBuilder(self)
        self.declare(b)
        return b

    @cached_property
    def coordinates(self) -> tuple[Quantity, ...]:
        return tuple(self.declaration.coords)

    @cached_property
    def invariants(self) -> tuple[Quantity, ...]:
        d = self.declaration
        return tuple(q for q, _ in d.invariants) + tuple(
            Quantity(f"constraint_{name}", "") for name, _ in d.constraints)

    @cached_property
    def observables(self) -> tuple[Quantity, ...]:
        return tuple(q for q, _ in self.declaration.observables)

    @cached_property
    def frames(self) -> tuple[FrameSpec, ...]:
        return tuple(f.spec for f in self.declaration.frames)

    @cached_property
    def events(self) -> tuple[Event, ...]:
        return tuple(e for e, _ in self.declaration.events)

    @cached_property
    def modes(self) -> tuple[Quantity, ...]:
        return tuple(self.declaration.modes)

    @cached_property
    def structure(self) -> Structure:
        d = self.declaration
        qs, vs, t = set(d.q), set(d.v), d.t
        M = sp.hessian(d.kinetic, d.v)
        constant_mass = not (M.free_symbols & (qs | vs | {t}))
        time_dep = t in (d.kinetic.free_symbols | d.potential.free_symbols
                         | sp.sympify(d.linear).free_symbols) or any(
            t in g.free_symbols for _, g in d.constraints)
        dissipative = d.rayleigh != 0
        driven = any(f != 0 for f in d.forces)
        separable = (constant_mass and not d.constraints and not dissipative and not driven
                     and d.linear == 0
                     and not time_dep and not (d.potential.free_symbols & vs)
                     and not (d.kinetic.free_symbols & qs)
                     and (len(d.q) <= 4 or M.is_diagonal()))
        return Structure(separable=separable, n_constraints=len(d.constraints),
                         dissipative=dissipative, driven=driven, time_dependent=time_dep)

    @cached_property
    def kernels(self) -> codegen.Kernels:
        """Built once per declaration: derived and compiled on the first use on a machine,
        imported from the cache afterwards (see ``derivation_key``)."""
        return codegen.build(f"{self.id}_{self.formulation}", self.derivation_key(),
                             self.kernel_source)

    def _param_index(self) -> dict[str, int]:
        numeric = [p.name for p in self.parameter_spec() if p.is_numeric]
        return {name: i for i, name in enumerate(numeric)}

    def effort_slice(self) -> slice:
        """Where the effort u (one generalized force per coordinate) sits in the parameter
        vector: after the numeric parameters. Not a parameter of the system: no name, no
        range, not in ``parameter_spec`` (so not a ROS or scene parameter)."""
        start = len(self._param_index())
        return slice(start, start + len(self.declaration.coords))

    def _make_parameter_vector(self) -> np.ndarray:
        """The numeric parameters, the efforts (zero) and the parameter constants."""
        p = super()._make_parameter_vector()
        return self.complete_parameters(np.concatenate([p, np.zeros(self.kernels.n_p - p.size)]))

    def complete_parameters(self, p: np.ndarray) -> np.ndarray:
        """``p`` (a copy) with its parameter constants computed afresh from its parameters."""
        p = super().complete_parameters(p)
        self.kernels.module.parameter_constants(p)
        return p

    def derivation_key(self) -> str:
        """Every input of the derivation: the declaration (expressions with their symbols'
        assumptions, names, events, modes), where each parameter sits in ``p`` (the index map
        the generated code bakes in), and the generator (its version and source text)."""
        d = self.declaration
        return codegen.fingerprint(
            GENERATOR_VERSION, _GENERATOR_SOURCE, type(self).__qualname__,
            self.declaration_version, self.formulation, sorted(self._param_index().items()),
            [(c.name, c.unit) for c in d.coords],
            sp.srepr(d.kinetic), sp.srepr(d.potential), sp.srepr(d.rayleigh),
            sp.srepr(d.linear), [sp.srepr(f) for f in d.forces],
            [(n, sp.srepr(g)) for n, g in d.constraints],
            [(q.name, sp.srepr(e)) for q, e in d.invariants],
            [(q.name, sp.srepr(e)) for q, e in d.observables],
            [(f.spec, [sp.srepr(e) for e in f.translation + f.rotation]) for f in d.frames],
            [(e, sp.srepr(x)) for e, x in d.events],
            [(k, sp.srepr(a)) for k, a in sorted(d.active.items())],
            [q.name for q in d.modes], sorted((k, sp.srepr(v)) for k, v in d.params.items()))

    def kernel_source(self) -> codegen.KernelSource:
        """Derive the kernel functions (sympy; about a second for most systems)."""
        d = self.declaration
        body, functions, n_constants = _derive(d, self._param_index(), self.structure)
        n = len(d.q)
        return codegen.KernelSource(
            name=f"{self.id}_{self.formulation}", functions=functions, body=body, constants={
                "N_Q": n, "N_Y": 2 * n + 2 + len(d.modes), "N_C": len(d.constraints),
                "N_INV": len(self.invariants), "N_OBS": len(self.observables),
                "N_FRAMES": len(d.frames), "N_EV": len(d.events), "N_MODE": len(d.modes),
                "N_P": self.effort_slice().stop + n_constants})

    @cached_property
    def _canonical(self) -> bool:
        return _canonical_ok(self.declaration, self.structure)

    def has_canonical_form(self) -> bool:
        return self._canonical

    def energy_function_conserved(self) -> bool:
        d = self.declaration
        L = d.kinetic - d.potential + d.linear
        return (d.t not in L.free_symbols and d.rayleigh == 0
                and not any(f != 0 for f in d.forces)
                and not any(d.t in g.free_symbols for _, g in d.constraints))

    def laws(self) -> tuple[Law, ...]:
        laws = list(super().laws())
        if self.energy_function_conserved():
            laws.insert(1 if laws[0].kind == "energy" else 0,
                        Law("energy_function", "energy_function"))
        return tuple(laws)


# ---------------------------------------------------------------------------------------------
# Derivation and code printing


#: Largest |n| of an integer power x**n written out as products (``_binary_power``).
POWER_PRODUCT_MAX = 16


def _binary_power(base: str, n: int) -> str:
    """``base**n`` (n ≥ 1) written out as the products numba evaluates for it: repeated
    squaring, the powers of the set bits of n multiplied in increasing order (numba's
    ``int_power``), so the value is the same to the last bit. Numba compiles ``int_power`` as
    a subroutine in every process that compiles a kernel using ``**`` (about 0.1 s)."""
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


#: Functions a parameter constant may contain: those numpy evaluates as the kernels do.
_CONSTANT_FUNCTIONS = (sp.sin, sp.cos, sp.tan, sp.asin, sp.acos, sp.atan, sp.atan2, sp.sinh,
                       sp.cosh, sp.tanh, sp.exp, sp.log, sp.Abs)


class _ParameterConstants:
    """The parameter constants of one derivation: subexpressions of the kernels in the
    parameters and numbers alone, each replaced by a symbol ``pc_<i>`` that the kernels load
    from ``p[first + i]`` like a parameter. The kernel module's ``parameter_constants(p)``
    (plain Python on numpy scalars, so the same IEEE results as the compiled kernels: a
    division by zero gives inf, not an exception) fills those slots from the parameters;
    ``LagrangianModel.complete_parameters`` calls it for every parameter vector."""

    def __init__(self, params: dict[str, sp.Symbol], pindex: dict[str, int], first: int
                 ) -> None:
        self.params = params
        self.pindex = pindex
        self.symbols = set(params.values())
        self.first = first
        self.found: dict[Expr, sp.Symbol] = {}
        self._pure: dict[Expr, bool] = {}

    def is_constant(self, e: Expr) -> bool:
        """Parameters and numbers only, in forms numpy evaluates."""
        known = self._pure.get(e)
        if known is None:
            if e.is_Atom:
                known = bool(e.is_number or e in self.symbols)
            else:
                known = bool((e.is_Add or e.is_Mul or e.is_Pow
                              or isinstance(e, _CONSTANT_FUNCTIONS))
                             and all(self.is_constant(a) for a in e.args))
            self._pure[e] = known
        return known

    def _symbol(self, e: Expr) -> sp.Symbol:
        if e not in self.found:
            self.found[e] = sp.Symbol(f"pc_{len(self.found)}", real=True)
        return self.found[e]

    def hoist(self, e: Expr) -> Expr:
        """``e`` with its largest constant subexpressions replaced by their symbols (the
        constant terms of a sum, and factors of a product, taken together)."""
        if e.is_Atom or not e.args:
            return e
        if self.is_constant(e):
            return self._symbol(e) if e.free_symbols else e
        if e.is_Add or e.is_Mul:
            const = [a for a in e.args if self.is_constant(a)]
            if len(const) >= 2 and any(a.free_symbols for a in const):
                rest = [self.hoist(a) for a in e.args if not self.is_constant(a)]
                return e.func(self._symbol(e.func(*const)), *rest)
        return e.func(*[self.hoist(a) for a in e.args])

    def loads(self) -> list[str]:
        return [f"    {s.name} = p[{self.first + i}]" for i, s in enumerate(self.found.values())]

    def source(self) -> str:
        """``parameter_constants(p)``: fills p[first:] from the parameters, in place."""
        pr = NumPyPrinter({"fully_qualified_modules": True})
        lines = ["def parameter_constants(p):",
                 '    """The parameter constants (``_ParameterConstants``) into p, in place."""',
                 '    with numpy.errstate(all="ignore"):']
        lines += [f"        {sym.name} = p[{self.pindex[name]}]"
                  for name, sym in self.params.items()]
        lines += [f"        p[{self.first + i}] = {pr.doprint(e)}"
                  for i, e in enumerate(self.found)]
        if not self.found:
            lines[2:] = ["    return"]
        return "\n".join(["import numpy", "", "", *lines, ""])


def _emit(assign: list[tuple[str, Expr]], indent: str = "    ",
          constants: _ParameterConstants | None = None) -> list[str]:
    """Common-subexpression-eliminated assignments ``target = expr`` (with ``constants``:
    after their parameter constants are taken out)."""
    if not assign:
        return []
    pr = _printer()
    targets = [a for a, _ in assign]
    exprs = [sp.sympify(e) for _, e in assign]
    repl, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("c_"), optimizations="basic")
    if constants is not None:
        # After cse, so what it shares stays shared (the damping power of dE and P_diss is
        # one value: W_ext of an undriven system stays exactly 0); a shared subexpression
        # in the parameters alone goes back into its users, to be taken out whole with them.
        known: dict[sp.Symbol, Expr] = {}
        kept: list[tuple[sp.Symbol, Expr]] = []
        for sym, e in repl:
            e = e.xreplace(known)
            if constants.is_constant(e) and e.free_symbols:
                known[sym] = e
            else:
                kept.append((sym, constants.hoist(e)))
        repl = kept
        reduced = [constants.hoist(e.xreplace(known)) for e in reduced]
    lines = [f"{indent}{s} = {pr.doprint(e)}" for s, e in repl]
    lines += [f"{indent}{tgt} = {pr.doprint(e)}" for tgt, e in zip(targets, reduced, strict=True)]
    return lines


#: Largest unconstrained system whose mass matrix is solved in generated scalar code (LDLᵀ:
#: no array, no allocation per call); a larger one, or a constrained one (its saddle-point
#: matrix is indefinite), goes through ``_solve`` (Gaussian elimination, partial pivoting).
SCALAR_SOLVE_MAX = 8


def _ldl_solve(M: sp.Matrix, f: list[Expr], x: list[str],
               constants: _ParameterConstants | None = None) -> list[str]:
    """Lines setting the scalars ``x`` to the solution of M x = f, M symmetric positive
    definite (a mass matrix), by LDLᵀ without pivoting (stable for such M); entries of M that
    are identically zero are left out of the arithmetic."""
    n = len(x)
    m = {(i, j): f"m_{i}_{j}" for i in range(n) for j in range(i + 1) if M[i, j] != 0}
    lines = _emit([(name, M[i, j]) for (i, j), name in m.items()]
                  + [(f"f_{i}", f[i]) for i in range(n)], constants=constants)
    L: dict[tuple[int, int], str] = {}  # nonzero entries below the diagonal
    for j in range(n):
        terms = [f"{L[j, k]} * {L[j, k]} * d_{k}" for k in range(j) if (j, k) in L]
        lines.append(f"    d_{j} = {m.get((j, j), '0.0')}" + "".join(f" - {t}" for t in terms))
        for i in range(j + 1, n):
            terms = [f"{L[i, k]} * {L[j, k]} * d_{k}" for k in range(j)
                     if (i, k) in L and (j, k) in L]
            if (i, j) in m or terms:
                L[i, j] = f"l_{i}_{j}"
                lines.append(f"    l_{i}_{j} = ({m.get((i, j), '0.0')}"
                             + "".join(f" - {t}" for t in terms) + f") / d_{j}")
    for i in range(n):  # L z = f, then Lᵀ x = z / d
        lines.append(f"    z_{i} = f_{i}" + "".join(f" - {L[i, k]} * z_{k}" for k in range(i)
                                                     if (i, k) in L))
    for i in reversed(range(n)):
        lines.append(f"    {x[i]} = z_{i} / d_{i}" + "".join(
            f" - {L[k, i]} * {x[k]}" for k in range(i + 1, n) if (k, i) in L))
    return lines


def _prelude(d: LagrangianBuilder, pindex: dict[str, int], with_v: bool = True,
             q_name: str = "y") -> list[str]:
    lines = ["    t = t"]
    n = len(d.q)
    for i, qs in enumerate(d.q):
        lines.append(f"    {qs.name} = {q_name}[{i}]")
    if with_v:
        for i, vs in enumerate(d.v):
            lines.append(f"    {vs.name} = y[{n + i}]")
        for i, ms in enumerate(d.mode_symbols):
            lines.append(f"    {ms.name} = y[{2 * n + 2 + i}]")
    for name, sym in d.params.items():
        lines.append(f"    {sym.name} = p[{pindex[name]}]")
    for i, u in enumerate(d.efforts):  # after the parameters: LagrangianModel.effort_slice
        lines.append(f"    {u.name} = p[{len(pindex) + i}]")
    return lines


#: A load of one entry of an argument array into a local (what ``_prelude`` writes).
_LOAD = re.compile(r"    (\w+) = [ypqz]\[\d+\]")


def _func(name: str, args: str, body: list[str]) -> str:
    """The source of kernel function ``name``: ``body`` without the loads of arguments it
    never reads (every function starts from the same prelude; numba would type and lower each
    dead load before LLVM drops it)."""
    loads = [_LOAD.fullmatch(line) for line in body]
    read = set(re.findall(r"\w+", "\n".join(
        line for line, load in zip(body, loads, strict=True) if not load)))
    kept = [line for line, load in zip(body, loads, strict=True)
            if line != "    t = t" and (load is None or load.group(1) in read)]
    return "\n".join([codegen.decorator(name), f"def {name}({args}):", *kept, "    return", ""])


def _canonical_ok(d: LagrangianBuilder, st: Structure) -> bool:
    """Hamilton's equations are generated (for Gauss–Legendre) when the system is unconstrained,
    event-free, undriven, undamped, has no explicit time dependence and T is homogeneous
    quadratic in the rates — then E = T + V equals h and is conserved, so the work terms stay
    zero (a rotating-coordinate T with ω² terms, where the motor works, is excluded)."""
    if d.constraints or d.events or d.modes or st.dissipative or st.driven or st.time_dependent:
        return False
    v = sp.Matrix(d.v)
    M = sp.hessian(d.kinetic, d.v)
    return sp.expand(d.kinetic - (v.T * M * v)[0, 0] / 2) == 0


def _derive(d: LagrangianBuilder, pindex: dict[str, int], st: Structure
            ) -> tuple[str, tuple[str, ...], int]:
    """The kernel module body, the contract functions it defines (those it leaves out are
    no-ops: no constraints, not separable, no canonical form, no events, nothing to output)
    and the number of parameter constants (in p after the efforts)."""
    n, nc = len(d.q), len(d.constraints)
    hoist = _ParameterConstants(d.params, pindex, len(pindex) + len(d.efforts))

    def emit(assign: list[tuple[str, Expr]], indent: str = "    ") -> list[str]:
        return _emit(assign, indent, hoist)

    def func(name: str, args: str, body: list[str]) -> str:
        return _func(name, args, hoist.loads() + body)  # (loads it does not read are dropped)

    t, q, v = d.t, sp.Matrix(d.q), sp.Matrix(d.v)
    T, V, D = d.kinetic, d.potential, d.rayleigh
    L = T - V + d.linear
    dL_dv = sp.Matrix([sp.diff(L, vi) for vi in d.v])
    M = sp.hessian(T, d.v)
    forces = list(d.forces) + [sp.Integer(0)] * (n - len(d.forces))
    f0 = sp.Matrix([  # without the effort u (f = f0 + u)
        sp.diff(L, d.q[i]) - sum(sp.diff(dL_dv[i], d.q[j]) * d.v[j] for j in range(n))
        - sp.diff(dL_dv[i], t) - sp.diff(D, d.v[i]) + forces[i] for i in range(n)])
    f = f0 + sp.Matrix(d.efforts)
    g = sp.Matrix([c for _, c in d.constraints]) if nc else sp.zeros(0, 1)
    G = g.jacobian(q) if nc else sp.zeros(0, n)
    g_t = sp.diff(g, t) if nc else sp.zeros(0, 1)
    gdot = (G * v + g_t) if nc else sp.zeros(0, 1)
    gamma = (gdot.jacobian(q) * v + sp.diff(gdot, t)) if nc else sp.zeros(0, 1)
    E = T + V
    h = (v.T * dL_dv)[0, 0] - L
    P_diss = sum(d.v[i] * sp.diff(D, d.v[i]) for i in range(n)) if D != 0 else sp.Integer(0)
    a_syms = d.qdd
    a_names = [a.name for a in a_syms]
    dE = sp.diff(E, t) + sum(sp.diff(E, d.q[i]) * d.v[i] + sp.diff(E, d.v[i]) * a_syms[i]
                             for i in range(n))
    lam = [d.multiplier(k) for k in range(nc)]
    active = d.active
    act = [active.get(k, sp.Integer(1)) for k in range(nc)]

    out: list[str] = []
    pre = _prelude(d, pindex)
    # accel(t, y, p, a, lam): M a = f + Gᵀ λ, G a = −γ
    body = list(pre)
    diagonal = nc == 0 and M.is_diagonal()
    accel_exprs: list[Expr] = []
    if diagonal:
        # simplify only small quotients: on large ones (rational functions of square roots)
        # its cancel() step can take hours; cse in _emit still shares the work.
        accel_exprs = [sp.simplify(f0[i] / M[i, i]) if sp.count_ops(f0[i] / M[i, i]) <= 40
                       else f0[i] / M[i, i] for i in range(n)]
        # The effort's share u/M is added apart (own cse pass), so without an effort every
        # expression evaluates exactly as without the input (W_ext of a free or damped
        # system stays exactly 0).
        effort_accel = [d.efforts[i] / M[i, i] for i in range(n)]
        body += emit([(f"a[{i}]", accel_exprs[i]) for i in range(n)])
        body += emit([(f"ua_{i}", effort_accel[i]) for i in range(n)])
        body += [f"    a[{i}] += ua_{i}" for i in range(n)]
    elif nc == 0 and n <= SCALAR_SOLVE_MAX:
        body += _ldl_solve(M, [f[i] for i in range(n)], [f"x_{i}" for i in range(n)], hoist)
        body += [f"    a[{i}] = x_{i}" for i in range(n)]
    else:
        m = n + nc
        body.append(f"    A = _zero_matrix({m}, {m})")
        body.append(f"    b = _vector({m})")
        assign: list[tuple[str, Expr]] = []
        for i in range(n):
            for j in range(n):
                if M[i, j] != 0:
                    assign.append((f"A[{i}, {j}]", M[i, j]))
            assign.append((f"b[{i}]", f[i]))
        for k in range(nc):
            for j in range(n):
                if G[k, j] != 0:
                    assign.append((f"A[{n + k}, {j}]", act[k] * G[k, j]))
                    assign.append((f"A[{j}, {n + k}]", -act[k] * G[k, j]))
            if k in active:  # released: the row reads λ_k = 0
                assign.append((f"A[{n + k}, {n + k}]", 1 - act[k]))
            assign.append((f"b[{n + k}]", -act[k] * gamma[k]))
        body += emit(assign)
        body.append("    x = _solve(A, b)")
        body += [f"    a[{i}] = x[{i}]" for i in range(n)]
        body += [f"    lam[{k}] = x[{n + k}]" for k in range(nc)]
    out.append(func("accel", "t, y, p, a, lam", body))

    # rhs: without constraints the accelerations are written inline (no array allocation
    # per call; a full mass matrix solved in scalars up to SCALAR_SOLVE_MAX coordinates);
    # otherwise through accel's linear solve.
    if diagonal:
        dE_inline = dE.subs(dict(zip(a_syms, accel_exprs, strict=True)))
        P_u = sum(sp.diff(E, d.v[i]) * effort_accel[i] for i in range(n))  # dE's effort part
        body = list(pre) + emit([(a_names[i], accel_exprs[i]) for i in range(n)]
                                + [("P_diss", P_diss), ("dE", dE_inline)])
        body += emit([(f"ua_{i}", effort_accel[i]) for i in range(n)] + [("P_u", P_u)])
        body += [f"    {a_names[i]} = {a_names[i]} + ua_{i}" for i in range(n)]
        external = "dE + P_diss + P_u"
    elif nc == 0 and n <= SCALAR_SOLVE_MAX:
        body = list(pre) + _ldl_solve(M, [f[i] for i in range(n)], a_names, hoist)
        body += emit([("P_diss", P_diss), ("dE", dE)])
        external = "dE + P_diss"
    else:
        body = [f"    lam = _vector({max(nc, 1)})", f"    acc = _vector({n})",
                "    accel(t, y, p, acc, lam)"]
        body += pre
        body += [f"    {a_names[i]} = acc[{i}]" for i in range(n)]
        body += emit([("P_diss", P_diss), ("dE", dE)])
        external = "dE + P_diss"
    body += [f"    dy[{i}] = y[{n + i}]" for i in range(n)]
    body += [f"    dy[{n + i}] = {a_names[i]}" for i in range(n)]
    body += [f"    dy[{2 * n}] = {external}", f"    dy[{2 * n + 1}] = P_diss"]
    out.append(func("rhs", "t, y, p, dy", body))

    # project
    if nc:
        body = list(pre)
        body[1:1 + n] = []  # q read inside the loop
        body += [f"    G = _matrix({nc}, {n})", f"    r = _vector({nc})",
                 f"    qq = y[0:{n}]", f"    vv = y[{n}:{2 * n}]", "    for _it in range(6):"]
        inner = [f"        {qs.name} = qq[{i}]" for i, qs in enumerate(d.q)]
        inner += emit([(f"r[{k}]", act[k] * g[k]) for k in range(nc)]
                      + [(f"G[{k}, {j}]", act[k] * G[k, j]) for k in range(nc)
                         for j in range(n)],
                      indent="        ")
        inner += ["        _project_onto(G, r, qq)",
                  "        if _all_below(r, 1e-15):", "            break"]
        body += inner
        body += [f"    {qs.name} = qq[{i}]" for i, qs in enumerate(d.q)]
        body += [f"    {vs.name} = vv[{i}]" for i, vs in enumerate(d.v)]
        body += emit([(f"r[{k}]", act[k] * gdot[k]) for k in range(nc)]
                     + [(f"G[{k}, {j}]", act[k] * G[k, j]) for k in range(nc)
                        for j in range(n)])
        body += ["    _project_onto(G, r, vv)"]
        out.append(func("project", "t, y, p", body))

    # accel_q for separable systems
    if st.separable:
        Minv = M.inv()
        gradV = sp.Matrix([sp.diff(V, qi) for qi in d.q])
        acc = Minv * (-gradV)
        body = _prelude(d, pindex, with_v=False, q_name="q")
        body += emit([(f"a[{i}]", sp.simplify(acc[i])) for i in range(n)])
        out.append(func("accel_q", "t, q, p, a", body))

    # canonical form (conservative, unconstrained, no events): z = [q, p = ∂L/∂q̇, ...]
    if _canonical_ok(d, st):
        b0 = dL_dv.subs({vi: 0 for vi in d.v})
        p_syms = [sp.Symbol(f"pm_{i}", real=True) for i in range(n)]
        zpre = ["    t = t"] + [f"    {qs.name} = z[{i}]" for i, qs in enumerate(d.q)]
        zpre += [f"    pm_{i} = z[{n + i}]" for i in range(n)]
        zpre += [f"    {sym.name} = p[{pindex[name]}]" for name, sym in d.params.items()]
        if M.is_diagonal():
            vel = emit([(vs.name, (p_syms[i] - b0[i]) / M[i, i])
                        for i, vs in enumerate(d.v)])
        else:
            vel = [f"    A = _zero_matrix({n}, {n})", f"    b = _vector({n})"]
            vel += emit([(f"A[{i}, {j}]", M[i, j]) for i in range(n) for j in range(n)
                         if M[i, j] != 0] + [(f"b[{i}]", p_syms[i] - b0[i]) for i in range(n)])
            vel += ["    x = _solve(A, b)"] + [f"    {vs.name} = x[{i}]"
                                                for i, vs in enumerate(d.v)]
        body = list(pre) + emit([(f"z[{n + i}]", dL_dv[i]) for i in range(n)])
        body += [f"    z[{i}] = y[{i}]" for i in range(n)]
        body += [f"    for k in range({2 * n}, y.size):", "        z[k] = y[k]"]
        out.append(func("to_momenta", "t, y, p, z", body))
        body = list(zpre) + vel
        body += [f"    y[{i}] = z[{i}]" for i in range(n)]
        body += [f"    y[{n + i}] = {vs.name}" for i, vs in enumerate(d.v)]
        body += [f"    for k in range({2 * n}, z.size):", "        y[k] = z[k]"]
        out.append(func("from_momenta", "t, z, p, y", body))
        dL_dq = [sp.diff(L, qi) for qi in d.q]
        body = list(zpre) + vel + emit([(f"dz[{n + i}]", dL_dq[i]) for i in range(n)])
        body += [f"    dz[{i}] = {vs.name}" for i, vs in enumerate(d.v)]
        body += [f"    for k in range({2 * n}, z.size):", "        dz[k] = 0.0"]
        out.append(func("canonical_rhs", "t, z, p, dz", body))

    # energy
    body = list(pre) + emit([("out[0]", T), ("out[1]", V), ("out[2]", h)])
    out.append(func("energy", "t, y, p, out", body))

    # invariants (declared ones, then constraint residuals)
    inv = [e for _, e in d.invariants] + [a * c for a, (_, c) in zip(act, d.constraints,
                                                                      strict=True)]
    if inv:
        body = list(pre) + emit([(f"out[{i}]", e) for i, e in enumerate(inv)])
        out.append(func("invariants", "t, y, p, out", body))

    # observables (may use the multipliers)
    obs = [e for _, e in d.observables]
    body = list(pre)
    uses_lam = any(set(lam) & e.free_symbols for e in obs)
    if uses_lam or any(set(a_syms) & e.free_symbols for e in obs):
        body += [f"    lam = _vector({max(nc, 1)})", f"    acc = _vector({n})",
                 "    accel(t, y, p, acc, lam)"]
        body += [f"    lam_{k} = lam[{k}]" for k in range(nc)]
        body += [f"    {a_names[i]} = acc[{i}]" for i in range(n)]
    if obs:
        body += emit([(f"out[{i}]", e) for i, e in enumerate(obs)])
        out.append(func("observables", "t, y, p, out", body))

    # events (may use the multipliers, like observables)
    evx = [e for _, e in d.events]
    body = list(pre)
    if any((set(lam) | set(a_syms)) & e.free_symbols for e in evx):
        body += [f"    lam = _vector({max(nc, 1)})", f"    acc = _vector({n})",
                 "    accel(t, y, p, acc, lam)"]
        body += [f"    lam_{k} = lam[{k}]" for k in range(nc)]
        body += [f"    {a_names[i]} = acc[{i}]" for i in range(n)]
    if evx:
        body += emit([(f"out[{i}]", e) for i, e in enumerate(evx)])
        out.append(func("event", "t, y, p, out", body))

    # frames
    assign = []
    for k, fr in enumerate(d.frames):
        for c, e in enumerate(fr.translation + fr.rotation):
            assign.append((f"out[{k}, {c}]", e))
    if assign:
        out.append(func("frames", "t, y, p, out", list(pre) + emit(assign)))
    functions = tuple(name for name in FUNCTIONS
                      if any(text.startswith(f"{codegen.decorator(name)}\ndef {name}(")
                             for text in out))
    out.append(hoist.source())
    return "\n\n".join(out), functions, len(hoist.found)

