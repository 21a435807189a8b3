"""The model interface every system implements, declared by a Lagrangian or written directly.

A model owns its parameters, its generalized coordinates, the names of its invariants and
observables, the frames it poses, the conservation laws that hold for it, and a compiled kernel
module (see ``mechsim.codegen``) with the numeric functions the integrators and outputs call.
State layout everywhere: ``y = [q (n), v = q̇ (n), work_external, work_dissipated]``, followed
by the model's discrete mode entries, if it declares any (``modes``; see ``Event``).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from mechsim.params import Parameter, Value, resolve

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


@dataclass(frozen=True)
class Law:
    """A conservation law the diagnostics node checks.

    kind: "energy" | "energy_function" | "work_balance" | "invariant" | "constraint";
    name: the quantity (invariant or constraint name; the kind itself for energy laws).
    """

    kind: str
    name: str

    @property
    def key(self) -> str:
        return self.kind if self.kind in ("energy", "energy_function", "work_balance") \
            else f"{self.kind}:{self.name}"


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


class Model(ABC):
    """One system with one parameter set. Subclasses set the class attributes below."""

    id: ClassVar[str]
    title: ClassVar[str]
    source: ClassVar[str]  # document and section, e.g. "seed 000 S1 (Simple pendulum)"
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

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray) -> np.ndarray | None:
        """Closed-form state rows ``[q, v, work_external, work_dissipated, ...]`` at times
        ``t`` from the state ``y0`` at ``t0``, or None where the model has none (default)."""
        return None

    def has_canonical_form(self) -> bool:
        """Whether the kernels provide Hamilton's equations in z = [q, p] (conservative,
        unconstrained, event-free Lagrangian systems): what Gauss–Legendre integrates."""
        return False

    def has_closed_form(self) -> bool:
        """Whether ``propagate`` is exact for this model's formulation and parameters."""
        return type(self).propagate is not Model.propagate and self.propagate(
            0.0, self.initial_y(), np.zeros(1)) is not None

    def laws(self) -> tuple[Law, ...]:
        s = self.structure
        laws = [Law("work_balance", "work_balance")]
        if not (s.dissipative or s.driven or s.time_dependent):
            laws.insert(0, Law("energy", "energy"))
        laws += [Law("invariant", q.name) for q in self.invariants
                 if not q.name.startswith("constraint_")]
        laws += [Law("constraint", q.name) for q in self.invariants
                 if q.name.startswith("constraint_")]
        return tuple(laws)

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
        values = {q.name: abs(float(inv[i])) for i, q in enumerate(self.invariants)}
        e = self.energy_scale()
        out: dict[str, float] = {}
        for law in self.laws():
            if law.kind in ("energy", "energy_function", "work_balance"):
                out[law.key] = e
            elif law.kind == "invariant":
                out[law.key] = values.get(law.name) or 1.0
            else:
                out[law.key] = 1.0
        return out

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

    def _make_parameter_vector(self) -> np.ndarray:
        return np.array([float(self.values[p.name]) for p in self.parameter_spec()  # type: ignore[arg-type]
                         if p.is_numeric], dtype=np.float64)

    def initial_y(self) -> np.ndarray:
        """The initial state (projected onto the constraints)."""
        if "_initial_y" not in self.__dict__:
            q0, v0 = self.initial_state()
            y0 = np.concatenate([q0, v0, [0.0, 0.0], self.initial_modes()]).astype(np.float64)
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
