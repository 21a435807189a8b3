"""A whole run in one compiled call: what ``mechsim.simulate`` does for the explicit pairs,
radau15 and the closed forms on a model without events, without a Python stepper in between.

``plan_run`` decides once per model and set of inputs what ``make_stepper`` would make (the
method, ``auto``'s choice included, its tolerance and options) and keeps it as a
``RunPlan``: the compiled call (``compiled.runs.erk_call``, ``radau15_call``), the kernel
set with the outputs asked for, and every option. ``RunPlan.prepare`` adds an initial state
and output times and makes every argument of the call once (``PreparedRun``), whose ``run``
then costs one buffer and one call into compiled code, which starts the method as its
stepper does, steps, and evaluates the outputs into that buffer (``RunLayout``); its rows
equal the stepper's bit for bit (``tests/test_fast_path.py``). A run the loop cannot finish
(an event, a step limit, a stiff phase: any status but OK) is left to the stepper, which goes
on or raises as the solver contract says. ``exact`` has a plan of its own
(``ClosedFormPlan``): the model's closed form at the output times, then the outputs, as its
stepper and ``evaluate`` do: all in one compiled call (``compiled.runs.closed_call``) where
the model's closed form is compiled (``Model.closed_form_kernel``), else ``propagate`` and
then the outputs in one compiled call.
"""

from __future__ import annotations

import functools
import math
import weakref
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numba import njit

from mechsim.integrators.auto import Auto
from mechsim.integrators.base import Request, Stepper, event_directions
from mechsim.integrators.closed_form import ClosedForm
from mechsim.integrators.compiled import load, load_runs
from mechsim.integrators.dop853 import DOP853
from mechsim.integrators.dopri5 import DOPRI5
from mechsim.integrators.model import SteppableModel as Model
from mechsim.integrators.radau15 import Radau15
from mechsim.integrators.state import Status

#: The kernel functions each output needs (``OUTPUTS`` of ``mechsim.simulate``).
_OUTPUT_KERNELS = {"energy": "energy", "invariants": "invariants",
                   "observables": "observables", "frames": "frames"}


@dataclass(frozen=True)
class RunLayout:
    """Where a prepared run (``PreparedRun``) writes into its one buffer, a 2-D array of rows
    as wide as the state (``shape``): the rows Y (its first ``samples`` rows), then, one
    after the other in the flat buffer, the output times, the outputs E, I, O, F
    (``widths``: their columns, 0 for one not wanted; ``columns``: the columns of each, what
    the compiled call is told), the parameters and the counters
    (``compiled.runs._laid_out``)."""

    samples: int
    n_y: int
    n_p: int
    widths: tuple[int, int, int, int]  # energy terms, invariants, observables, frames
    columns: tuple[int, int, int, int]  # the same, wanted or not
    _parts: tuple[slice, ...] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        m = self.samples
        ce, ci, co, cf = self.widths
        sizes = (m * self.n_y, m, m * ce, m * ci, m * co, m * cf * 7, self.n_p, COUNTERS)
        ends = np.cumsum(sizes).tolist()
        object.__setattr__(self, "_parts", tuple(
            slice(end - size, end) for end, size in zip(ends, sizes, strict=True)))

    @property
    def shape(self) -> tuple[int, int]:
        """The buffer's shape: as many rows of Y's width as hold every part."""
        return -(-int(self._parts[-1].stop) // self.n_y), self.n_y

    def _cut(self, buf: np.ndarray, part: int) -> np.ndarray:
        """Part ``part`` of ``buf`` (0 Y, 1 t, 2 E, 3 I, 4 O, 5 F, 6 p, 7 counters), flat."""
        return buf.reshape(-1)[self._parts[part]]

    def times(self, buf: np.ndarray) -> np.ndarray:
        return self._cut(buf, 1)

    def rows(self, buf: np.ndarray) -> np.ndarray:
        return buf[:self.samples]

    def outputs(self, buf: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """E, I, O, F as ``evaluate_arrays`` makes them (the ones not wanted without columns)."""
        m = self.samples
        ce, ci, co, cf = self.widths
        return (self._cut(buf, 2).reshape(m, ce), self._cut(buf, 3).reshape(m, ci),
                self._cut(buf, 4).reshape(m, co), self._cut(buf, 5).reshape(m, cf, 7))

    def parameters(self, buf: np.ndarray) -> np.ndarray:
        return self._cut(buf, 6)

    def counters(self, buf: np.ndarray) -> np.ndarray:
        """Rows written, steps, evaluations, rejections, error estimate, time reached."""
        return self._cut(buf, 7)


#: The counters at the end of a prepared run's buffer.
COUNTERS = 6


@dataclass(frozen=True)
class PreparedRun:
    """A plan's run from one initial state to fixed output times, every argument of its
    compiled call made once (``RunPlan.prepare``): ``run`` costs one buffer and one call.

    The arguments are this object's own (never handed out; the call copies the state, the
    times and the parameters into the buffer before it writes), so their types never change:
    ``call`` may be the entry point of the compiled overload for exactly these types, checked
    when it was prepared, which spares numba's type dispatch."""

    layout: RunLayout
    call: Any
    arguments: tuple[Any, ...]
    shape: tuple[int, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "shape", self.layout.shape)

    def run(self) -> tuple[int, np.ndarray]:
        """(status, buffer): the status a ``Status`` value as an int."""
        buf = np.empty(self.shape)
        return self.call(*self.arguments, buf), buf


@dataclass(frozen=True)
class RunPlan:
    """What a run's compiled call (``compiled.runs.erk_call``, ``radau15_call``: ``loop``)
    gets besides the initial state, the output times and its buffer: the kernel set, the
    events' directions, its integer options (max_steps, then for the explicit pairs the pair,
    its stages and the entries integrated) and its float options (``compiled.runs``), and the
    outputs wanted."""

    method: str
    ks: Any
    ev_dir: np.ndarray
    options: tuple[int, int, int, int]
    floats: tuple[float, ...]
    want: tuple[bool, bool, bool, bool]
    loop: Any

    def prepare(self, model: Model, y: np.ndarray, p: np.ndarray, t: np.ndarray,
                work_columns: tuple[int, int] | None, entry: bool) -> PreparedRun:
        """The run of ``model`` from ``y`` to the times ``t``; ``work_columns``: the columns
        of Y to set NaN after the run (the work terms not wanted). With ``entry``, the call
        goes through the compiled entry point where the arguments' types are the ones the
        loop was compiled for."""
        layout = _layout(model, y, p, t, self.want)
        arguments = (self.ks, *_call_data(layout, work_columns, self.floats, y, p, t,
                                          (*self.options, *self.ev_dir.tolist())))
        return PreparedRun(layout, _entry(self.loop, arguments) if entry else self.loop,
                           arguments)


def _call_data(layout: RunLayout, work_columns: tuple[int, int] | None,
               floats: tuple[float, ...], y: np.ndarray, p: np.ndarray, t: np.ndarray,
               options: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The ``ints`` and ``data`` of a compiled call (``compiled.runs.CALL_INTS``), made once:
    the call never writes them."""
    ints = np.array([*map(int, (w > 0 for w in layout.widths)), *layout.columns[1:],
                     *(work_columns or (-1, -1)), y.size, p.size, t.size, len(floats),
                     *options], np.int64)
    data = np.concatenate([np.array(floats, np.float64), np.asarray(y, np.float64).ravel(),
                           np.asarray(p, np.float64).ravel(), np.asarray(t, np.float64)])
    return ints, data


def _layout(model: Model, y: np.ndarray, p: np.ndarray, t: np.ndarray,
            want: tuple[bool, bool, bool, bool]) -> RunLayout:
    """The layout of a run of ``model``: the outputs' columns as many as its kernels write
    (at least one, as ``simulate.output_buffers``), none for an output not wanted."""
    sizes = model.kernels.sizes
    columns = (3, max(sizes["N_INV"], 1), max(sizes["N_OBS"], 1), max(sizes["N_FRAMES"], 1))
    return RunLayout(t.size, y.size, p.size,
                     tuple(c if w else 0  # type: ignore[arg-type]
                           for c, w in zip(columns, want, strict=True)), columns)


@functools.cache
def _motion(rows: Any) -> Any:
    """The compiled value of a model's closed form ``rows`` (made once per function)."""
    from mechsim.codegen.contract import make_motion

    return make_motion(rows)


def _entry(loop: Any, arguments: tuple[Any, ...]) -> Any:
    """The entry point of ``loop``'s compiled overload for ``arguments`` and a buffer
    (``RunLayout.shape``: 2-D float64), if it has one for exactly their types; else ``loop``
    (numba dispatches)."""
    from numba import typeof

    signature = tuple(map(typeof, (*arguments, np.empty((1, 1)))))
    overloads = getattr(loop, "overloads", None)
    if overloads is None:
        return loop
    if signature not in overloads:
        loop.compile(signature)
    overload = overloads.get(signature)
    return loop if overload is None else getattr(overload, "entry_point", loop)


@dataclass(frozen=True)
class ClosedFormPlan:
    """``exact`` from the model's initial state: ``Model.propagate`` at the output times and
    the outputs wanted in one compiled call (``ks``: the output kernels alone). Without the
    work terms, the closed form may leave them NaN: the first ``n_finite`` entries of each row
    (q and q̇) are the ones that must be finite."""

    method: str
    ks: Any
    want: tuple[bool, bool, bool, bool]
    work_terms: bool
    n_finite: int

    def run(self, model: Model, y: np.ndarray, p: np.ndarray, t: np.ndarray, Y: np.ndarray,
            E: np.ndarray, I: np.ndarray, O: np.ndarray, F: np.ndarray  # noqa: E741
            ) -> tuple[int, int, int, int, int, float, float]:
        """As ``RunPlan.run``: one evaluation of the closed form, no steps; a status other
        than OK where there is none from this state or it is not finite (the stepper then
        raises what the solver contract says)."""
        rows = model.propagate(0.0, y, t, self.work_terms)
        if rows is None:
            return Status.NOT_CONVERGED, 0, 0, 0, 0, 0.0, 0.0
        if not _finite_columns(rows, self.n_finite):
            return Status.NOT_FINITE, 0, 0, 0, 0, 0.0, 0.0
        Y[:] = rows
        if any(self.want):
            load().evaluate_outputs(self.ks, t, Y, p, *self.want, E, I, O, F)
        return Status.OK, t.size, 0, 1, 0, 0.0, float(t[-1])

    def prepare(self, model: Model, y: np.ndarray, p: np.ndarray, t: np.ndarray,
                work_columns: tuple[int, int] | None, entry: bool) -> PreparedRun:
        """As ``RunPlan.prepare``: where the model's closed form is compiled
        (``Model.closed_form_kernel``), one call of ``compiled.runs.closed_call``, which does
        what ``run`` does; else ``run`` into the buffer of its layout."""
        layout = _layout(model, y, p, t, self.want)
        kernel = model.closed_form_kernel(y)
        if kernel is None:
            return PreparedRun(layout, self._into, (model, layout, y.copy(), p.copy(),
                                                    t.copy(), work_columns))
        rows, constants = kernel
        arguments = (_motion(rows), self.ks,
                     *_call_data(layout, work_columns, tuple(map(float, constants)), y, p, t,
                                 (self.n_finite,)))
        loop = load_runs().closed_call
        return PreparedRun(layout, _entry(loop, arguments) if entry else loop, arguments)

    def _into(self, model: Model, layout: RunLayout, y: np.ndarray, p: np.ndarray,
              t: np.ndarray, work_columns: tuple[int, int] | None, buf: np.ndarray) -> int:
        times, parameters, Y = layout.times(buf), layout.parameters(buf), layout.rows(buf)
        times[:] = t
        parameters[:] = p
        status, *counters = self.run(model, y.copy(), parameters, times, Y,
                                     *layout.outputs(buf))
        layout.counters(buf)[:] = counters
        if work_columns is not None:
            Y[:, list(work_columns)] = np.nan
        return status


Plan = RunPlan | ClosedFormPlan


@njit(cache=True)
def _finite_columns(rows: np.ndarray, n: int) -> bool:
    """Whether the first ``n`` entries of every row are finite (one pass, no temporaries)."""
    for i in range(rows.shape[0]):
        for j in range(n):
            if not math.isfinite(rows[i, j]):
                return False
    return True


def plan_run(model: Model, method: str, tolerance: float, which: tuple[str, ...], *,
             step: float | None = None, horizon: float | None = None,
             closed_form: bool = False, work_terms: bool = True) -> Plan | None:
    """The plan of a run of ``model`` from its initial state at t = 0 as ``make_stepper(model,
    method, tolerance, ...)`` would make it with the options of ``base.Request`` given here
    (``method`` already checked against the model), with the outputs ``which``; None where
    the stepper must run it (events, the other methods). Kept per model and inputs
    (``_PLANS``, at most ``PLANS_PER_MODEL`` a model): a model's parameters never change."""
    key = (method, tolerance, which, step, horizon, closed_form, work_terms)
    plan = _PLANS.get(model, key)
    if plan is NOT_KEPT:
        plan = _make_plan(model, method, tolerance,
                          Request(step=step, horizon=horizon, closed_form=closed_form,
                                  work_terms=work_terms), which)
        _PLANS.keep(model, key, plan)
    return plan  # type: ignore[return-value]


#: What ``kept_for`` returns for a key it does not keep.
NOT_KEPT: Any = object()


class PerModel:
    """Values kept per model object and key, at most ``PLANS_PER_MODEL`` a model (all
    forgotten when full: a sweep over horizons or tolerances), each model's gone with it.
    Looked up by the model's ``id`` (a weak reference's ``finalize`` drops the entry before
    the object's memory, and so its id, can be reused): a lookup costs two dict reads."""

    def __init__(self) -> None:
        self._kept: dict[int, dict[Any, Any]] = {}

    def get(self, model: object, key: Any) -> Any:
        """What is kept for ``model`` under ``key``, else ``NOT_KEPT`` (TypeError for a key
        that cannot be hashed)."""
        kept = self._kept.get(id(model))
        if kept is None:
            hash(key)
            return NOT_KEPT
        return kept.get(key, NOT_KEPT)

    def keep(self, model: object, key: Any, value: Any) -> None:
        """Keep ``value`` for ``model`` under ``key``."""
        kept = self._kept.get(id(model))
        if kept is None:
            kept = self._kept[id(model)] = {}
            weakref.finalize(model, self._kept.pop, id(model), None)
        elif len(kept) >= PLANS_PER_MODEL:
            kept.clear()
        kept[key] = value


#: Plans (and other per-run set-ups) kept per model.
PLANS_PER_MODEL = 64
_PLANS = PerModel()


def _make_plan(model: Model, method: str, tolerance: float, request: Request,
               which: tuple[str, ...]) -> Plan | None:
    from mechsim.integrators import method_class

    cls = method_class(method)
    cls.check(model)
    if model.events or request.step is not None or not 0.0 < tolerance < 1.0:
        return None  # (the stepper says what is wrong with the tolerance)
    local, options = tolerance, dict[str, Any]()
    if cls is Auto:
        cls, local, options = Auto.decide(model, model.initial_y(), 0.0, tolerance, request)
    elif issubclass(cls, Stepper):
        options = cls.options(request)
    want = tuple(name in which for name in _OUTPUT_KERNELS)
    if cls is ClosedForm and not request.given_state:
        n_y = model.initial_y().size
        return ClosedFormPlan(ClosedForm.method, model.kernels.kernel_set(*which),
                              want, request.work_terms,  # type: ignore[arg-type]
                              n_y if request.work_terms else 2 * model.kernels.n_q)
    needed = ("rhs", "project", "event", "energy", *which)
    loops = load_runs()
    ks = model.kernels.kernel_set(*needed)
    max_steps = 10_000_000
    if cls in (DOP853, DOPRI5) and set(options) <= {"work_terms"}:
        assert issubclass(cls, DOP853)
        work = options.get("work_terms", True)
        n_y = model.initial_y().size
        tol = max(local * cls.LOCAL_FACTOR, cls.LOCAL_FLOOR)
        return RunPlan(cls.method, ks, event_directions(model),
                       (max_steps, int(cls.PAIR), cls.N_STAGES,
                        n_y if work else 2 * model.kernels.n_q),
                       (tol, tol, math.inf), want, loops.erk_call)  # type: ignore[arg-type]
    if cls is Radau15 and set(options) <= {"eps"}:
        lo, hi = Radau15.EPS_RANGE
        eps = options.get("eps", min(max(0.01 * math.sqrt(local), lo), hi))
        tau = float(model.time_scale())
        return RunPlan(Radau15.method, ks, event_directions(model),
                       (max_steps, 0, 0, 0),
                       (eps, tau, tau**2, Radau15.FLOOR, float(local), float(local)),
                       want, loops.radau15_call)  # type: ignore[arg-type]
    return None
