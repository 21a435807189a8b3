"""Systems declared by their Lagrangian; one engine derives everything else.

A system writes T and V in its generalized coordinates, its holonomic constraints g(q, t) = 0,
its Rayleigh dissipation function D(q, q̇, t) and any other generalized forces Q(q, q̇, t). From
that declaration sympy derives, once per declaration (the generated module is cached on disk):

- the mass matrix M = ∂²T/∂q̇², and the forcing f = ∂L/∂q − (∂²L/∂q̇∂q) q̇ − ∂²L/∂q̇∂t − ∂D/∂q̇ + Q
  + u, so that M q̈ = f + Gᵀλ, with G = ∂g/∂q and G q̈ = −γ (the constraints differentiated
  twice). u is the *effort*: one generalized force per coordinate (N for a length, N·m for an
  angle) applied from outside at run time, read from the parameter vector after the numeric
  parameters (``ParameterLayout.efforts``, ``LagrangianModel.effort_slice``; zero unless a
  caller sets it, as the simulator node does from its ``effort`` topic); it enters only the
  right-hand side (``accel``,
  ``rhs``): the separable and canonical forms, for the symplectic methods, leave it out;
- the energy function h = Σ q̇ ∂L/∂q̇ − L;
- the power balance: dissipated power P_d = Σ q̇ ∂D/∂q̇, and the external power
  P_ext = dE/dt + P_d with dE/dt from the chain rule on E = T + V, so the integrated work terms
  close total − total₀ = W_ext − W_d by construction of the equations, not of the outputs (the
  effort's power u·q̇ is part of P_ext: q̈ includes it);
- constraint projection, invariants, observables (which may use the multipliers λ) and frames;
- the *parameter constants*: every subexpression of these that depends on the parameters alone
  (ω = √(G(m₁ + m₂)/L³), L/M, …) is computed once per parameter vector, into slots after the
  efforts (``_ParameterConstants``, ``ParameterLayout.constants``), instead of at every call of
  a kernel;
- state events (``b.event``: a sign change of an expression, which may use λ) with discrete
  modes (``b.mode``: extra state entries an expression may switch on, e.g. a constraint that is
  active only in contact, ``b.constraint(name, g, active=...)``); the model handles each event
  in a method ``on_<event name>(t, y) -> y`` (see ``mechsim.integrators``).

No equation of motion is typed by hand, so no typo of the source documents can reach the code.

Where things are: what a system declares, ``declaration.LagrangianBuilder``; the derivation and
the kernel printing, ``lagrangian_kernels`` (imported only to derive); the model, here. A model
reads its shape and structure (coordinates, invariants, frames, events, modes, separability,
canonical form) and the derivation key of its kernels from a *summary*: made from the
declaration the first time a class is built with this code and the values its declaration
reads, then recalled from the cache (``codegen.recall``), so that a model derived before is set
up without importing sympy (``_symbolic``), which would otherwise be much of the CPU of a warm
``mechsim run``. The summary is keyed on the values the declaration *read* (a pendulum's
declaration reads only its formulation: every gravity and initial angle of a sweep shares one
summary; a bead's on a wire reads the wire's shape, and on a custom wire its curve), noted as
it was made (``_ReadValues``).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Iterator, Mapping
from functools import cached_property
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from mechsim import codegen
from mechsim.errors import ParameterError
from mechsim.params import Value
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Event, FrameSpec, Law, Model, Quantity, Structure
from mechsim.systems.declaration import LagrangianBuilder
from mechsim.systems.layout import ParameterLayout

#: Part of every derivation's cache key, with the source text of this module, of
#: ``declaration`` (what a system declares) and of ``lagrangian_kernels`` (the derivation): any
#: change to the generator gives new kernel modules (see ``mechsim.codegen``).
GENERATOR_VERSION = 8
_HERE = Path(__file__).resolve().parent
GENERATOR_SOURCE = codegen.source_fingerprint([_HERE / "lagrangian.py", _HERE / "declaration.py",
                                                _HERE / "lagrangian_kernels.py",
                                                _HERE / "kernel_printer.py"])


#: What a model's summary holds (``LagrangianModel._summary``).
_SUMMARY_KEYS = frozenset({"derivation_key", "coordinates", "invariants", "observables",
                           "frames", "events", "modes", "structure", "canonical",
                           "energy_function_conserved"})


#: How many sets of read values a class's summaries are keyed by that the cache keeps (the
#: most recently made): a declaration reads the same values whatever they are, unless it
#: branches on one (a bead's curve), so a class has a few.
MAX_READ_SETS = 16


class _ReadValues(Mapping[str, Value]):
    """A model's values that note the name of each one read (names looked up and absent
    too); whoever iterates them, or asks their number, has read them all."""

    def __init__(self, values: Mapping[str, Value]) -> None:
        self._values = values
        self.read: set[str] = set()

    def __getitem__(self, name: str) -> Value:
        self.read.add(name)
        return self._values[name]

    def __iter__(self) -> Iterator[str]:
        self.read.update(self._values)
        return iter(self._values)

    def __len__(self) -> int:
        self.read.update(self._values)
        return len(self._values)


#: The formulation a Lagrangian system may offer besides its own (by listing it last in its
#: ``formulations``): Hamilton's equations, generated from its first formulation.
HAMILTONIAN = "hamiltonian"


class LagrangianModel(Model):
    """A model whose equations come from ``declare``; see the module docstring.

    A class that lists ``"hamiltonian"`` among its ``formulations`` (last) offers Hamilton's
    equations of its first formulation's Lagrangian (PHYS0500 – Advanced Classical Mechanics,
    §3.6 Hamiltonian Dynamics): the state holds the canonical momenta p = ∂L/∂q̇ where the
    others hold q̇, ``y = [q, p, work_external, work_dissipated]``, integrated by any method as
    q̇ = M⁻¹(p − ∂L/∂q̇|₀), ṗ = ∂L/∂q − ∂D/∂q̇ + Q + u. Everything else (the system's own
    code, its outputs) is that of the first formulation: ``formulation`` names it, while
    ``chosen_formulation`` reports "hamiltonian"; ``rates`` gives q̇ for the published state.
    Declarations with constraints, events or modes have none (their multipliers and event
    handlers are written in q̇)."""

    declaration_version: ClassVar[int] = 1

    @property
    def formulation(self) -> str:
        chosen = self.chosen_formulation
        return self.formulations[0] if chosen == HAMILTONIAN else chosen

    @cached_property
    def hamiltonian(self) -> bool:
        """Whether the state holds the canonical momenta (formulation ``hamiltonian``)."""
        return self.chosen_formulation == HAMILTONIAN

    def declare(self, b: LagrangianBuilder) -> None:
        raise NotImplementedError

    @cached_property
    def declaration(self) -> LagrangianBuilder:
        b = LagrangianBuilder(self)
        self.declare(b)
        return b

    # --- what the model is, from its summary (recalled without sympy when derived before) ---
    @cached_property
    def _summary(self) -> dict[str, Any]:
        """The declaration's summary (``_summarize``) and the derivation key of its kernels:
        recalled from the cache when this class and this code were declared before with the
        same values of every parameter that declaration read (``_summary_key``), so that a
        model whose kernels are cached is set up without sympy; otherwise made from the
        declaration and remembered under the values it read."""
        class_key = self._recall_key()
        if class_key is None:
            return {"derivation_key": self.derivation_key(), **self._summarize()}
        read_sets = _recall_read_sets(class_key)
        for names in read_sets:
            recalled = codegen.recall(self._summary_key(class_key, names))
            if recalled is not None and recalled.keys() == _SUMMARY_KEYS:
                return recalled
        made, names = self._summary_made()
        codegen.remember(self._summary_key(class_key, names), made)
        if names not in read_sets:
            codegen.remember(class_key, {"read_sets": [names, *read_sets][:MAX_READ_SETS]})
        return made

    def _summary_made(self) -> tuple[dict[str, Any], list[str]]:
        """The summary made from the declaration, and the names of the values it read.

        It is made by a bare instance of this class whose only state is this model's values,
        seen through ``_ReadValues``: nothing it computes from a value can have been computed
        before and so go unnoted. Deterministic code that reads the same values gets the same
        summary, so it stands for every model that agrees with this one on those values. Its
        declaration is this model's too (the same values)."""
        probe = object.__new__(type(self))
        values = _ReadValues(self.values)
        probe.__dict__["values"] = values
        made = {"derivation_key": probe.derivation_key(), **probe._summarize()}
        self.__dict__.setdefault("declaration", probe.declaration)
        return made, sorted(values.read)

    def _summary_key(self, class_key: str, names: list[str]) -> str:
        """The key of the summary of this class's declaration with this model's values of
        ``names`` (an absent name is part of the key as absent)."""
        return codegen.fingerprint(class_key, [(k, k in self.values, repr(self.values.get(k)))
                                               for k in names])

    def _recall_key(self) -> str | None:
        """Every input of the declaration and of its derivation key but the parameter values
        (``_summary_key`` adds those it reads): see ``_class_recall_key``."""
        return _class_recall_key(type(self))

    def _summarize(self) -> dict[str, Any]:
        """What the model's shape and structure are, from its declaration, as JSON values
        (``_summary``): each list entry holds a dataclass's fields in order."""
        from mechsim.systems.lagrangian_kernels import _canonical_ok

        d = self.declaration
        st = self._structure_of(d)
        canonical = _canonical_ok(d, st)
        if self.hamiltonian:
            if d.constraints or d.velocity_constraints or d.events or d.modes:
                raise ParameterError("formulation", f"hamiltonian: {self.id} "
                                     f"({self.formulation}) has constraints, events or modes")
            # the state is (q, p): no separable form in (q, q̇), no second canonical map
            st = dataclasses.replace(st, separable=False, second_order=False)
            canonical = False
        rows = dataclasses.astuple
        return {
            "coordinates": [rows(q) for q in d.coords],
            "invariants": [rows(q) for q, _ in d.invariants]
            + [rows(Quantity(f"constraint_{name}", "")) for name, _ in d.constraints]
            + [rows(Quantity(f"constraint_{name}", "")) for name, _ in d.velocity_constraints],
            "observables": [rows(q) for q, _ in d.observables],
            "frames": [rows(f.spec) for f in d.frames],
            "events": [rows(e) for e, _ in d.events],
            "modes": [rows(q) for q in d.modes],
            "structure": rows(st),
            "canonical": canonical,
            "energy_function_conserved": self._energy_function_conserved_of(d),
        }

    @cached_property
    def coordinates(self) -> tuple[Quantity, ...]:
        return tuple(Quantity(*row) for row in self._summary["coordinates"])

    @cached_property
    def invariants(self) -> tuple[Quantity, ...]:
        return tuple(Quantity(*row) for row in self._summary["invariants"])

    @cached_property
    def observables(self) -> tuple[Quantity, ...]:
        return tuple(Quantity(*row) for row in self._summary["observables"])

    @cached_property
    def frames(self) -> tuple[FrameSpec, ...]:
        return tuple(FrameSpec(*row) for row in self._summary["frames"])

    @cached_property
    def events(self) -> tuple[Event, ...]:
        return tuple(Event(*row) for row in self._summary["events"])

    @cached_property
    def modes(self) -> tuple[Quantity, ...]:
        return tuple(Quantity(*row) for row in self._summary["modes"])

    @cached_property
    def structure(self) -> Structure:
        return Structure(*self._summary["structure"])

    def has_canonical_form(self) -> bool:
        return bool(self._summary["canonical"])

    def energy_function_conserved(self) -> bool:
        return bool(self._summary["energy_function_conserved"])

    def has_closed_form(self) -> bool:
        """A system's closed form gives (q, q̇) rows: none for the Hamiltonian state."""
        return not self.hamiltonian and super().has_closed_form()

    def initial_y(self) -> np.ndarray:
        """The initial state; in the Hamiltonian formulation with p = ∂L/∂q̇ in place of q̇."""
        y = super().initial_y()
        if not self.hamiltonian:
            return y
        z = np.empty_like(y)
        self.kernels.to_momenta(0.0, y, self.parameter_vector(), z)
        return z

    def rates_in_state(self) -> bool:
        return not self.hamiltonian

    def rates(self, t: np.ndarray, Y: np.ndarray, p: np.ndarray) -> np.ndarray:
        if not self.hamiltonian:
            return super().rates(t, Y, p)
        Z = np.atleast_2d(Y)
        times = np.broadcast_to(np.asarray(t, dtype=np.float64), Z.shape[:1])
        out, row = np.empty((Z.shape[0], self.layout.n)), np.empty(Z.shape[1])
        for k in range(Z.shape[0]):
            self.kernels.from_momenta(float(times[k]), np.ascontiguousarray(Z[k]), p, row)
            out[k] = row[self.layout.v]
        return out.reshape(np.shape(Y)[:-1] + (self.layout.n,))

    @staticmethod
    def _structure_of(d: LagrangianBuilder) -> Structure:
        qs, vs, t = set(d.q), set(d.v), d.t
        M = sp.hessian(d.kinetic, d.v)
        constant_mass = not (M.free_symbols & (qs | vs | {t}))
        time_dep = t in (d.kinetic.free_symbols | d.potential.free_symbols
                         | sp.sympify(d.linear).free_symbols) or any(
            t in g.free_symbols for _, g in d.constraints + d.velocity_constraints)
        dissipative = d.rayleigh != 0
        # A velocity constraint with a term b free of the rates imposes a motion: its force
        # does work (power −μ b), as a generalized force would.
        driven = any(f != 0 for f in d.forces) or any(
            c.subs({vi: 0 for vi in d.v}) != 0 for _, c in d.velocity_constraints)
        n_constraints = len(d.constraints) + len(d.velocity_constraints)
        separable = (constant_mass and not n_constraints and not dissipative and not driven
                     and d.linear == 0
                     and not time_dep and not (d.potential.free_symbols & vs)
                     and not (d.kinetic.free_symbols & qs)
                     and (len(d.q) <= 4 or M.is_diagonal()))
        return Structure(separable=separable, n_constraints=n_constraints,
                         dissipative=dissipative, driven=driven, time_dependent=time_dep)

    @staticmethod
    def _energy_function_conserved_of(d: LagrangianBuilder) -> bool:
        L = d.kinetic - d.potential + d.linear
        # An ideal scleronomic velocity constraint (c = A(q) q̇) does no work: μ A q̇ = 0.
        return bool(d.t not in L.free_symbols and d.rayleigh == 0
                    and not any(f != 0 for f in d.forces)
                    and not any(d.t in g.free_symbols for _, g in d.constraints)
                    and not any(d.t in c.free_symbols or c.subs({vi: 0 for vi in d.v}) != 0
                                for _, c in d.velocity_constraints))

    @cached_property
    def kernels(self) -> codegen.Kernels:
        """Built once per declaration: derived and compiled on the first use on a machine,
        imported from the cache afterwards (see ``derivation_key``)."""
        return codegen.build(f"{self.id}_{self.chosen_formulation}",
                             self._summary["derivation_key"],
                             self.kernel_source)

    def _declared_layout(self, n_coordinates: int) -> ParameterLayout:
        """The numeric parameters and the efforts on ``n_coordinates`` coordinates: what the
        derivation is given (the parameter constants it takes out follow them)."""
        return ParameterLayout(super().parameter_layout.parameters, n_efforts=n_coordinates)

    @cached_property
    def parameter_layout(self) -> ParameterLayout:
        """The numeric parameters, the efforts and the parameter constants (as many as the
        derivation took out: the rest of the kernels' ``N_P``)."""
        declared = self._declared_layout(len(self.coordinates))
        return declared.with_constants(self.kernels.n_p - declared.size)

    def effort_slice(self) -> slice:
        """Where the effort u (one generalized force per coordinate) sits in the parameter
        vector: after the numeric parameters. Not a parameter of the system: no name, no
        range, not in ``parameter_spec`` (so not a ROS or scene parameter)."""
        return self._declared_layout(len(self.coordinates)).efforts

    def _make_parameter_vector(self) -> np.ndarray:
        """The numeric parameters, the efforts (zero) and the parameter constants."""
        p = np.zeros(self.parameter_layout.size)
        p[self.parameter_layout.values] = super()._make_parameter_vector()
        return self.complete_parameters(p)

    def complete_parameters(self, p: np.ndarray) -> np.ndarray:
        """``p`` (a copy) with its parameter constants computed afresh from its parameters."""
        p = super().complete_parameters(p)
        self.kernels.module.parameter_constants(p)
        return p

    def derivation_key(self) -> str:
        """Every input of the derivation: the declaration (expressions with their symbols'
        assumptions, names, events, modes), where each parameter sits in ``p`` (the index map
        the generated code bakes in), and the generator (its version and source text, and the
        sympy version)."""
        d = self.declaration
        return codegen.fingerprint(
            GENERATOR_VERSION, GENERATOR_SOURCE, codegen.distribution_version("sympy"),
            type(self).__qualname__,
            self.declaration_version, self.chosen_formulation,
            sorted(self._declared_layout(len(d.q)).indices().items()),
            [(c.name, c.unit) for c in d.coords],
            sp.srepr(d.kinetic), sp.srepr(d.potential), sp.srepr(d.rayleigh),
            sp.srepr(d.linear), [sp.srepr(f) for f in d.forces],
            [(n, sp.srepr(g)) for n, g in d.constraints],
            [(n, sp.srepr(c)) for n, c in d.velocity_constraints],
            [(q.name, sp.srepr(e)) for q, e in d.invariants],
            [(q.name, sp.srepr(e)) for q, e in d.observables],
            [(f.spec, [sp.srepr(e) for e in f.translation + f.rotation]) for f in d.frames],
            [(e, sp.srepr(x)) for e, x in d.events],
            [(k, sp.srepr(a)) for k, a in sorted(d.active.items())],
            [q.name for q in d.modes], sorted((k, sp.srepr(v)) for k, v in d.params.items()))

    def kernel_source(self) -> codegen.KernelSource:
        """Derive the kernel functions (sympy: the slow part of a model's first run)."""
        from mechsim.systems.lagrangian_kernels import _derive

        d = self.declaration
        layout = self._declared_layout(len(d.q))
        body, functions, n_constants = _derive(d, layout, self.structure, self.hamiltonian)
        n = len(d.q)
        return codegen.KernelSource(
            name=f"{self.id}_{self.chosen_formulation}", functions=functions, body=body, constants={
                "N_Q": n, "N_Y": 2 * n + 2 + len(d.modes), "N_C": self.structure.n_constraints,
                "N_INV": len(self.invariants), "N_OBS": len(self.observables),
                "N_FRAMES": len(d.frames), "N_EV": len(d.events), "N_MODE": len(d.modes),
                "N_P": layout.with_constants(n_constants).size})

    def laws(self) -> tuple[Law, ...]:
        laws = list(super().laws())
        if self.energy_function_conserved():
            laws.insert(1 if laws[0].kind == "energy" else 0,
                        Law("energy_function", "energy_function"))
        return tuple(laws)


def _recall_read_sets(class_key: str) -> list[list[str]]:
    """The sets of names the declarations of a class read (``LagrangianModel._summary``), the
    latest first; none when the cache holds nothing readable."""
    record = codegen.recall(class_key)
    sets = record.get("read_sets") if record is not None else None
    if not (isinstance(sets, list) and all(
            isinstance(names, list) and all(isinstance(k, str) for k in names)
            for names in sets)):
        return []
    return sets[:MAX_READ_SETS]


@functools.cache
def _class_recall_key(cls: type[LagrangianModel]) -> str | None:
    """The class, the source of every module of ``mechsim`` (where the class and all the code
    it can call live), and the versions of Python, numba, sympy, mpmath, numpy and scipy (a
    declaration may bake in numbers they computed): under this key the cache holds the sets
    of names the class's declarations read. None for a class outside ``mechsim.systems`` (a
    plug-in, a test): its code is not in that source, so it is always declared afresh."""
    if not cls.__module__.startswith("mechsim.systems."):
        return None
    return codegen.fingerprint(
        "recall", GENERATOR_VERSION, cls.__module__, cls.__qualname__,
        cls.declaration_version, codegen.package_fingerprint(), codegen.RUNTIME,
        [codegen.distribution_version(d) for d in ("sympy", "mpmath", "numpy", "scipy")])
