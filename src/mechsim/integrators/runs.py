"""A whole run in one compiled call: what ``mechsim.simulate`` does for the explicit pairs,
radau15 and the closed forms on a model without events, without a Python stepper in between.

``plan_run`` decides once per model and set of inputs what ``make_stepper`` would make (the
method, ``auto``'s choice included, its tolerance and options) and keeps it as a
``RunPlan``: the compiled loop (``compiled.runs``), the kernel set with the outputs asked
for, and every argument that does not change from call to call. ``RunPlan.run`` then costs
one call into compiled code, which starts the method as its stepper does, steps, and
evaluates the outputs; its rows equal the stepper's bit for bit (``tests/test_fast_path.py``).
A run the loop cannot finish (an event, a step limit, a stiff phase: any status but OK) is
left to the stepper, which goes on or raises as the solver contract says. ``exact`` has a plan
of its own (``ClosedFormPlan``): the model's closed form at the output times, then the outputs
in one compiled call, as its stepper and ``evaluate`` do.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
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
from mechsim.integrators.state import DOP853_STATE, RADAU_STATE, Status

#: The kernel functions each output needs (``OUTPUTS`` of ``mechsim.simulate``).
_OUTPUT_KERNELS = {"energy": "energy", "invariants": "invariants",
                   "observables": "observables", "frames": "frames"}


@dataclass(frozen=True)
class RunPlan:
    """What one ``RunPlan.run`` passes to the compiled loop (see the module docstring)."""

    method: str
    radau: bool
    ks: Any
    dtype: np.dtype
    fixed: tuple[Any, ...]  # the loop's arguments before y (the erk loop's)
    tail: tuple[Any, ...]  # its arguments between Y and the output flags
    want: tuple[bool, bool, bool, bool]
    loop: Any

    def run(self, model: Model, y: np.ndarray, p: np.ndarray, t: np.ndarray, Y: np.ndarray,
            E: np.ndarray, I: np.ndarray, O: np.ndarray, F: np.ndarray  # noqa: E741
            ) -> tuple[int, int, int, int, int, float, float]:
        """Integrate ``model`` from (0, y) to the times ``t`` into ``Y`` and evaluate the
        outputs wanted into E, I, O, F: (status, rows written, steps, evaluations,
        rejections, error estimate, time reached); the status is a ``Status`` value, as an
        int."""
        state = np.zeros(1, self.dtype)
        we, wi, wo, wf = self.want
        if self.radau:
            return self.loop(self.ks, state, y, p, t, Y, *self.tail,  # type: ignore[no-any-return]
                             we, wi, wo, wf, E, I, O, F)
        return self.loop(self.ks, *self.fixed, state, y, p, t, Y,  # type: ignore[no-any-return]
                         *self.tail, we, wi, wo, wf, E, I, O, F)


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
    plan = kept_for(_PLANS, model, key)
    if plan is NOT_KEPT:
        plan = _make_plan(model, method, tolerance,
                          Request(step=step, horizon=horizon, closed_form=closed_form,
                                  work_terms=work_terms), which)
        keep_for(_PLANS, model, key, plan)
    return plan  # type: ignore[return-value]


#: What ``kept_for`` returns for a key it does not keep.
NOT_KEPT: Any = object()


def kept_for(store: weakref.WeakKeyDictionary[Any, dict[Any, Any]], model: object,
             key: Any) -> Any:
    """What ``store`` keeps for ``model`` under ``key``, else ``NOT_KEPT`` (TypeError for a
    key that cannot be hashed, where ``model`` has a store)."""
    kept = store.get(model)
    return NOT_KEPT if kept is None else kept.get(key, NOT_KEPT)


def keep_for(store: weakref.WeakKeyDictionary[Any, dict[Any, Any]], model: object,
             key: Any, value: Any) -> None:
    """Keep ``value`` for ``model`` under ``key``: at most ``PLANS_PER_MODEL`` a model (all
    forgotten when full: a sweep over horizons or tolerances)."""
    kept = store.get(model)
    if kept is None:
        kept = store[model] = {}
    elif len(kept) >= PLANS_PER_MODEL:
        kept.clear()
    kept[key] = value


#: Plans (and other per-run set-ups) kept per model.
PLANS_PER_MODEL = 64
_PLANS: weakref.WeakKeyDictionary[Model, dict[tuple[Any, ...], Plan | None]] = (
    weakref.WeakKeyDictionary())


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
        return RunPlan(cls.method, False, ks, DOP853_STATE,
                       (int(cls.PAIR), cls.N_STAGES, n_y if work else 2 * model.kernels.n_q),
                       (tol, tol, math.inf, max_steps, event_directions(model)),
                       want, loops.erk_run)  # type: ignore[arg-type]
    if cls is Radau15 and set(options) <= {"eps"}:
        lo, hi = Radau15.EPS_RANGE
        eps = options.get("eps", min(max(0.01 * math.sqrt(local), lo), hi))
        tau = float(model.time_scale())
        return RunPlan(Radau15.method, True, ks, RADAU_STATE, (),
                       (eps, max_steps, event_directions(model), tau, tau**2, Radau15.FLOOR,
                        float(local), float(local)),
                       want, loops.radau15_run)  # type: ignore[arg-type]
    return None
