"""Ensembles: many members of one system (the same equations, each with its own parameter
values and initial state) integrated to the same output times, one compiled call per method
for all of them, the members spread over the cores (``compiled.runs``: ``erk_many``,
``radau15_many``, ``outputs_many``).

Each member gets what ``make_stepper`` would make for it alone (``auto``'s choice included,
decided from its own parameters and state), so the tolerance is the same contract per member
and its rows equal a single run's bit for bit. Members of the explicit pairs and of radau15
(without events, fixed steps or other options) share a compiled call per method and
tolerance; the others, and a member that stops short in the compiled call (an event, the
step budget, a stiff phase, a failure), run by their own stepper, which goes on or raises as
the solver contract says.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numba
import numpy as np

from mechsim.errors import IntegrationError
from mechsim.integrators.auto import Auto
from mechsim.integrators.base import Request, Stepper, event_directions
from mechsim.integrators.compiled import load_runs
from mechsim.integrators.dop853 import DOP853
from mechsim.integrators.dopri5 import DOPRI5
from mechsim.integrators.model import SteppableModel as Model
from mechsim.integrators.radau15 import Radau15
from mechsim.integrators.state import DOP853_STATE, RADAU_STATE, Status

#: The step budget of a member in the compiled call (a stepper's default ``max_steps``).
MAX_STEPS = 10_000_000
#: The output kernels of ``mechsim.simulate.OUTPUTS``, in its order.
OUTPUT_KERNELS = ("energy", "invariants", "observables", "frames")


@dataclass
class Members:
    """The members of an ensemble: a model each (one system and formulation: one set of
    kernels), their initial states (N, len(y)) and parameter vectors (N, n_p);
    ``given_state``: the states are not the models' initial ones."""

    models: list[Model]
    y0: np.ndarray
    P: np.ndarray
    given_state: bool = False


@dataclass
class EnsembleRun:
    """Rows (N, samples, len(y)) and, per member, the method that ran it and its counters;
    the events met by members that ran by their stepper."""

    Y: np.ndarray
    methods: list[str]
    n_steps: np.ndarray
    n_evaluations: np.ndarray
    n_rejected: np.ndarray
    error_estimate: np.ndarray
    events: dict[int, list[tuple[float, str]]] = field(default_factory=dict)


@dataclass(frozen=True)
class _Choice:
    """What runs a member: the method, the tolerance its stepper is made with, its options."""

    method: type[Stepper]
    tolerance: float
    options: tuple[tuple[str, Any], ...]

    @property
    def compiled(self) -> bool:
        """Whether the member runs in a shared compiled call."""
        names = {name for name, _ in self.options}
        if self.method in (DOP853, DOPRI5):
            return names <= {"work_terms"}
        return self.method is Radau15 and names <= {"eps"}


def _choose(cls: Any, members: Members, tolerance: float, request: Request) -> list[_Choice]:
    """Each member's choice (``auto`` decides per member, from its own model and state)."""
    n = len(members.models)
    if cls is not Auto:
        return [_Choice(cls, tolerance, tuple(sorted(cls.options(request).items())))] * n
    choices = []
    for model, y0 in zip(members.models, members.y0, strict=True):
        method, local, options = Auto.decide(model, y0, 0.0, tolerance, request)
        choices.append(_Choice(method, local, tuple(sorted(options.items()))))
    return choices


def integrate_many(cls: Any, members: Members, tolerance: float, t: np.ndarray,
                   request: Request, threads: int | None = None) -> EnsembleRun:
    """Every member of ``members`` from t = 0 to the times ``t`` by method ``cls`` (a class
    of ``METHODS``, checked against the model), ``threads`` cores at most (all if None)."""
    n, m = members.y0.shape[0], t.size
    choices = _choose(cls, members, tolerance, request)
    run = EnsembleRun(np.full((n, m, members.y0.shape[1]), np.nan),
                      [c.method.method for c in choices], np.zeros(n, np.int64),
                      np.zeros(n, np.int64), np.zeros(n, np.int64), np.zeros(n))
    groups, alone = _partition(choices, request)
    before = numba.get_num_threads()
    if threads is not None:
        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    try:
        for choice, idx in groups.items():
            alone += _run_group(choice, np.array(idx, dtype=np.int64), members, t, run)
    finally:
        numba.set_num_threads(before)
    for i in sorted(alone):
        _run_alone(i, choices[i], members, t, request, run)
    return run


def _partition(choices: list[_Choice], request: Request
               ) -> tuple[dict[_Choice, list[int]], list[int]]:
    """The members in shared compiled calls, by choice, and those run alone."""
    kinds = set(choices)
    if len(kinds) == 1:  # one method for all (any but auto): no per-member pass
        (c,) = kinds
        every = list(range(len(choices)))
        return ({c: every}, []) if c.compiled and request.step is None else ({}, every)
    groups: dict[_Choice, list[int]] = {}
    alone: list[int] = []
    compiled = {c: c.compiled and request.step is None for c in kinds}
    for i, c in enumerate(choices):
        if compiled[c]:
            groups.setdefault(c, []).append(i)
        else:
            alone.append(i)
    return groups, alone


class _Group:
    """The stacked arrays of one compiled call (each with a leading axis of all N members; the
    call touches its own members' slices), and the members' steppers for their events:
    steppers of the member's method whose arrays are views of these (``_stepper``), so that
    an event is handled by the stepper's own code and the compiled call goes on from it."""

    def __init__(self, choice: _Choice, members: Members, n_outputs: int) -> None:
        model = members.models[0]
        n, n_y = members.y0.shape
        self.choice, self.members = choice, members
        self.radau = choice.method is Radau15
        self.options = dict(choice.options)
        self.y = np.ascontiguousarray(members.y0, dtype=np.float64).copy()
        self.P = np.ascontiguousarray(members.P, dtype=np.float64)
        self.ev_dir = event_directions(model)
        self.g_old = np.zeros((n, self.ev_dir.size))
        self.comp = np.zeros((n, n_y))
        self.status = np.full(n, -1, dtype=np.int64)
        self.done = np.zeros(n, dtype=np.int64)
        self.restart = np.ones(n, dtype=np.int64)
        self.local = np.full(n, choice.tolerance)
        self.steppers: dict[int, Stepper] = {}
        if self.radau:
            self.state = np.zeros(n, RADAU_STATE)
            size = model.kernels.n_q + 2
            lo, hi = Radau15.EPS_RANGE
            self.eps = np.full(n, self.options.get(
                "eps", min(max(0.01 * math.sqrt(choice.tolerance), lo), hi)))
            self.b, self.g, self.e = (np.zeros((n, 7, size)) for _ in range(3))
            self.F0 = np.zeros((n, size))
            self.dy = np.zeros((n, n_y))
            self.floors = np.zeros((n, 2))
            self.tau = np.ones(n)
        else:
            method: Any = choice.method
            self.state = np.zeros(n, DOP853_STATE)
            self.state["n_integrated"] = (n_y if self.options.get("work_terms", True)
                                          else 2 * model.kernels.n_q)
            self.tol = np.maximum(self.local * method.LOCAL_FACTOR, method.LOCAL_FLOOR)
            self.y_old = self.y.copy()
            self.K = np.zeros((n, method.N_STAGES, n_y))
            self.F = np.zeros((n, 7, n_y))
            defaults = DOP853.__init__.__kwdefaults__ or {}
            self.stiff_steps = float(defaults["stiff_steps_per_output"])

    def call(self, ks: Any, active: np.ndarray, t: np.ndarray, Y: np.ndarray) -> None:
        """One compiled call for the members ``active``."""
        loops = load_runs()
        if self.radau:
            loops.radau15_many(ks, active, self.state, self.y, self.P, t, self.done, Y,
                               self.eps, MAX_STEPS, self.comp, self.b, self.g, self.e,
                               self.F0, self.dy, self.g_old, self.ev_dir, self.floors,
                               self.tau, self.tau**2, Radau15.FLOOR, self.local, self.local,
                               self.restart, self.status)
        else:
            method: Any = self.choice.method
            loops.erk_many(ks, int(method.PAIR), active, self.state, self.y, self.y_old,
                           self.K, self.F, self.P, t, self.done, Y, self.tol, self.tol,
                           math.inf, MAX_STEPS, self.g_old, self.ev_dir, self.comp,
                           self.restart, self.status)

    def _stepper(self, i: int) -> Any:
        """Member ``i``'s stepper on views of the stacked arrays (made at its first event)."""
        if i in self.steppers:
            return self.steppers[i]
        c = self.choice
        st: Any = c.method(self.members.models[i], self.y[i], 0.0, c.tolerance, **self.options)
        st.state, st.y, st.comp, st.g_old, st.p = (self.state[i:i + 1], self.y[i],
                                                    self.comp[i], self.g_old[i], self.P[i])
        if self.radau:
            st.b, st.g, st.e, st.F0, st.dy = self.b[i], self.g[i], self.e[i], self.F0[i], self.dy[i]
        else:
            st.y_old, st.K, st.F, st._t = self.y_old[i], self.K[i], self.F[i], st.state["t"]
            st._restart = 0
        self.steppers[i] = st
        return st

    def resume(self, i: int, gap: float) -> bool:
        """After member ``i`` stopped short: whether the compiled call goes on with it (its
        stepper's ``advance`` would: an event handled, a stiff phase that does not crawl),
        its restart set as the stepper's."""
        status = Status(int(self.status[i]))
        s = self.state[i:i + 1]
        if status == Status.STIFF and not self.radau:
            if float(s["h_old"][0]) * self.stiff_steps >= gap:
                s["stiff_positive"] = 0
                return True
            return False
        if status != Status.EVENT:
            return False
        st = self._stepper(i)
        st.t = float(s["t"][0])
        if self.radau:
            st.a_floor, st.w_floor = self.floors[i]
        try:
            st._handle_event(int(s["last_event"][0]))
        except IntegrationError:
            return False
        if self.radau:
            self.floors[i] = st.a_floor, st.w_floor
        else:
            self.restart[i], st._restart = st._restart, 0
        return True


def _run_group(choice: _Choice, idx: np.ndarray, members: Members, t: np.ndarray,
               run: EnsembleRun) -> list[int]:
    """The members ``idx`` in compiled calls of ``choice``'s method, each resumed after its
    events; the members that stopped otherwise (left to their steppers, from the start)."""
    model = members.models[0]
    ks = model.kernels.kernel_set("rhs", "project", "event", "energy")
    group = _Group(choice, members, t.size)
    if group.radau:
        group.tau[idx] = [float(members.models[i].time_scale()) for i in idx]
    gap = float(t[-1]) / t.size if t.size else 0.0  # a stepper's first advance, from t = 0
    failed: list[int] = []
    active = idx
    while active.size:
        group.call(ks, active, t, run.Y)
        again = active[group.status[active] != Status.OK]
        stopped = [int(i) for i in again if not group.resume(int(i), gap)]
        failed += stopped
        active = again[~np.isin(again, stopped)]
    for name in ("n_steps", "n_evaluations", "n_rejected", "error_estimate"):
        getattr(run, name)[idx] = group.state[name][idx]
    if not group.radau and not group.options.get("work_terms", True):
        n_q = model.kernels.n_q
        run.Y[idx, :, 2 * n_q:2 * n_q + 2] = np.nan
    for i, st in group.steppers.items():
        run.events[i] = [e for e in st.events if e[0] <= t[-1]]
    return failed


def _run_alone(i: int, choice: _Choice, members: Members, t: np.ndarray, request: Request,
               run: EnsembleRun) -> None:
    """Member ``i`` by its own stepper, from its start."""
    model = members.models[i]
    st = choice.method(model, members.y0[i], 0.0, choice.tolerance, **dict(choice.options))
    run.Y[i] = st.advance(t)
    if not request.work_terms:
        n_q = model.kernels.n_q
        run.Y[i, :, 2 * n_q:2 * n_q + 2] = np.nan
    run.methods[i] = st.method
    run.n_steps[i], run.n_evaluations[i] = st.n_steps, st.n_evaluations
    run.n_rejected[i], run.error_estimate[i] = st.n_rejected, st.error_estimate
    run.events[i] = [e for e in st.events if e[0] <= t[-1]]


def evaluate_many(members: Members, t: np.ndarray, Y: np.ndarray, which: tuple[str, ...],
                  buffers: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
                  threads: int | None = None) -> None:
    """The outputs ``which`` of every member at its rows ``Y`` into ``buffers`` (energy,
    invariants, observables, frames: each (N, samples, ...)), members in parallel."""
    if not which:
        return
    ks = members.models[0].kernels.kernel_set(*which)
    want = [name in which for name in OUTPUT_KERNELS]
    before = numba.get_num_threads()
    if threads is not None:
        numba.set_num_threads(max(1, min(threads, numba.config.NUMBA_NUM_THREADS)))
    try:
        load_runs().outputs_many(ks, t, Y, np.ascontiguousarray(members.P), *want, *buffers)
    finally:
        numba.set_num_threads(before)
