"""The model interface every system implements, declared by a Lagrangian or written directly.

A model owns its parameters, its generalized coordinates, the names of its invariants and
observables, the frames it poses, the conservation laws that hold for it, and a compiled kernel
module (see ``mechsim.codegen``) with the numeric functions the integrators and outputs call.
State layout everywhere: ``y = [q (n), v = q̇ (n), work_external, work_dissipated]``, followed
by the model's discrete mode entries, if it declares any (``modes``; see ``Event``); one helper,
``StateLayout`` (``Model.layout``), says where each part sits, and ``ParameterLayout``
(``Model.parameter_layout``) where each part of the kernels' parameter vector does (both in
``layout``). A ``Law`` owns the meaning of
each conservation law (value, drift, scale, thresholds).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from mechsim.params import Parameter, Value, resolve
from mechsim.systems.layout import ParameterLayout, StateLayout

if TYPE_CHECKING:
    from mechsim.codegen import Kernels


@dataclass(frozen=True)
class Quantity:
    """A named scalar with its SI unit."""

    name: str
    unit: str = ""
    description: str = ""


@dataclass(frozen=True)
class FrameSpec:
    """A frame posed by the model: ``child`` relative to ``parent`` (names without namespace).

    ``parent == "world"`` means the scene's fixed root. Static frames go on /tf_static.
    """

    child: str
    parent: str
    static: bool = False


@dataclass(frozen=True)
class Attitude:
    """Coordinates that hold an orientation as a quaternion rather than joint angles.

    ``q[quaternion]`` = (x, y, z, w), normalised, is the orientation world_R_frame of the
    moving frame ``frame`` (a child of "world" whose origin stays at the world origin, so its
    linear velocity is zero). ``angular_velocity(q, v)`` is the angular velocity of that frame
    in its own (body) axes, rad/s, for q, v of shape (..., n) -> (..., 3). These coordinates
    are not joints: they are published as a pose and a twist, not in JointState.
    """

    frame: str
    quaternion: tuple[int, int, int, int]
    angular_velocity: Callable[[np.ndarray, np.ndarray], np.ndarray]

    def orientation(self, q: np.ndarray) -> np.ndarray:
        """The unit quaternion (x, y, z, w) of ``q`` (..., n) -> (..., 4)."""
        o = np.asarray(q, dtype=float)[..., list(self.quaternion)]
        return o / np.linalg.norm(o, axis=-1, keepdims=True)


@dataclass(frozen=True)
class Visual:
    """How a 3D viewer (Rerun) draws part of the model, in terms of its frames.

    kind: "sphere" (at ``frame``'s origin), "link" (segment from ``frame`` to ``to_frame``),
    "trail" (path of ``frame``'s origin over time), "polyline" (fixed ``points`` in ``frame``,
    e.g. a wire or a surface outline), "box" (half-sizes ``size`` centred on ``frame``),
    "axes" (the frame's axes, length ``radius``), "arrow" (from ``frame``'s origin along the
    vector ``points[0]`` in that frame).
    """

    kind: str
    frame: str
    to_frame: str | None = None
    radius: float = 0.05
    points: tuple[tuple[float, float, float], ...] = ()
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)
    color: tuple[int, int, int] = (220, 220, 220)


#: Prefix of the invariants that are constraint residuals (zero on the constraint manifold).
CONSTRAINT_PREFIX = "constraint_"
#: Names of the levels a law's drift gets (``DiagnosticStatus`` levels 0..3).
LEVEL_NAMES = ("OK", "WARN", "ERROR", "STALE")
_ENERGY_KINDS = ("energy", "energy_function", "work_balance")
_NAMED_KINDS = ("invariant", "constraint")


class EnergyTerms(Protocol):
    """What an energy-type law reads: an ``Energy`` message, a ``SimulationResult`` (arrays),
    or anything else with these attributes."""

    @property
    def total(self) -> Any: ...
    @property
    def energy_function(self) -> Any: ...
    @property
    def work_external(self) -> Any: ...
    @property
    def work_dissipated(self) -> Any: ...


@dataclass(frozen=True)
class Law:
    """A conservation law, the one home of its meaning: which quantity of a sample it keeps,
    how far that quantity has drifted, against which scale, and when that is a warning or an
    error. The simulator declares the laws, the diagnostics node checks them, ``simulate``,
    the stress catalogue and Rerun evaluate them, all through this class.

    kind:
      "energy"          T + V is constant;
      "energy_function" h = Σ q̇ ∂L/∂q̇ − L is constant;
      "work_balance"    total − (W_ext − W_diss) is constant, i.e. total − total₀ = W_ext − W_diss;
      "invariant"       the named invariant is constant;
      "constraint"      the named constraint residual is zero.
    name: the invariant or residual name; for the energy kinds, the kind itself.
    On the wire (``SystemInfo.laws``) a law is its ``key``; :meth:`from_key` reads it back.
    Values, drifts and levels work elementwise on numpy arrays as well as on floats.
    """

    kind: str
    name: str = ""

    #: Default relative drifts from which a law is WARN / ERROR (scene and node defaults).
    WARN_DRIFT: ClassVar[float] = 1e-6
    ERROR_DRIFT: ClassVar[float] = 1e-3

    def __post_init__(self) -> None:
        if self.kind in _ENERGY_KINDS:
            if self.name not in ("", self.kind):
                raise ValueError(f"law {self.kind!r} takes no name (got {self.name!r})")
            object.__setattr__(self, "name", self.kind)
        elif self.kind in _NAMED_KINDS:
            if not self.name:
                raise ValueError(f"law {self.kind!r} needs the name of its quantity")
        else:
            raise ValueError(f"unknown law kind {self.kind!r} "
                             f"(known: {', '.join(_ENERGY_KINDS + _NAMED_KINDS)})")

    @classmethod
    def from_key(cls, key: str) -> Law:
        """The law whose ``key`` this is (raises ValueError for anything else)."""
        kind, sep, name = key.partition(":")
        if not sep and kind in _ENERGY_KINDS:
            return cls(kind)
        if sep and kind in _NAMED_KINDS and name:
            return cls(kind, name)
        raise ValueError(f"not a conservation law: {key!r}")

    @classmethod
    def for_invariant(cls, name: str) -> Law:
        """The law a model's invariant obeys: a residual named ``constraint_*`` stays zero,
        anything else stays constant."""
        return cls("constraint" if name.startswith(CONSTRAINT_PREFIX) else "invariant", name)

    @property
    def key(self) -> str:
        return self.kind if self.kind in _ENERGY_KINDS else f"{self.kind}:{self.name}"

    @property
    def is_constraint(self) -> bool:
        """A residual that should stay zero (drift = |value| / scale, no initial value)."""
        return self.kind == "constraint"

    @property
    def stream(self) -> str:
        """Which sample carries the law's quantity: "energy" or "invariants"."""
        return "energy" if self.kind in _ENERGY_KINDS else "invariants"

    def value(self, energy: EnergyTerms | None = None,
              invariants: Mapping[str, Any] | None = None) -> Any:
        """The quantity the law keeps, from a sample's energy terms or its invariants (by
        name), whichever :attr:`stream` says."""
        if self.kind in _ENERGY_KINDS:
            if energy is None:
                raise ValueError(f"law {self.key} needs the energy terms")
            if self.kind == "energy":
                return energy.total
            if self.kind == "energy_function":
                return energy.energy_function
            return energy.total - (energy.work_external - energy.work_dissipated)
        if invariants is None:
            raise ValueError(f"law {self.key} needs the invariants")
        return invariants[self.name]

    def deviation(self, value: Any, initial: Any) -> Any:
        """How far ``value`` is from what the law demands: the change since ``initial`` (a
        residual: the value itself)."""
        return value if self.is_constraint else value - initial

    def drift(self, value: Any, initial: Any, scale: Any) -> Any:
        """Relative drift |deviation| / scale."""
        return abs(self.deviation(value, initial)) / scale

    def scale(self, energy_scale: float, initial_invariants: Mapping[str, float]) -> float:
        """What drifts are measured against: the model's energy scale for the energy kinds,
        an invariant's initial magnitude (1 if it starts at 0), 1 for a residual (SI)."""
        if self.kind in _ENERGY_KINDS:
            return energy_scale
        if self.kind == "invariant":
            return abs(float(initial_invariants.get(self.name, 0.0))) or 1.0
        return 1.0

    def level(self, drift: float, warn: float | None = None, error: float | None = None) -> int:
        """0 OK, 1 WARN, 2 ERROR for a relative drift (non-finite: ERROR); thresholds default
        to :attr:`WARN_DRIFT` and :attr:`ERROR_DRIFT`."""
        warn = self.WARN_DRIFT if warn is None else warn
        error = self.ERROR_DRIFT if error is None else error
        if not math.isfinite(drift) or drift >= error:
            return 2
        return 1 if drift >= warn else 0


@dataclass(frozen=True)
class Event:
    """A state event: the kernel function ``event(t, y, p, out)`` gives one value per event and
    the event happens where ``out[index]`` changes sign in ``direction``: +1 rising (− to +),
    −1 falling (+ to −), 0 either. The integrator locates the time on its dense output and
    stops there; the model's ``handle_event`` returns the state to continue from (a velocity
    jump, a new discrete mode, or the state unchanged to merely record the time).
    """

    name: str
    direction: int = 0
    description: str = ""


@dataclass(frozen=True)
class Structure:
    """What the equations of motion look like, so `auto` can pick a method."""

    separable: bool  # H = T(p) + V(q), constant mass matrix, no dissipation, forcing or constraints
    n_constraints: int = 0
    dissipative: bool = False
    driven: bool = False
    time_dependent: bool = False
    # q̇ is the state's v part, y[n:2n] (what radau15 integrates in second-order form); not so
    # for a state of momenta (a Hamiltonian formulation)
    second_order: bool = True


class Model(ABC):
    """One system with one parameter set. Subclasses set the class attributes below."""

    id: ClassVar[str]
    title: ClassVar[str]
    source: ClassVar[str]  # document title and section, e.g. "“Minimal Frames” (blog post)"
    parameters: ClassVar[tuple[Parameter, ...]]
    formulations: ClassVar[tuple[str, ...]] = ("default",)
    # One line for the README systems table: which analytic results the tests check.
    oracles: ClassVar[str] = ""

    def __init__(self, **values: Any) -> None:
        self.values: dict[str, Value] = resolve(self.parameter_spec(), values)
        self.check()

    @classmethod
    def parameter_spec(cls) -> tuple[Parameter, ...]:
        spec = cls.parameters
        if len(cls.formulations) > 1:
            spec = (Parameter("formulation", cls.formulations[0], "",
                              "which form of the equations of motion to integrate",
                              choices=cls.formulations),) + spec
        return spec

    @property
    def formulation(self) -> str:
        """The form of the equations the model's physics is written in (what its own code
        branches on)."""
        return self.chosen_formulation

    @property
    def chosen_formulation(self) -> str:
        """The formulation as chosen (the ``formulation`` parameter): what is reported. It
        differs from ``formulation`` where one is generated from another (a Lagrangian
        model's ``hamiltonian``, from its first formulation)."""
        return str(self.values.get("formulation", self.formulations[0]))

    def check(self) -> None:
        """Cross-parameter validation; raise ParameterError naming the field."""

    def value(self, name: str) -> float:
        return float(self.values[name])  # type: ignore[arg-type]

    def with_values(self, **changes: Any) -> Model:
        """A new model of the same system with some parameters changed (validated)."""
        merged = dict(self.values)
        merged.update(changes)
        return type(self)(**merged)

    # --- shape of the model -------------------------------------------------------------------
    @property
    @abstractmethod
    def coordinates(self) -> tuple[Quantity, ...]: ...

    @property
    def invariants(self) -> tuple[Quantity, ...]:
        return ()

    @property
    def observables(self) -> tuple[Quantity, ...]:
        return ()

    @property
    def frames(self) -> tuple[FrameSpec, ...]:
        return ()

    @property
    def attitude(self) -> Attitude | None:
        """Coordinates holding a quaternion orientation (see ``Attitude``); None by default."""
        return None

    @property
    def events(self) -> tuple[Event, ...]:
        """State events (see ``Event``); none by default."""
        return ()

    @property
    def modes(self) -> tuple[Quantity, ...]:
        """Discrete mode entries appended to the state after the work terms (e.g. a contact
        phase 0/1). Constant between events; only ``handle_event`` changes them."""
        return ()

    def initial_modes(self) -> np.ndarray:
        return np.zeros(len(self.modes))

    def handle_event(self, index: int, t: float, y: np.ndarray) -> np.ndarray:
        """The state to continue from after event ``index`` at time ``t`` (``y`` is a copy of
        the state there, which may be modified and returned). Default: call the method
        ``on_<event name>(t, y)``."""
        return getattr(self, f"on_{self.events[index].name}")(t, y)  # type: ignore[no-any-return]

    def visuals(self) -> tuple[Visual, ...]:
        """Default look: a sphere and a trail on every moving frame, a link to its parent."""
        out: list[Visual] = []
        moving = [f for f in self.frames if not f.static]
        for f in moving:
            out.append(Visual("sphere", f.child))
            out.append(Visual("trail", f.child, color=(120, 170, 255)))
            if f.parent != "world":
                out.append(Visual("link", f.parent, to_frame=f.child, radius=0.01))
        return tuple(out)

    @property
    @abstractmethod
    def structure(self) -> Structure: ...

    @property
    @abstractmethod
    def kernels(self) -> Kernels:
        """The compiled kernel functions (built on first use, cached on disk)."""

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Generalized coordinates and rates at t = 0. Default: ``initial.<coordinate>`` and
        ``initial_rate.<coordinate>`` (0 where there is no rate parameter). Override when the
        initial state comes from other parameters (orbital elements, another formulation)."""
        names = [c.name for c in self.coordinates]
        missing = [n for n in names if f"initial.{n}" not in self.values]
        if missing:
            raise NotImplementedError(f"{type(self).__name__}: no initial.{missing[0]} "
                                      "parameter; override initial_state()")
        q = [self.value(f"initial.{n}") for n in names]
        v = [self.value(f"initial_rate.{n}") if f"initial_rate.{n}" in self.values else 0.0
             for n in names]
        return np.array(q, dtype=np.float64), np.array(v, dtype=np.float64)

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray,
                  work_terms: bool = True) -> np.ndarray | None:
        """Closed-form state rows ``[q, v, work_external, work_dissipated, ...]`` at times
        ``t`` from the state ``y0`` at ``t0``, or None where the model has none (default).
        ``work_terms=False``: the caller reads the rest of the state only, and a model whose
        work terms cost more than its motion may leave them NaN."""
        return None

    def closed_form_kernel(self, y0: np.ndarray) -> tuple[Any, np.ndarray] | None:
        """``propagate`` from the state y0 compiled, where the model has it so: a numba
        function of ``codegen.contract.CLOSED_FORM_SIGNATURE`` that writes the rows
        ``propagate`` returns (what ``propagate`` calls), and its constants (from the
        parameters, and from y0 where the model keeps them per state). Default: None
        (``propagate`` alone)."""
        return None

    def curves(self) -> tuple[Any, ...]:
        """Curves of one variable the model defines for its parameters, with the levels read
        against them (``mechsim.systems.curves``: an effective potential with the orbit's
        energy, ...; each a ``curves.Curve``): published once per parameter set beside the
        run. Default: none."""
        return ()

    def rates(self, t: np.ndarray, Y: np.ndarray, p: np.ndarray) -> np.ndarray:
        """The rates q̇ at the states ``Y`` (rows) at times ``t``: the state's ``v`` entries,
        except for a model whose state holds momenta instead (a Hamiltonian formulation)."""
        return Y[..., self.layout.v]

    def rates_in_state(self) -> bool:
        """Whether ``rates`` are the state's ``v`` entries (not a Hamiltonian formulation's
        momenta turned into rates)."""
        return True

    def has_canonical_form(self) -> bool:
        """Whether the kernels provide Hamilton's equations in z = [q, p] (conservative,
        unconstrained, event-free Lagrangian systems): what Gauss–Legendre integrates."""
        return False

    def has_closed_form(self) -> bool:
        """Whether ``propagate`` is exact for this model's formulation and parameters (asked
        once per model: its parameters never change)."""
        if "_closed_form" not in self.__dict__:
            self.__dict__["_closed_form"] = type(self).propagate is not Model.propagate \
                and self.propagate(0.0, self.initial_y(), np.zeros(1)) is not None
        return bool(self.__dict__["_closed_form"])

    def laws(self) -> tuple[Law, ...]:
        """The conservation laws that hold: energy for closed systems, the work balance always,
        each invariant, then each constraint residual (``Law.for_invariant``)."""
        s = self.structure
        laws = [Law("work_balance")]
        if not (s.dissipative or s.driven or s.time_dependent):
            laws.insert(0, Law("energy"))
        named = [Law.for_invariant(q.name) for q in self.invariants]
        laws += [law for law in named if not law.is_constraint]
        laws += [law for law in named if law.is_constraint]
        return tuple(laws)

    def effort_slice(self) -> slice | None:
        """Where the effort (one generalized force per coordinate, applied from outside at
        run time) sits in the parameter vector, or None for a model whose kernels take none
        (default; Lagrangian models take one, see ``mechsim.systems.lagrangian``)."""
        return None

    def laws_under_effort(self) -> tuple[Law, ...]:
        """The laws that still hold while an effort acts: the work balance (its work is part
        of W_ext) and the constraint residuals. Energy, h and the invariants change with the
        effort's work and impulse."""
        return tuple(law for law in self.laws() if law.kind == "work_balance" or law.is_constraint)

    def energy_function_conserved(self) -> bool:
        """True when L has no explicit time dependence and nothing dissipates or drives."""
        s = self.structure
        return not (s.dissipative or s.driven or s.time_dependent)

    def energy_scale(self) -> float:
        """Energy that drifts are measured against: |T₀| + |V₀|, or 1 J if both vanish.
        Override where the initial energies are not representative (e.g. starting at rest)."""
        e = np.zeros(3)
        self.kernels.energy(0.0, self.initial_y(), self.parameter_vector(), e)
        scale = abs(e[0]) + abs(e[1])
        return scale if scale > 0 else 1.0

    def law_scales(self) -> dict[str, float]:
        """Scale of each law's quantity (key: ``Law.key``): relative drift = |change| / scale.
        Invariants: their initial magnitude (1 if zero); constraints: 1 (residual in SI)."""
        inv = np.zeros(max(len(self.invariants), 1))
        self.kernels.invariants(0.0, self.initial_y(), self.parameter_vector(), inv)
        values = {q.name: float(inv[i]) for i, q in enumerate(self.invariants)}
        e = self.energy_scale()
        scales = {law.key: law.scale(e, values) for law in self.laws()}
        for key in scales:  # parts of the energy (a mode's share may start at 0)
            if key.startswith("invariant:") and key[10:].startswith(self.energy_parts):
                scales[key] = e
        return scales

    #: Invariants (name prefixes) that are parts of the energy, such as mode energies: their
    #: drift is measured against the energy scale, not their own initial value.
    energy_parts: ClassVar[tuple[str, ...]] = ()

    def time_scale(self) -> float:
        """A characteristic time (e.g. small-oscillation period), for step-size choices."""
        return 1.0

    # A model's parameters never change (``with_values`` makes a new model), so what follows
    # from them is computed once per model; callers get copies they may modify.
    def parameter_vector(self) -> np.ndarray:
        """Numeric parameters in kernel order (all numeric parameters, in spec order)."""
        if "_parameter_vector" not in self.__dict__:
            self.__dict__["_parameter_vector"] = self._make_parameter_vector()
        return self.__dict__["_parameter_vector"].copy()  # type: ignore[no-any-return]

    def complete_parameters(self, p: np.ndarray) -> np.ndarray:
        """A parameter vector of this model's layout, as float64, with whatever the model
        derives from its parameters recomputed (``LagrangianModel``: its parameter
        constants): a caller that changed a parameter in a copy of ``parameter_vector()``
        gets a consistent vector. A vector of another length is refused."""
        p = np.array(p, dtype=np.float64)
        size = self.kernels.n_p
        if p.shape != (size,):
            raise ValueError(f"{self.id}: a parameter vector has {size} entries "
                             f"(got shape {p.shape})")
        return p

    def _make_parameter_vector(self) -> np.ndarray:
        """The numeric parameters' values, in the order of ``parameter_layout.parameters``."""
        return np.array([float(self.values[name])  # type: ignore[arg-type]
                         for name in self.parameter_layout.parameters], dtype=np.float64)

    @property
    def parameter_layout(self) -> ParameterLayout:
        """Where each parameter sits in the kernels' parameter vector (default: the numeric
        parameters in the order of ``parameter_spec``, nothing else)."""
        return ParameterLayout(tuple(p.name for p in self.parameter_spec() if p.is_numeric))

    @cached_property
    def layout(self) -> StateLayout:
        """Where coordinates, rates, work terms and modes sit in the state vector (made once:
        a model's coordinates and modes never change)."""
        return StateLayout(len(self.coordinates), len(self.modes))

    def initial_y(self) -> np.ndarray:
        """The initial state (projected onto the constraints)."""
        if "_initial_y" not in self.__dict__:
            q0, v0 = self.initial_state()
            y0 = self.layout.compose(q0, v0, modes=self.initial_modes())
            self.kernels.project(0.0, y0, self.parameter_vector())
            self.__dict__["_initial_y"] = y0
        return self.__dict__["_initial_y"].copy()  # type: ignore[no-any-return]

    def describe(self) -> dict[str, Any]:
        return {
            "id": self.id, "title": self.title, "source": self.source,
            "formulations": list(self.formulations),
            "parameters": [p.describe() for p in self.parameter_spec()],
            "coordinates": [{"name": c.name, "unit": c.unit} for c in self.coordinates],
            "invariants": [{"name": c.name, "unit": c.unit} for c in self.invariants],
            "observables": [{"name": c.name, "unit": c.unit} for c in self.observables],
            "frames": [{"child": f.child, "parent": f.parent, "static": f.static}
                       for f in self.frames],
            "laws": [law.key for law in self.laws()],
            **({"events": [{"name": e.name, "direction": e.direction} for e in self.events]}
               if self.events else {}),
            **({"modes": [c.name for c in self.modes]} if self.modes else {}),
        }


def quaternion_about(axis: tuple[float, float, float], angle: float) -> tuple[float, ...]:
    """Quaternion (x, y, z, w) of a right-handed rotation by ``angle`` about a unit ``axis``."""
    s = math.sin(angle / 2.0)
    return (axis[0] * s, axis[1] * s, axis[2] * s, math.cos(angle / 2.0))
