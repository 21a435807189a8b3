"""What a Lagrangian system declares: its ``declare(b)`` fills a :class:`LagrangianBuilder`
with T, V, D, forces, constraints (on the positions, or on the velocities), invariants,
observables, frames, events and modes, in sympy
expressions of the symbols the builder hands out (``mechsim.systems.lagrangian`` describes the
whole engine; ``lagrangian_kernels`` derives the kernels from a declaration)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Event, FrameSpec, Model, Quantity

if TYPE_CHECKING:
    from sympy import Expr


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
    kinetic: Expr = field(default_factory=lambda: sp.Integer(0))
    potential: Expr = field(default_factory=lambda: sp.Integer(0))
    rayleigh: Expr = field(default_factory=lambda: sp.Integer(0))
    # Terms of L linear in q̇, Σ aᵢ(q, t) q̇ᵢ, that belong to neither T nor V (magnetic q q̇·A):
    # they enter L (and so the equations and h) but not E = T + V; static ones do no work.
    linear: Expr = field(default_factory=lambda: sp.Integer(0))
    forces: list[Expr] = field(default_factory=list)
    constraints: list[tuple[str, Expr]] = field(default_factory=list)
    # Constraints on the velocities, c = A(q, t)·q̇ + b(q, t) = 0 (``velocity_constraint``).
    velocity_constraints: list[tuple[str, Expr]] = field(default_factory=list)
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

    def velocity_constraint(self, name: str, c: Expr) -> sp.Symbol:
        """A constraint on the velocities, c = A(q, t)·q̇ + b(q, t) = 0, which need not be the
        derivative of any g(q, t) = 0 (non-integrable, non-holonomic: a blade that cannot slip
        sideways, a wheel that rolls). This is the documents' constraint in differential form,
        Σ_α A_α dq_α + A dt = 0 ("Dynamical Systems and Constraints: Part 1 – General
        Theory"; PHYS 229 Lecture 10, §5; PHYS0500 §3.4), divided by dt. The equations become
        M q̈ = f + Gᵀλ + Aᵀμ, closed by ċ = 0; the rates are projected onto c = 0; the
        residual c is published as constraint_<name>. Returns μ, the constraint's multiplier:
        μ A is its generalized force (for observables and events). Raises ValueError if ``c``
        is not linear in the rates."""
        c = sp.sympify(c)
        if any(sp.diff(c, vi, vj) != 0 for vi in self.v for vj in self.v):
            raise ValueError(f"velocity constraint {name}: not linear in the rates")
        if not (c.free_symbols & set(self.v)):
            raise ValueError(f"velocity constraint {name}: depends on no rate (a constraint "
                             "on the positions is declared with b.constraint)")
        self.velocity_constraints.append((name, c))
        return self.velocity_multiplier(len(self.velocity_constraints) - 1)

    def velocity_multiplier(self, index: int) -> sp.Symbol:
        """μ of velocity constraint ``index`` (see ``velocity_constraint``)."""
        return sp.Symbol(f"mu_{index}", real=True)

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
