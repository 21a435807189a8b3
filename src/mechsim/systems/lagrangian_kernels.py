"""How a Lagrangian declaration (``mechsim.systems.lagrangian``) becomes the source of its kernel
module: the equations of motion, the power balance, the projections, the canonical form and the
outputs, derived with sympy, common subexpressions shared (``_emit``), parameter constants
taken out (``_ParameterConstants``) and printed as numba kernels (``kernel_printer``).

Imported only to derive a model missing from the cache (``LagrangianModel.kernel_source``);
this module's text is part of every derivation's cache key (``GENERATOR_SOURCE``).
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

import sympy as sp
from sympy.printing.numpy import NumPyPrinter

from mechsim import codegen
from mechsim.codegen import ARGUMENTS, FUNCTIONS
from mechsim.systems.base import Structure
from mechsim.systems.kernel_printer import _printer
from mechsim.systems.layout import ParameterLayout

if TYPE_CHECKING:
    from sympy import Expr

    from mechsim.systems.declaration import LagrangianBuilder

#: Functions a parameter constant may contain: those numpy evaluates as the kernels do.
_CONSTANT_FUNCTIONS = (sp.sin, sp.cos, sp.tan, sp.asin, sp.acos, sp.atan, sp.atan2, sp.sinh,
                       sp.cosh, sp.tanh, sp.exp, sp.log, sp.Abs)


class _ParameterConstants:
    """The parameter constants of one derivation: subexpressions of the kernels in the
    parameters and numbers alone, each replaced by a symbol ``pc_<i>`` that the kernels load
    from ``p[layout.constant(i)]`` like a parameter. The kernel module's ``parameter_constants(p)``
    (plain Python on numpy scalars, so the same IEEE results as the compiled kernels: a
    division by zero gives inf, not an exception) fills those slots from the parameters;
    ``LagrangianModel.complete_parameters`` calls it for every parameter vector."""

    def __init__(self, params: dict[str, sp.Symbol], layout: ParameterLayout) -> None:
        self.params = params
        self.layout = layout
        self.symbols = set(params.values())
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
        return [f"    {s.name} = p[{self.layout.constant(i)}]"
                for i, s in enumerate(self.found.values())]

    def source(self) -> str:
        """``parameter_constants(p)``: fills p[first:] from the parameters, in place."""
        pr = NumPyPrinter({"fully_qualified_modules": True})
        lines = ["def parameter_constants(p):",
                 '    """The parameter constants (``_ParameterConstants``) into p, in place."""',
                 '    with numpy.errstate(all="ignore"):']
        lines += [f"        {sym.name} = p[{self.layout.index(name)}]"
                  for name, sym in self.params.items()]
        lines += [f"        p[{self.layout.constant(i)}] = {pr.doprint(e)}"
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


def _prelude(d: LagrangianBuilder, layout: ParameterLayout, with_v: bool = True,
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
        lines.append(f"    {sym.name} = p[{layout.index(name)}]")
    for i, u in enumerate(d.efforts):
        lines.append(f"    {u.name} = p[{layout.effort(i)}]")
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
    if d.constraints or d.velocity_constraints or d.events or d.modes or st.dissipative \
            or st.driven or st.time_dependent:
        return False
    v = sp.Matrix(d.v)
    M = sp.hessian(d.kinetic, d.v)
    return sp.expand(d.kinetic - (v.T * M * v)[0, 0] / 2) == 0



class _Derivation:
    """The kernel functions of one declaration, derived and printed in order (``source``).
    Each function printed is recorded as it is written (``_func``): the derivation knows which
    functions of the contract it defined; those it leaves out are no-ops (no constraints, not
    separable, no canonical form, no events, nothing to output)."""

    def __init__(self, d: LagrangianBuilder, layout: ParameterLayout, st: Structure,
                 hamiltonian: bool = False) -> None:
        self.d, self.layout, self.st, self.hamiltonian = d, layout, st, hamiltonian
        self.n, self.nc = n, nc = len(d.q), len(d.constraints)
        # The velocity constraints c = A q̇ + b = 0 follow the holonomic ones in every
        # constrained solve and projection (rows G, then A; multipliers λ, then μ).
        self.nv = nv = len(d.velocity_constraints)
        self.nm = nc + nv
        self.hoist = _ParameterConstants(d.params, layout)
        self.parts: list[str] = []
        self.defined: set[str] = set()
        t, q, v = d.t, sp.Matrix(d.q), sp.Matrix(d.v)
        self.L = L = d.kinetic - d.potential + d.linear
        self.dL_dv = dL_dv = sp.Matrix([sp.diff(L, vi) for vi in d.v])
        self.M = sp.hessian(d.kinetic, d.v)
        forces = list(d.forces) + [sp.Integer(0)] * (n - len(d.forces))
        self.f0 = f0 = sp.Matrix([  # without the effort u (f = f0 + u)
            sp.diff(L, d.q[i]) - sum(sp.diff(dL_dv[i], d.q[j]) * d.v[j] for j in range(n))
            - sp.diff(dL_dv[i], t) - sp.diff(d.rayleigh, d.v[i]) + forces[i]
            for i in range(n)])
        self.f = f0 + sp.Matrix(d.efforts)
        self.g = g = sp.Matrix([c for _, c in d.constraints]) if nc else sp.zeros(0, 1)
        self.G = G = g.jacobian(q) if nc else sp.zeros(0, n)
        g_t = sp.diff(g, t) if nc else sp.zeros(0, 1)
        self.gdot = gdot = (G * v + g_t) if nc else sp.zeros(0, 1)
        self.gamma = (gdot.jacobian(q) * v + sp.diff(gdot, t)) if nc else sp.zeros(0, 1)
        if nv:  # ċ = A q̈ + (∂c/∂q q̇ + ∂c/∂t): the rows A and their γ
            c = sp.Matrix([e for _, e in d.velocity_constraints])
            self.A = c.jacobian(v)
            if self.A.free_symbols & set(d.v):
                raise ValueError("a velocity constraint is not linear in the rates")
            self.c = c
            self.gamma_v = c.jacobian(q) * v + sp.diff(c, t)
        self.E = E = d.kinetic + d.potential
        self.h = (v.T * dL_dv)[0, 0] - L
        self.P_diss = (sum(d.v[i] * sp.diff(d.rayleigh, d.v[i]) for i in range(n))
                       if d.rayleigh != 0 else sp.Integer(0))
        self.a_names = [a.name for a in d.qdd]
        self.dE = sp.diff(E, t) + sum(sp.diff(E, d.q[i]) * d.v[i] + sp.diff(E, d.v[i]) * d.qdd[i]
                                      for i in range(n))
        self.lam = [d.multiplier(k) for k in range(nc)]
        self.mu = [d.velocity_multiplier(j) for j in range(nv)]
        self.act = [d.active.get(k, sp.Integer(1)) for k in range(nc)]
        self.pre = self.lagrangian_pre = _prelude(d, layout)
        if hamiltonian:  # every function reads (q, p) and first works out q̇ from p
            self.pre = self.rates_from_momenta("y")
        self.diagonal = self.nm == 0 and self.M.is_diagonal()
        self.accel_exprs: list[Expr] = []
        self.effort_accel: list[Expr] = []

    def emit(self, assign: list[tuple[str, Expr]], indent: str = "    ") -> list[str]:
        return _emit(assign, indent, self.hoist)

    def func(self, name: str, body: list[str], args: str | None = None) -> None:
        """Print function ``name`` (a contract function, arguments from the contract, or a
        helper with ``args``), the parameter constants found so far loaded first (the loads
        it does not read are dropped)."""
        self.parts.append(_func(name, ARGUMENTS[name] if args is None else args,
                                self.hoist.loads() + body))
        self.defined.add(name)

    def source(self) -> tuple[str, tuple[str, ...], int]:
        """The kernel module body, the contract functions it defines and the number of
        parameter constants."""
        self.accel()
        if self.hamiltonian:
            self.hamilton_rhs()
            self.momentum_maps()
        else:
            self.rhs()
        if self.nc:
            self.project()
        elif self.nv:
            self.project_rates()
        if self.st.separable:
            self.accel_q()
        if not self.hamiltonian and _canonical_ok(self.d, self.st):
            self.canonical()
        self.outputs()
        functions = tuple(name for name in FUNCTIONS if name in self.defined)
        return ("\n\n".join([*self.parts, self.hoist.source()]), functions,
                len(self.hoist.found))

    # accel(t, y, p, a, lam): M a = f + Gᵀ λ, G a = −γ
    def accel(self) -> None:
        d, n, M, f0 = self.d, self.n, self.M, self.f0
        body = list(self.pre)
        if self.diagonal:
            # simplify only small quotients: on large ones (rational functions of square
            # roots) its cancel() step can take hours; cse in _emit still shares the work.
            self.accel_exprs = [sp.simplify(f0[i] / M[i, i])
                                if sp.count_ops(f0[i] / M[i, i]) <= 40 else f0[i] / M[i, i]
                                for i in range(n)]
            # The effort's share u/M is added apart (own cse pass), so without an effort every
            # expression evaluates exactly as without the input (W_ext of a free or damped
            # system stays exactly 0).
            self.effort_accel = [d.efforts[i] / M[i, i] for i in range(n)]
            body += self.emit([(f"a[{i}]", self.accel_exprs[i]) for i in range(n)])
            body += self.emit([(f"ua_{i}", self.effort_accel[i]) for i in range(n)])
            body += [f"    a[{i}] += ua_{i}" for i in range(n)]
        elif self.nm == 0 and n <= SCALAR_SOLVE_MAX:
            body += _ldl_solve(M, [self.f[i] for i in range(n)], [f"x_{i}" for i in range(n)],
                               self.hoist)
            body += [f"    a[{i}] = x_{i}" for i in range(n)]
        else:
            body += self.saddle_point_solve()
        self.func("accel", body, args="t, y, p, a, lam")

    def saddle_point_solve(self) -> list[str]:
        """Lines solving [[M, −Gᵀ], [G, 0]] [a, λ] = [f, −γ] (a released constraint's row
        reads λ_k = 0) by Gaussian elimination into ``a`` and ``lam``; velocity constraints
        add rows [A, 0] a = −γ_A and columns −Aᵀ, their μ after the λ in ``lam``."""
        n, nc, M, G, act = self.n, self.nc, self.M, self.G, self.act
        m = n + self.nm
        lines = [f"    A = _zero_matrix({m}, {m})", f"    b = _vector({m})"]
        assign: list[tuple[str, Expr]] = []
        for i in range(n):
            assign += [(f"A[{i}, {j}]", M[i, j]) for j in range(n) if M[i, j] != 0]
            assign.append((f"b[{i}]", self.f[i]))
        for k in range(nc):
            for j in range(n):
                if G[k, j] != 0:
                    assign.append((f"A[{n + k}, {j}]", act[k] * G[k, j]))
                    assign.append((f"A[{j}, {n + k}]", -act[k] * G[k, j]))
            if k in self.d.active:  # released: the row reads λ_k = 0
                assign.append((f"A[{n + k}, {n + k}]", 1 - act[k]))
            assign.append((f"b[{n + k}]", -act[k] * self.gamma[k]))
        for j in range(self.nv):
            row = n + nc + j
            for i in range(n):
                if self.A[j, i] != 0:
                    assign.append((f"A[{row}, {i}]", self.A[j, i]))
                    assign.append((f"A[{i}, {row}]", -self.A[j, i]))
            assign.append((f"b[{row}]", -self.gamma_v[j]))
        lines += self.emit(assign)
        lines.append("    x = _solve(A, b)")
        lines += [f"    a[{i}] = x[{i}]" for i in range(n)]
        lines += [f"    lam[{k}] = x[{n + k}]" for k in range(self.nm)]
        return lines

    def rhs(self) -> None:
        """rhs: without constraints the accelerations are written inline (no array allocation
        per call; a full mass matrix solved in scalars up to SCALAR_SOLVE_MAX coordinates);
        otherwise through accel's linear solve."""
        d, n, a_names, pre = self.d, self.n, self.a_names, self.pre
        if self.diagonal:
            dE_inline = self.dE.subs(dict(zip(d.qdd, self.accel_exprs, strict=True)))
            P_u = sum(sp.diff(self.E, d.v[i]) * self.effort_accel[i]  # dE's effort part
                      for i in range(n))
            body = list(pre) + self.emit([(a_names[i], self.accel_exprs[i]) for i in range(n)]
                                         + [("P_diss", self.P_diss), ("dE", dE_inline)])
            body += self.emit([(f"ua_{i}", self.effort_accel[i]) for i in range(n)]
                              + [("P_u", P_u)])
            body += [f"    {a_names[i]} = {a_names[i]} + ua_{i}" for i in range(n)]
            external = "dE + P_diss + P_u"
        elif self.nm == 0 and n <= SCALAR_SOLVE_MAX:
            body = list(pre) + _ldl_solve(self.M, [self.f[i] for i in range(n)], a_names,
                                          self.hoist)
            body += self.emit([("P_diss", self.P_diss), ("dE", self.dE)])
            external = "dE + P_diss"
        else:
            body = [f"    lam = _vector({max(self.nm, 1)})", f"    acc = _vector({n})",
                    "    accel(t, y, p, acc, lam)"]
            body += pre
            body += [f"    {a_names[i]} = acc[{i}]" for i in range(n)]
            body += self.emit([("P_diss", self.P_diss), ("dE", self.dE)])
            external = "dE + P_diss"
        body += [f"    dy[{i}] = y[{n + i}]" for i in range(n)]
        body += [f"    dy[{n + i}] = {a_names[i]}" for i in range(n)]
        body += [f"    dy[{2 * n}] = {external}", f"    dy[{2 * n + 1}] = P_diss"]
        self.func("rhs", body)

    def rates_from_momenta(self, source: str) -> list[str]:
        """A prelude reading q and the momenta p from array ``source`` (``pm_<i>``), then
        q̇ from M q̇ = p − ∂L/∂q̇|_{q̇=0} under the rates' own names, so that every expression
        of the declaration in (q, q̇, t) evaluates as in the Lagrangian form."""
        d, n, M = self.d, self.n, self.M
        b0 = self.dL_dv.subs({vi: 0 for vi in d.v})
        lines = ["    t = t"] + [f"    {qs.name} = {source}[{i}]" for i, qs in enumerate(d.q)]
        lines += [f"    pm_{i} = {source}[{n + i}]" for i in range(n)]
        lines += [line for line in _prelude(d, self.layout, with_v=False)
                  if line != "    t = t" and not line.startswith(tuple(
                      f"    {qs.name} = y[" for qs in d.q))]
        rhs = [sp.Symbol(f"pm_{i}", real=True) - b0[i] for i in range(n)]
        names = [vs.name for vs in d.v]
        if M.is_diagonal():
            return lines + self.emit([(names[i], rhs[i] / M[i, i]) for i in range(n)])
        if n <= SCALAR_SOLVE_MAX:
            return lines + _ldl_solve(M, rhs, names, self.hoist)
        lines += [f"    A = _zero_matrix({n}, {n})", f"    b = _vector({n})"]
        lines += self.emit([(f"A[{i}, {j}]", M[i, j]) for i in range(n) for j in range(n)
                            if M[i, j] != 0] + [(f"b[{i}]", rhs[i]) for i in range(n)])
        return lines + ["    x = _solve(A, b)"] + [f"    {v} = x[{i}]"
                                                    for i, v in enumerate(names)]

    def hamilton_rhs(self) -> None:
        """rhs of the Hamiltonian formulation, y = [q, p, ...]: q̇ (from the prelude) and
        ṗ = ∂L/∂q − ∂D/∂q̇ + Q + u; the power balance as in the Lagrangian form, dE/dt by the
        chain rule with q̈ from M q̈ = f."""
        d, n, a_names = self.d, self.n, self.a_names
        forces = list(d.forces) + [sp.Integer(0)] * (n - len(d.forces))
        pdot = [sp.diff(self.L, d.q[i]) - sp.diff(d.rayleigh, d.v[i]) + forces[i]
                + d.efforts[i] for i in range(n)]
        body = list(self.pre)
        if n <= SCALAR_SOLVE_MAX:
            body += _ldl_solve(self.M, [self.f[i] for i in range(n)], a_names, self.hoist)
        else:
            body += ["    lam = _vector(1)", f"    acc = _vector({n})",
                     "    accel(t, y, p, acc, lam)"]
            body += [f"    {a_names[i]} = acc[{i}]" for i in range(n)]
        body += self.emit([(f"dy[{n + i}]", pdot[i]) for i in range(n)]
                          + [("P_diss", self.P_diss), ("dE", self.dE)])
        body += [f"    dy[{i}] = {vs.name}" for i, vs in enumerate(d.v)]
        body += [f"    dy[{2 * n}] = dE + P_diss", f"    dy[{2 * n + 1}] = P_diss"]
        self.func("rhs", body)

    def momentum_maps(self) -> None:
        """to_momenta (the Lagrangian state (q, q̇) to the Hamiltonian one (q, p)) and
        from_momenta (back), for the Hamiltonian formulation's initial state and rates."""
        n = self.n
        body = list(self.lagrangian_pre) + self.emit([(f"z[{n + i}]", self.dL_dv[i])
                                                      for i in range(n)])
        body += [f"    z[{i}] = y[{i}]" for i in range(n)]
        body += [f"    for k in range({2 * n}, y.size):", "        z[k] = y[k]"]
        self.func("to_momenta", body)
        body = self.rates_from_momenta("z")
        body += [f"    y[{i}] = z[{i}]" for i in range(n)]
        body += [f"    y[{n + i}] = {vs.name}" for i, vs in enumerate(self.d.v)]
        body += [f"    for k in range({2 * n}, z.size):", "        y[k] = z[k]"]
        self.func("from_momenta", body)

    def project(self) -> None:
        """Positions onto g = 0 (Newton, at most six iterations), then rates onto ġ = 0."""
        d, n, nc, G, act = self.d, self.n, self.nc, self.G, self.act
        body = list(self.pre)
        body[1:1 + n] = []  # q read inside the loop
        body += [f"    G = _matrix({nc}, {n})", f"    r = _vector({nc})",
                 f"    qq = y[0:{n}]", f"    vv = y[{n}:{2 * n}]", "    for _it in range(6):"]
        body += [f"        {qs.name} = qq[{i}]" for i, qs in enumerate(d.q)]
        body += self.emit([(f"r[{k}]", act[k] * self.g[k]) for k in range(nc)]
                          + [(f"G[{k}, {j}]", act[k] * G[k, j]) for k in range(nc)
                             for j in range(n)],
                          indent="        ")
        body += ["        _project_onto(G, r, qq)",
                 "        if _all_below(r, 1e-15):", "            break"]
        body += [f"    {qs.name} = qq[{i}]" for i, qs in enumerate(d.q)]
        body += [f"    {vs.name} = vv[{i}]" for i, vs in enumerate(d.v)]
        if self.nv:  # the rates onto ġ = 0 and c = 0 together
            body += [f"    G = _matrix({self.nm}, {n})", f"    r = _vector({self.nm})"]
        body += self.emit([(f"r[{k}]", act[k] * self.gdot[k]) for k in range(nc)]
                          + [(f"G[{k}, {j}]", act[k] * G[k, j]) for k in range(nc)
                             for j in range(n)] + self.velocity_rows(nc))
        body += ["    _project_onto(G, r, vv)"]
        self.func("project", body)

    def velocity_rows(self, first: int) -> list[tuple[str, Expr]]:
        """Residuals and rows of the velocity constraints, from row ``first`` of r and G."""
        n = self.n
        return [(f"r[{first + j}]", self.c[j]) for j in range(self.nv)] + [
            (f"G[{first + j}, {i}]", self.A[j, i]) for j in range(self.nv) for i in range(n)]

    def project_rates(self) -> None:
        """Without holonomic constraints: the rates onto c = A q̇ + b = 0 (least-norm
        correction; exact for a constraint linear in the rates, so no iteration)."""
        n, nv = self.n, self.nv
        body = list(self.pre)
        body[1 + n:1 + 2 * n] = []  # q̇ read from vv
        body += [f"    G = _matrix({nv}, {n})", f"    r = _vector({nv})",
                 f"    vv = y[{n}:{2 * n}]"]
        body += [f"    {vs.name} = vv[{i}]" for i, vs in enumerate(self.d.v)]
        body += self.emit(self.velocity_rows(0))
        body += ["    _project_onto(G, r, vv)"]
        self.func("project", body)

    def accel_q(self) -> None:
        """The acceleration of a separable system, a function of q alone."""
        d = self.d
        gradV = sp.Matrix([sp.diff(d.potential, qi) for qi in d.q])
        acc = self.M.inv() * (-gradV)
        body = _prelude(d, self.layout, with_v=False, q_name="q")
        body += self.emit([(f"a[{i}]", sp.simplify(acc[i])) for i in range(self.n)])
        self.func("accel_q", body)

    def canonical(self) -> None:
        """Hamilton's equations in z = [q, p = ∂L/∂q̇, ...] (conservative, unconstrained, no
        events) and the maps between y and z."""
        d, n, M, dL_dv = self.d, self.n, self.M, self.dL_dv
        b0 = dL_dv.subs({vi: 0 for vi in d.v})
        p_syms = [sp.Symbol(f"pm_{i}", real=True) for i in range(n)]
        zpre = ["    t = t"] + [f"    {qs.name} = z[{i}]" for i, qs in enumerate(d.q)]
        zpre += [f"    pm_{i} = z[{n + i}]" for i in range(n)]
        zpre += [f"    {sym.name} = p[{self.layout.index(name)}]"
                 for name, sym in d.params.items()]
        if M.is_diagonal():
            vel = self.emit([(vs.name, (p_syms[i] - b0[i]) / M[i, i])
                             for i, vs in enumerate(d.v)])
        else:
            vel = [f"    A = _zero_matrix({n}, {n})", f"    b = _vector({n})"]
            vel += self.emit([(f"A[{i}, {j}]", M[i, j]) for i in range(n) for j in range(n)
                              if M[i, j] != 0]
                             + [(f"b[{i}]", p_syms[i] - b0[i]) for i in range(n)])
            vel += ["    x = _solve(A, b)"] + [f"    {vs.name} = x[{i}]"
                                                for i, vs in enumerate(d.v)]
        body = list(self.pre) + self.emit([(f"z[{n + i}]", dL_dv[i]) for i in range(n)])
        body += [f"    z[{i}] = y[{i}]" for i in range(n)]
        body += [f"    for k in range({2 * n}, y.size):", "        z[k] = y[k]"]
        self.func("to_momenta", body)
        body = list(zpre) + vel
        body += [f"    y[{i}] = z[{i}]" for i in range(n)]
        body += [f"    y[{n + i}] = {vs.name}" for i, vs in enumerate(d.v)]
        body += [f"    for k in range({2 * n}, z.size):", "        y[k] = z[k]"]
        self.func("from_momenta", body)
        dL_dq = [sp.diff(self.L, qi) for qi in d.q]
        body = list(zpre) + vel + self.emit([(f"dz[{n + i}]", dL_dq[i]) for i in range(n)])
        body += [f"    dz[{i}] = {vs.name}" for i, vs in enumerate(d.v)]
        body += [f"    for k in range({2 * n}, z.size):", "        dz[k] = 0.0"]
        self.func("canonical_rhs", body)

    def solved_first(self, exprs: list[Expr]) -> list[str]:
        """Lines solving for λ and q̈ (through ``accel``) where ``exprs`` read them."""
        n, nc = self.n, self.nc
        if not any((set(self.lam) | set(self.mu) | set(self.d.qdd)) & e.free_symbols
                   for e in exprs):
            return []
        return [f"    lam = _vector({max(self.nm, 1)})", f"    acc = _vector({n})",
                "    accel(t, y, p, acc, lam)", *[f"    lam_{k} = lam[{k}]" for k in range(nc)],
                *[f"    mu_{j} = lam[{nc + j}]" for j in range(self.nv)],
                *[f"    {self.a_names[i]} = acc[{i}]" for i in range(n)]]

    def outputs(self) -> None:
        """Energy terms; invariants (declared ones, then constraint residuals); observables
        and events (which may use the multipliers and accelerations); frames."""
        d, pre = self.d, self.pre
        self.func("energy", list(pre) + self.emit([("out[0]", d.kinetic),
                                                   ("out[1]", d.potential), ("out[2]", self.h)]))
        inv = [e for _, e in d.invariants] + [a * c for a, (_, c) in zip(
            self.act, d.constraints, strict=True)] + [c for _, c in d.velocity_constraints]
        if inv:
            self.func("invariants",
                      list(pre) + self.emit([(f"out[{i}]", e) for i, e in enumerate(inv)]))
        for name, exprs in (("observables", [e for _, e in d.observables]),
                            ("event", [e for _, e in d.events])):
            if exprs:
                body = list(pre) + self.solved_first(exprs)
                body += self.emit([(f"out[{i}]", e) for i, e in enumerate(exprs)])
                self.func(name, body)
        assign = [(f"out[{k}, {c}]", e) for k, fr in enumerate(d.frames)
                  for c, e in enumerate(fr.translation + fr.rotation)]
        if assign:
            self.func("frames", list(pre) + self.emit(assign))


def _derive(d: LagrangianBuilder, layout: ParameterLayout, st: Structure,
            hamiltonian: bool = False) -> tuple[str, tuple[str, ...], int]:
    """The kernel module body, the contract functions it defines (those it leaves out are
    no-ops) and the number of parameter constants (in p after the efforts: ``layout`` places
    the parameters and efforts, ``ParameterLayout.constants`` the constants)."""
    return _Derivation(d, layout, st, hamiltonian).source()
