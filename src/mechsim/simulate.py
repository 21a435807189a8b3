"""The pure-Python API: one call integrates a model and returns every output as arrays."""

from __future__ import annotations

import math
import time
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Generic, NamedTuple, TypeVar, overload

import numpy as np

from mechsim.errors import ParameterError
from mechsim.integrators import METHODS, Stepper, loops, make_stepper
from mechsim.integrators.runs import (
    NOT_KEPT,
    PerModel,
    Plan,
    PreparedRun,
    RunLayout,
    plan_run,
)
from mechsim.integrators.state import Status
from mechsim.params import PUBLISH_RATE, TOLERANCE, shown
from mechsim.systems import load_system as _load_model
from mechsim.systems.base import Law, Model

OUTPUTS = ("energy", "invariants", "observables", "frames")
_NONE2 = np.zeros((0, 1))
_NONE3 = np.zeros((0, 1, 7))


@dataclass
class Outputs:
    """Energy terms, invariants, observables and frames at sample times (only those asked for)."""

    kinetic: np.ndarray | None = None
    potential: np.ndarray | None = None
    energy_function: np.ndarray | None = None
    invariants: dict[str, np.ndarray] = field(default_factory=dict)
    observables: dict[str, np.ndarray] = field(default_factory=dict)
    frames: np.ndarray | None = None  # (samples, frames, 7): translation xyz, quaternion xyzw


@dataclass(frozen=True)
class OutputShape:
    """How many invariants, observables and frames a model's outputs have (asked of the
    model once: some models derive them)."""

    invariants: tuple[str, ...]
    observables: tuple[str, ...]
    frames: int

    @classmethod
    def of(cls, model: Model) -> OutputShape:
        """The shape of ``model``'s outputs (worked out once per model: a model never
        changes)."""
        shape = _SHAPES.get(model)
        if shape is None:
            shape = _SHAPES[model] = cls(tuple(q.name for q in model.invariants),
                                         tuple(q.name for q in model.observables),
                                         len(model.frames))
        return shape


_SHAPES: weakref.WeakKeyDictionary[Model, OutputShape] = weakref.WeakKeyDictionary()


def evaluate_arrays(model: Model, shape: OutputShape, t: np.ndarray, Y: np.ndarray,
                    p: np.ndarray, which: tuple[str, ...] = OUTPUTS
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The requested outputs at the given states as arrays, in one compiled call: energy
    terms (m, 3: kinetic, potential, energy_function), invariants (m, k), observables
    (m, k), frames (m, frames, 7); outputs not asked for are empty stand-ins."""
    E, inv, obs, fr = output_buffers(shape, which, t.size)
    loops().evaluate_outputs(model.kernels.kernel_set(*which), np.ascontiguousarray(t),
                             np.ascontiguousarray(Y), p, "energy" in which,
                             "invariants" in which, "observables" in which, "frames" in which,
                             E, inv, obs, fr)
    return (E, inv[:, :len(shape.invariants)], obs[:, :len(shape.observables)],
            fr[:, :shape.frames])


def evaluate(model: Model, t: np.ndarray, Y: np.ndarray, p: np.ndarray,
             which: tuple[str, ...] = OUTPUTS) -> Outputs:
    """Compute the requested outputs at the given states (nothing else is computed)."""
    if not which:
        return Outputs()
    shape = OutputShape.of(model)
    return assemble(shape, which, *evaluate_arrays(model, shape, t, Y, p, which))


def output_buffers(shape: OutputShape, which: tuple[str, ...], m: int, members: int = 0
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The arrays the compiled output evaluation writes for ``m`` samples (``evaluate_arrays``),
    empty stand-ins for the outputs not asked for; with ``members``, for each of that many
    members of an ensemble (a leading axis)."""
    if not members:
        return (np.zeros((m, 3)) if "energy" in which else _NONE2,
                np.zeros((m, max(len(shape.invariants), 1))) if "invariants" in which
                else _NONE2,
                np.zeros((m, max(len(shape.observables), 1))) if "observables" in which
                else _NONE2,
                np.zeros((m, max(shape.frames, 1), 7)) if "frames" in which else _NONE3)
    E, inv, obs, fr = output_buffers(shape, which, m)
    return (np.zeros((members, *E.shape)), np.zeros((members, *inv.shape)),
            np.zeros((members, *obs.shape)), np.zeros((members, *fr.shape)))


def assemble(shape: OutputShape, which: tuple[str, ...], E: np.ndarray, inv: np.ndarray,
             obs: np.ndarray, fr: np.ndarray) -> Outputs:
    """``Outputs`` from the arrays of ``evaluate_arrays`` (or ``output_buffers``: with a
    leading axis of members, each output has it too)."""
    out = Outputs()
    if "energy" in which:
        out.kinetic, out.potential, out.energy_function = E[..., 0], E[..., 1], E[..., 2]
    if "invariants" in which:
        out.invariants = {name: inv[..., i] for i, name in enumerate(shape.invariants)}
    if "observables" in which:
        out.observables = {name: obs[..., i] for i, name in enumerate(shape.observables)}
    if "frames" in which:
        out.frames = fr[..., :shape.frames, :]
    return out


class OutputViews:
    """The evaluated outputs of a run (``self.outputs``) by name: energy terms, invariants and
    observables; shared by a single run's and an ensemble's results."""

    outputs: Outputs

    @property
    def kinetic(self) -> np.ndarray:
        assert self.outputs.kinetic is not None
        return self.outputs.kinetic

    @property
    def potential(self) -> np.ndarray:
        assert self.outputs.potential is not None
        return self.outputs.potential

    @property
    def total(self) -> np.ndarray:
        return self.kinetic + self.potential

    @property
    def energy_function(self) -> np.ndarray:
        assert self.outputs.energy_function is not None
        return self.outputs.energy_function

    @property
    def invariants(self) -> dict[str, np.ndarray]:
        return self.outputs.invariants

    @property
    def observables(self) -> dict[str, np.ndarray]:
        return self.outputs.observables


T = TypeVar("T")


_Run = tuple[Model, RunLayout, np.ndarray, tuple[str, ...]]  # (model, layout, buffer, outputs)


class StateColumns(NamedTuple):
    """The columns of a model's rows holding q, and v where the state holds the rates (None:
    a Hamiltonian formulation's momenta, turned into rates by ``Model.rates``)."""

    q: slice
    v: slice | None

    @classmethod
    def of(cls, model: Model) -> StateColumns:
        at = model.layout
        return cls(at.q, at.v if model.rates_in_state() else None)


def _rows(run: _Run) -> np.ndarray:
    """The rows Y of a prepared run (``SimulationResult.of_run``): its buffer's first rows."""
    return run[1].rows(run[2])


class _FromRun(Generic[T]):
    """An attribute of a result made from its prepared run's buffer (``_Run``) when first
    read, then kept in the result's ``__dict__``: a non-data descriptor, so that a value set
    on the instance (a result made by ``SimulationResult(...)``) shadows it."""

    def __init__(self, make: Callable[[SimulationResult, _Run], T]) -> None:
        self.make = make

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    @overload
    def __get__(self, result: None, owner: type) -> _FromRun[T]: ...
    @overload
    def __get__(self, result: object, owner: type | None = None) -> T: ...

    def __get__(self, result: object, owner: type | None = None) -> T | _FromRun[T]:
        if result is None:
            return self
        value = result.__dict__[self.name] = self.make(result,  # type: ignore[arg-type]
                                                       result.__dict__["_run"])
        return value


class SimulationResult(OutputViews):
    """Arrays at the output times. ``total = kinetic + potential``; the work terms close
    ``total - total[0] = work_external - work_dissipated``.

    A run ``simulate`` finishes in one compiled call leaves its arrays in one buffer: ``q``
    and ``v`` are made from it (views) with the result, every other attribute when it is
    first read."""

    model: Model
    method: str
    tolerance: float
    wall_time: float
    q: np.ndarray
    v: np.ndarray
    t: _FromRun[np.ndarray] = _FromRun(lambda r, run: run[1].times(run[2]))
    work_external: _FromRun[np.ndarray] = _FromRun(
        lambda r, run: _rows(run)[:, run[0].layout.work_external])
    work_dissipated: _FromRun[np.ndarray] = _FromRun(
        lambda r, run: _rows(run)[:, run[0].layout.work_dissipated])
    outputs: _FromRun[Outputs] = _FromRun(
        lambda r, run: assemble(OutputShape.of(run[0]), run[3], *run[1].outputs(run[2]))
        if run[3] else Outputs())
    n_steps: _FromRun[int] = _FromRun(lambda r, run: int(run[1].counters(run[2])[1]))
    #: Events met on the way, as (time, event name); the discrete mode entries at each sample.
    events: _FromRun[list[tuple[float, str]]] = _FromRun(lambda r, run: [])
    modes: _FromRun[np.ndarray | None] = _FromRun(
        lambda r, run: _rows(run)[:, run[0].layout.modes])
    #: What the run cost: right-hand-side (or force) evaluations and rejected steps.
    n_evaluations: _FromRun[int] = _FromRun(lambda r, run: int(run[1].counters(run[2])[2]))
    n_rejected: _FromRun[int] = _FromRun(lambda r, run: int(run[1].counters(run[2])[3]))
    #: The integrator's own estimate of the error it committed: the sum over its steps of
    #: the local error estimates, relative to the state's scale (1e-9: about a billionth of a
    #: typical coordinate or rate). It assumes the errors add up: a chaotic system can
    #: amplify them beyond it, and a symplectic method's energy error stays far below it;
    #: the closed forms report 0. A diagnostic, not a bound: the contract is ``tolerance``
    #: (see ``mechsim.integrators``; tests/test_tolerance.py checks it against references).
    error_estimate: _FromRun[float] = _FromRun(
        lambda r, run: float(run[1].counters(run[2])[4]))

    def __init__(self, model: Model, method: str, tolerance: float, t: np.ndarray,
                 q: np.ndarray, v: np.ndarray, work_external: np.ndarray,
                 work_dissipated: np.ndarray, outputs: Outputs, wall_time: float, n_steps: int,
                 events: list[tuple[float, str]] | None = None, modes: np.ndarray | None = None,
                 n_evaluations: int = 0, n_rejected: int = 0, error_estimate: float = 0.0
                 ) -> None:
        self.model, self.method, self.tolerance = model, method, tolerance
        self.t, self.q, self.v, self.modes = t, q, v, modes
        self.work_external, self.work_dissipated = work_external, work_dissipated
        self.outputs, self.wall_time, self.n_steps = outputs, wall_time, n_steps
        self.events = [] if events is None else events
        self.n_evaluations, self.n_rejected = n_evaluations, n_rejected
        self.error_estimate = error_estimate

    @classmethod
    def of_run(cls, model: Model, set_up: _SetUp, buf: np.ndarray, wall_time: float
               ) -> SimulationResult:
        """The result of ``set_up``'s prepared run (``integrators.runs.PreparedRun``), which
        wrote ``buf``: q and v now, the other arrays when first read (``_FromRun``)."""
        result = cls.__new__(cls)
        m, state = set_up.t.size, set_up.state
        # q and v with the result (what nearly every caller reads; v from the rows as run,
        # whatever a caller later writes into them), the rest when first read
        result.__dict__ = {
            "model": model, "method": set_up.run_method, "tolerance": set_up.tolerance,
            "wall_time": wall_time, "_run": (model, set_up.layout, buf, set_up.outputs),
            "q": buf[:m, state.q],
            "v": buf[:m, state.v] if state.v is not None
            else model.rates(set_up.layout.times(buf), buf[:m],  # type: ignore[union-attr]
                             set_up.layout.parameters(buf))}  # type: ignore[union-attr]
        return result

    def __repr__(self) -> str:
        return (f"SimulationResult({self.model.id}, method={self.method!r}, "
                f"tolerance={self.tolerance:g}, samples={self.t.size})")

    @property
    def balance_residual(self) -> np.ndarray:
        """(total − total₀) − (W_ext − W_diss): zero up to integration error."""
        law = Law("work_balance")
        value = self.law_value(law)
        return law.deviation(value, value[0])  # type: ignore[no-any-return]

    def law_value(self, law: Law) -> np.ndarray:
        """The quantity ``law`` keeps, at every sample (energy terms or invariants must have
        been evaluated)."""
        return law.value(self, self.invariants)  # type: ignore[no-any-return]

    def law_drift(self, law: Law, scale: float | np.ndarray) -> np.ndarray:
        """Relative drift of ``law`` at every sample against its first sample."""
        value = self.law_value(law)
        return law.drift(value, value[0], scale)  # type: ignore[no-any-return]

    def event_times(self, name: str | None = None) -> np.ndarray:
        """Times of the events met (of one event name, if given)."""
        return np.array([t for t, n in self.events if name is None or n == name])

    def mode(self, name: str) -> np.ndarray:
        assert self.modes is not None
        return self.modes[:, [c.name for c in self.model.modes].index(name)]

    def coordinate(self, name: str) -> np.ndarray:
        names = [c.name for c in self.model.coordinates]
        return self.q[:, names.index(name)]

    def rate(self, name: str) -> np.ndarray:
        names = [c.name for c in self.model.coordinates]
        return self.v[:, names.index(name)]


#: The run settings :func:`load_system` takes beside a system's parameters, under the names of
#: the nodes' ROS parameters: the defaults of :func:`simulate` for that model.
API_SETTINGS = ("method", "tolerance", "publish_rate")
#: Settings of a running node only, with why ``simulate`` has no use for them.
NODE_SETTINGS = {
    "real_time_factor": "simulate() runs as fast as possible",
    "constraint_limit": "simulate() has no constraint guard (see the invariants instead)",
    "effort_timeout": "simulate() takes no effort commands",
    "effort_wait": "simulate() takes no effort commands",
    "warn_drift": "a threshold of the diagnostics node",
    "error_drift": "a threshold of the diagnostics node",
}
_SETTINGS: weakref.WeakKeyDictionary[Model, dict[str, float | str]] = \
    weakref.WeakKeyDictionary()


def load_system(system_id: str, **values: object) -> Model:
    """A model of ``system_id`` with its parameters ``values`` (validated: ParameterError),
    and run settings under the names the nodes' ROS parameters use: ``method``,
    ``tolerance`` and ``publish_rate`` (samples per simulated second) are what
    :func:`simulate` uses for this model unless it is given others."""
    settings: dict[str, float | str] = {}
    for name in list(values):
        if name in NODE_SETTINGS:
            raise ParameterError(name, f"a setting of a running node (scenes, --set, ROS "
                                 f"parameters): {NODE_SETTINGS[name]}")
        if name in API_SETTINGS:
            settings[name] = _setting(name, values.pop(name))
    model = _load_model(system_id, **values)
    if settings:
        _SETTINGS[model] = settings
    return model


def _setting(name: str, value: object) -> float | str:
    """A run setting given to the API, checked against its one range."""
    if name == "method":
        if not isinstance(value, str) or value not in METHODS:
            raise ParameterError("method", f"must be one of {', '.join(METHODS)} (got "
                                 f"{shown(value)})")
        return value
    return float((TOLERANCE if name == "tolerance" else PUBLISH_RATE).check(value, name))


def run_settings(model: Model) -> dict[str, float | str]:
    """The run settings :func:`load_system` was given for ``model`` (empty if none)."""
    return dict(_SETTINGS.get(model, {}))


def output_times(t_end: float, output_dt: float, t0: float = 0.0) -> np.ndarray:
    if not (math.isfinite(t_end) and t_end > t0):
        raise ParameterError("t_end", f"must be a finite time after {t0:g} (got {t_end!r})")
    if not (math.isfinite(output_dt) and output_dt > 0):
        raise ParameterError("output_dt", f"must be a positive time (got {output_dt!r})")
    n = int(math.floor((t_end - t0) / output_dt + 1e-9))
    t = output_dt * np.arange(n + 1.0)
    if t0:
        t += t0
    if t[-1] < t_end - 1e-12 * max(1.0, abs(t_end)):
        t = np.append(t, t_end)
    return t


def resolve_settings(model: Model, tolerance: float | None, method: str | None,
                     outputs: tuple[str, ...], output_dt: float | None,
                     publish_rate: float | None) -> tuple[float, str, float]:
    """The tolerance, method and output interval of a run of ``simulate`` (or
    ``simulate_many``): those given, else those :func:`load_system` was given, else the
    defaults; the outputs checked."""
    if outputs != OUTPUTS:
        if not isinstance(outputs, tuple | list):
            raise ParameterError("outputs", f"a tuple of output names, some of "
                                 f"{', '.join(OUTPUTS)} (got {shown(outputs)})")
        for o in outputs:
            if o not in OUTPUTS:
                raise ParameterError("outputs",
                                     f"unknown output {o!r} (known: {', '.join(OUTPUTS)})")
    given = _SETTINGS.get(model, {})
    tolerance = float(given.get("tolerance", TOLERANCE.default) if tolerance is None
                      else tolerance)
    method = str(given.get("method", "auto") if method is None else method)
    if output_dt is not None and publish_rate is not None:
        raise ParameterError("publish_rate", "not with output_dt (the same sampling)")
    if output_dt is None:
        rate = given.get("publish_rate", PUBLISH_RATE.default) if publish_rate is None \
            else _setting("publish_rate", publish_rate)
        output_dt = 1.0 / float(rate)
    return tolerance, method, output_dt


def simulate(model: Model, t_end: float, output_dt: float | None = None,
             tolerance: float | None = None, method: str | None = None,
             outputs: tuple[str, ...] = OUTPUTS, step: float | None = None,
             closed_form: bool = False, work_terms: bool = True,
             publish_rate: float | None = None) -> SimulationResult:
    """Integrate ``model`` from its initial state to ``t_end``, sampling every ``output_dt``
    (or ``publish_rate`` samples per simulated second, as the nodes' setting of that name).

    Unless given here, ``method``, ``tolerance`` and the sampling are the ones
    :func:`load_system` was given for the model, else ``auto``, 1e-10 and 100 per second.
    ``tolerance`` is a contract on the end-point error of the state (relative and absolute),
    not a per-step setting: see ``mechsim.integrators``.
    ``method``: "auto", "dop853", "dopri5", "radau15", "gauss6", "exact", "yoshida8",
    "yoshida6" or "verlet" (see mechsim.integrators; ``auto`` knows the horizon ``t_end``);
    ``closed_form=True`` lets "auto" use the exact propagator.
    ``outputs``: which of energy, invariants, observables, frames to evaluate (energy always
    when asked by the balance). ``work_terms=False``: the work terms are not needed (no
    work balance): ``work_external`` and ``work_dissipated`` are NaN, and the explicit pairs
    leave them out of their arithmetic and step control. Wall time covers integration and
    output evaluation.
    """
    start = time.perf_counter()
    if isinstance(outputs, list):
        outputs = tuple(outputs)  # (the set-up keyed by its entries)
    set_up = _set_up(model, t_end, output_dt, tolerance, method, outputs, step, closed_form,
                     work_terms, publish_rate)
    prepared = set_up.prepared
    if prepared is not None:  # (``PreparedRun.run`` inline: a method call less per call)
        buf = np.empty(prepared.shape)
        if prepared.call(*prepared.arguments, buf) == _OK:
            return SimulationResult.of_run(model, set_up, buf, time.perf_counter() - start)
        # (stopped short: an event, the step budget, a stiff phase, a failure: the stepper
        # runs it from the start, to go on or raise as the solver contract says)
    tolerance, method = set_up.tolerance, set_up.method
    t = set_up.t.copy()
    stepper: Stepper = make_stepper(model, method, tolerance, step=step,
                                    closed_form=closed_form, horizon=t_end,
                                    work_terms=work_terms)
    Y = stepper.advance(t)
    at = model.layout
    if not work_terms:  # (methods other than the explicit pairs integrate them anyway)
        Y[:, at.work_external] = Y[:, at.work_dissipated] = np.nan
    out = evaluate(model, t, Y, stepper.p, outputs)
    wall = time.perf_counter() - start
    return SimulationResult(model=model, method=stepper.method, tolerance=tolerance, t=t,
                            q=Y[:, at.q], v=model.rates(t, Y, stepper.p),
                            work_external=Y[:, at.work_external],
                            work_dissipated=Y[:, at.work_dissipated], outputs=out,
                            wall_time=wall, n_steps=stepper.n_steps,
                            events=[e for e in stepper.events if e[0] <= t[-1]],
                            modes=Y[:, at.modes], n_evaluations=stepper.n_evaluations,
                            n_rejected=stepper.n_rejected,
                            error_estimate=stepper.error_estimate)


@dataclass(frozen=True)
class _SetUp:
    """What a call of ``simulate`` works out before it runs: the tolerance and method it
    resolves, its output times, its run plan (None: the stepper runs it) and that plan's
    run prepared (``integrators.runs.PreparedRun``), with what its result is made of: the
    method the plan runs, the outputs asked for and the columns of q and v."""

    tolerance: float
    method: str
    t: np.ndarray
    plan: Plan | None
    prepared: PreparedRun | None
    state: StateColumns
    outputs: tuple[str, ...]
    run_method: str
    layout: RunLayout | None


_OK = int(Status.OK)


def _work_out(model: Model, t_end: float, output_dt: float | None, tolerance: float | None,
              method: str | None, outputs: tuple[str, ...], step: float | None,
              closed_form: bool, work_terms: bool, publish_rate: float | None,
              kept: bool = False) -> _SetUp:
    """The set-up of a call; ``kept``: it will serve many calls if its grid is short enough
    (``SET_UP_SAMPLES``): its run may then go through the compiled loop's entry point
    (``PreparedRun``)."""
    tolerance, method, output_dt = resolve_settings(model, tolerance, method, outputs,
                                                    output_dt, publish_rate)
    t = output_times(t_end, output_dt)
    plan = plan_run(model, method, tolerance, outputs, step=step, horizon=t_end,
                    closed_form=closed_form, work_terms=work_terms)
    prepared = None
    if plan is not None:
        at = model.layout
        prepared = plan.prepare(model, model.initial_y(), model.parameter_vector(), t,
                                None if work_terms else (at.work_external, at.work_dissipated),
                                entry=kept and t.size <= SET_UP_SAMPLES)
    return _SetUp(tolerance, method, t, plan, prepared, StateColumns.of(model), outputs,
                  method if plan is None else plan.method,
                  None if prepared is None else prepared.layout)


def _set_up(model: Model, *arguments: object) -> _SetUp:
    """``_work_out`` for a call of ``simulate`` with these ``arguments`` (after ``model``, in
    its order). Kept per model and arguments (every argument is in the key; a model and the
    run settings it was loaded with never change; at most ``PLANS_PER_MODEL`` a model) for
    grids of at most ``SET_UP_SAMPLES`` samples (a longer run's set-up costs little beside its
    steps); arguments that cannot be keyed (arrays) are worked out afresh. Its output times
    are read-only: a run copies them."""
    try:
        found = _SET_UPS.get(model, arguments)
    except TypeError:  # unhashable
        return _work_out(model, *arguments)  # type: ignore[arg-type]
    if found is NOT_KEPT:
        found = _work_out(model, *arguments, kept=True)  # type: ignore[arg-type,misc]
        if found.t.size > SET_UP_SAMPLES:
            return found  # type: ignore[no-any-return]
        found.t.flags.writeable = False
        _SET_UPS.keep(model, arguments, found)
    return found  # type: ignore[no-any-return]


#: The longest output grid whose set-up ``simulate`` keeps (``_set_up``).
SET_UP_SAMPLES = 1024
_SET_UPS = PerModel()
