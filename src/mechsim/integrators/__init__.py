"""Steppers: one contract, interchangeable methods (shape after scipy's ``OdeSolver``).

A stepper owns the integration state of one model and advances it to requested output times:
``advance(t_out) -> Y`` with one row ``[q, v, work_external, work_dissipated]`` per time. The
loops (``kernels.py``) are compiled once per machine and shared by every model: they call the
model's compiled functions through its kernel set (``mechsim.codegen.contract``). This module
holds their state (named records, ``state.py``) and reports what a run cost: ``n_steps``,
``n_evaluations`` (right-hand-side or force calls), ``n_rejected`` and ``error_estimate`` (the
sum of the local error estimates, relative to the state scale).

The tolerance bounds the error at the end of a run of ten time scales, relative to the
state's scale (tests/test_tolerance.py checks it for every system): every method sizes its
steps from it — the adaptive ones step by step, the fixed-step ones from an error estimate at
the start, checked along the run.

Methods:
- ``dop853``: adaptive explicit Runge-Kutta 8(5,3), dense output, events, constraint
  projection after every step (keeps constraint residuals at round-off). Works for every
  model; its local tolerance is a thousandth of the tolerance (errors add up over a run).
  With ``work_terms=False`` (a caller that reads the state only) it and ``dopri5`` integrate
  q and q̇ alone.
- ``dopri5``: adaptive explicit Runge–Kutta 5(4) of Dormand and Prince (FSAL, 6 evaluations
  a step) with its 4th-order dense output, in DOP853's loop (events, projection, stiffness
  test, local tolerance a thousandth of the tolerance): for loose tolerances (~1e-4), where
  DOP853's order over-delivers. Works for every model; only by name (``auto`` never takes it).
- ``radau15``: adaptive 15th-order Gauss–Radau predictor–corrector (the IAS15 scheme,
  generalised to velocity-dependent forces), events, projection: the end error stays at the
  round-off floor over long runs (energy error growing like √N). Works for every model. Its
  steps keep their own length (landing only on the last time asked for); outputs inside a
  step come from the step's expansion where its error estimate is within a thousandth of the
  tolerance, otherwise from a step of their own from the step's start (``n_side``).
- ``yoshida8`` / ``yoshida6`` / ``verlet``: symmetric compositions of velocity Verlet (orders
  8, 6, 2), symplectic and time-reversible, for separable Hamiltonians (bounded energy error).
- ``gauss6``: three-stage Gauss–Legendre collocation (order 6), symplectic, on Hamilton's
  equations in canonical variables (q, p = ∂L/∂q̇) generated from the Lagrangian, for
  conservative systems whose Hamiltonian is not separable (double pendulum, spherical
  pendulum, charged particle in B): bounded energy error, no drift. Fixed step, stage
  equations by fixed-point iteration; a step that does not converge is halved.
- ``exact``: closed-form propagation (``Model.propagate``) where the model has one for its
  parameters (harmonic, damped and driven oscillators, planar and coupled oscillators, Kepler
  via Kepler's equation): exact to round-off at any output times, no steps.
- ``auto`` (``choose_method``, ``make_stepper``): only methods that meet the tolerance, the
  fastest first: ``dop853``; ``radau15`` (without dissipation) below 1e-10 or beyond 100 time
  scales, and where a probe shows DOP853's error outgrowing the tolerance (chaotic motion); with
  ``closed_form=True``, ``exact`` wherever the model has it.

Stiffness (``dop853``, ``dopri5``): Hairer's stiffness test runs inside the loop (see
``kernels.py``); when it fires and the stability-limited step is also crawling — more than
``stiff_steps_per_output`` (1000) steps per output interval — the stepper raises
``StiffnessError`` (an IntegrationError naming the system, with what to change) instead of
crawling on. A stiff but cheap phase (a damped system settled at rest, big steps) goes on. The
test only reads the state: it never changes a non-stiff run.

Events (``dop853``, ``dopri5``, ``radau15``). A model may declare state events
(``Model.events``, each an ``Event(name, direction)``), computed by the kernel function
``event(t, y, p, out)``, and discrete modes (``Model.modes``), extra state entries after the
work terms that stay constant between events. The kernel checks the event functions after every
accepted step, locates the earliest sign change (in the event's direction) on the dense output
to 4 ulps of t, writes the outputs up to it and stops there with status ``Status.EVENT``.
``DOP853.advance`` then calls ``model.handle_event(index, t, y) -> y_new`` (a velocity jump, a
new mode, or y unchanged to record a time), restarts the integration at (t, y_new) (projection,
new first stage and initial step; counters kept) and goes on, so ``advance(t_out)`` still
returns every requested row (rows before an event come from the dense output of the step that
crossed it, even when a later call asks for them; a row at exactly the event time holds the
state after the handler). Events are handled when met, also past the last requested time. Each
event is recorded in ``stepper.events`` as (t, name). Models without events skip the event
code.
"""

from __future__ import annotations

import functools
import math
import weakref
from abc import ABC, abstractmethod
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from mechsim import codegen
from mechsim.errors import IntegrationError, ParameterError
from mechsim.integrators import dop853_tableau, dopri5_tableau, state
from mechsim.integrators.model import SteppableModel as Model
from mechsim.integrators.state import (
    DOP853_STATE,
    FIXED_STATE,
    RADAU_STATE,
    Pair,
    Status,
    new_state,
)

# Yoshida (1990), symmetric compositions of a 2nd-order symmetric method; each tuple lists
# w_m ... w_1 and the central weight is 1 - 2 Σ w_i.
_YOSHIDA6 = (0.784513610477560, 0.235573213359357, -1.17767998417887)
_YOSHIDA8 = (1.04242620869991, 1.82020630970714, 0.157739928123617, 2.44002732616735,
             -0.716989419708120e-2, -2.44699182370524, -1.61582374150097)


def _symmetric(outer: tuple[float, ...]) -> np.ndarray:
    w0 = 1.0 - 2.0 * sum(outer)
    return np.array([*outer, w0, *reversed(outer)], dtype=np.float64)


COMPOSITIONS: dict[str, tuple[np.ndarray, int]] = {
    "verlet": (np.array([1.0]), 2),
    "yoshida6": (_symmetric(_YOSHIDA6), 6),
    "yoshida8": (_symmetric(_YOSHIDA8), 8),
}
METHODS = ("auto", "dop853", "dopri5", "radau15", "gauss6", "exact", *COMPOSITIONS)


@functools.cache
def loops() -> ModuleType:
    """The shared compiled loops (``kernels.py``), loaded under a name that hashes their
    source and every module they read (see ``mechsim.codegen``); compiled on first use per
    machine, then loaded from numba's cache."""
    template = Path(__file__).with_name("kernels.py").read_text()
    head, rest = template.split("# >>> stubs", 1)
    tail = rest.split("# <<< stubs", 1)[1]
    text = f"{head}{dop853_tableau.loop_source()}\n\n{dopri5_tableau.loop_source()}{tail}"
    key = codegen.fingerprint(text, codegen.source_fingerprint([dop853_tableau, dopri5_tableau,
                                                                state]))
    return codegen.load_module("loops", key, lambda: text)


#: ``precompile``'s two halves, of about equal compile time (DOP853's loop ~15 s of CPU,
#: radau15's ~13 s, DOPRI5's ~7 s, the rest ~4 s), for set-up to compile on two cores.
PRECOMPILE_PARTS = (("dop853_advance", "erk_initial_step",
                     "composition_advance", "gauss_advance", "evaluate_outputs"),
                    ("radau15_advance", "dopri5_advance"))


def loop_signatures() -> dict[Any, tuple[Any, ...]]:
    """Each shared loop and the numba types of the arguments the steppers pass it: the one
    specialization set-up compiles. An argument of another type (a read-only array, another
    integer width) would make numba compile a second one at run time, in every new
    environment (≈ 20 s of CPU for DOP853's), and nothing would say so."""
    from numba import typeof

    from mechsim.codegen.contract import KERNEL_SET

    L = loops()
    v, m2, m3 = np.zeros(2), np.zeros((2, 2)), np.zeros((2, 2, 2))
    dop, fixed = new_state(DOP853_STATE, 0.0), new_state(FIXED_STATE, 0.0)
    iv = np.zeros(1, dtype=np.int64)
    signatures = {
        L.erk_initial_step: (KERNEL_SET, 0.0, v, v, v, 0.0, 0.0, 0.0, 0),
        **{loop: (KERNEL_SET, dop, v, v, m2, m2, v, v, m2, 0.0, 0.0, 0.0, 0, v, iv, v, 0)
           for loop in (L.dop853_advance, L.dopri5_advance)},
        L.composition_advance: (KERNEL_SET, fixed, v, v, 0, 0, 0.0, v, m2, v, v),
        L.gauss_advance: (KERNEL_SET, fixed, v, v, 0, 0, 0.0, m2, m2, v),
        L.evaluate_outputs: (KERNEL_SET, v, m2, v, True, True, True, True, m2, m2, m2, m3),
        L.radau15_advance: (KERNEL_SET, new_state(RADAU_STATE, 0.0), v, v, v, m2, 0.0, 0, v, m2,
                            m2, m2, v, v, v, iv, 0.0, 0.0, 0.0),
    }
    stray = {loop.__name__ for loop in signatures} ^ {n for p in PRECOMPILE_PARTS for n in p}
    if stray:  # a loop added or renamed without its part: set-up would not compile it
        raise RuntimeError(f"PRECOMPILE_PARTS out of step with the loops: {sorted(stray)}")
    return {loop: tuple(a if a is KERNEL_SET else typeof(a) for a in args)
            for loop, args in signatures.items()}


def precompile(part: int | None = None) -> None:
    """Compile the shared loops for the argument types the steppers pass (once per machine;
    ``tools/bootstrap.py`` calls this so that the first run of any system only compiles that
    system's small kernels): all of them, or ``PRECOMPILE_PARTS[part]``."""
    wanted = None if part is None else set(PRECOMPILE_PARTS[part])
    for loop, types in loop_signatures().items():
        if wanted is None or loop.__name__ in wanted:
            loop.compile(types)


class StiffnessError(IntegrationError):
    """DOP853's stiffness test fired (``Status.STIFF``): the state is kept at the last
    accepted step, whose outputs were all written."""


#: ``auto`` takes radau15 below this tolerance (DOP853 would need local tolerances at
#: round-off) and for horizons longer than ``LONG_HORIZON`` time scales (where DOP853's error,
#: growing with every step, outruns the tolerance while radau15 stays at round-off).
AUTO_RADAU_TOLERANCE = 1e-10
LONG_HORIZON = 100.0


def choose_method(model: Model, method: str, closed_form: bool = False,
                  tolerance: float = 1e-10, horizon: float | None = None) -> str:
    """The method a stepper will use. ``auto`` chooses only among methods that meet the
    tolerance over the horizon (the adaptive ones: their steps follow the tolerance), the
    fastest first: ``exact`` with ``closed_form``, else DOP853, or (without dissipation)
    radau15 at tolerances below ``AUTO_RADAU_TOLERANCE`` or horizons beyond ``LONG_HORIZON``
    time scales; ``make_stepper``
    also takes radau15 where a probe shows DOP853's error outgrowing the tolerance (chaotic
    motion). The fixed-step symplectic methods are for whoever asks for their energy
    behaviour by name."""
    if method not in METHODS:
        raise ParameterError("method", f"must be one of {', '.join(METHODS)} (got {method!r})")
    if method == "exact" or (method == "auto" and closed_form):
        if model.has_closed_form():
            return "exact"
        if method == "exact":
            raise ParameterError("method", f"exact: {model.id} ({model.formulation}) has no "
                                 "closed form for these parameters: use auto or dop853")
    if method == "auto":
        if model.structure.dissipative:
            # Errors decay with the motion, and damping can make the equations stiff, where
            # DOP853 notices and radau15's fixed-point iteration would crawl.
            return "dop853"
        long = horizon is not None and horizon > LONG_HORIZON * model.time_scale()
        return "radau15" if tolerance < AUTO_RADAU_TOLERANCE or long else "dop853"
    if method == "gauss6" and not model.has_canonical_form():
        raise ParameterError("method", f"gauss6 needs a conservative unconstrained system "
                             f"without events; {model.id} ({model.formulation}) is not: "
                             "use dop853 or auto")
    if method in COMPOSITIONS and model.events:
        raise ParameterError("method", f"{method} does not handle events; {model.id} has "
                             "events: use dop853 or auto")
    if method in COMPOSITIONS and not model.structure.separable:
        raise ParameterError("method", f"{method} needs a separable Hamiltonian; "
                             f"{model.id} ({model.formulation}) is not: use dop853 or auto")
    return method


class Stepper(ABC):
    """Integration state of one model; see the module docstring."""

    method: str
    state: np.ndarray  # one record of a dtype of ``state.py`` (a closed form has none)

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float) -> None:
        if not (0.0 < tolerance < 1.0):
            raise ParameterError("tolerance", f"must be in (0, 1) (got {tolerance!r})")
        self.model = model
        self.kernels = model.kernels
        self.p = model.parameter_vector()
        self.tolerance = float(tolerance)
        self.y = np.array(y0, dtype=np.float64)
        self.t = float(t0)
        self.events: list[tuple[float, str]] = []  # (time, event name), in order
        self._stalled = 0  # events in a row at the same time
        self._last_event_t = -math.inf

    @abstractmethod
    def advance(self, t_out: np.ndarray) -> np.ndarray: ...

    def _count(self, name: str) -> int:
        return int(self.state[name][0])

    @property
    def n_steps(self) -> int:
        return self._count("n_steps")

    @property
    def n_evaluations(self) -> int:
        """Calls of the model's right-hand side (or force, for compositions)."""
        return self._count("n_evaluations")

    @property
    def n_rejected(self) -> int:
        return self._count("n_rejected")

    @property
    def error_estimate(self) -> float:
        """Sum of the local error estimates so far, relative to the state scale."""
        return float(self.state["error_estimate"][0])

    def set_parameters(self, p: np.ndarray) -> None:
        """New parameter values, same structure (runtime ROS parameter changes); what the
        model derives from them is recomputed (``complete_parameters``)."""
        self.p = self.model.complete_parameters(p)

    def set_model(self, model: Model) -> None:
        """The same system with new parameter values; the state carries over."""
        self.model = model
        self.set_parameters(model.parameter_vector())

    def _handle_event(self, index: int) -> None:
        """Apply the model's event handler at the event time and restart there (adaptive
        methods with events: ``_restart_after_event``)."""
        t = self.t
        # (the handler gets a copy of its own: what it returns is not shared)
        y_new = np.asarray(self.model.handle_event(index, t, self.y.copy()), dtype=np.float64)
        if y_new.shape != self.y.shape or not np.isfinite(y_new).all():
            raise IntegrationError(f"{self.model.id}: handler of event "
                                   f"{self.model.events[index].name} returned a bad state")
        if t - self._last_event_t <= 1e-12 * max(1.0, abs(t)):
            self._stalled += 1
            if self._stalled > 100:
                raise IntegrationError(f"{self.model.id}: events accumulate at t = {t:.6g} "
                                       "(Zeno behaviour); the model must change mode there")
        else:
            self._stalled = 0
        self._last_event_t = t
        self.events.append((t, self.model.events[index].name))
        self._restart_after_event(t, y_new)

    def _restart_after_event(self, t: float, y: np.ndarray) -> None:
        raise NotImplementedError

    #: Methods that integrate the full right-hand side ``rhs``, so an input the model reads
    #: from ``p`` there (the effort of a Lagrangian model) acts; the others integrate the
    #: separable or canonical forms, or a closed form, which leave it out.
    TAKES_INPUTS = ("dop853", "dopri5", "radau15")

    def restart(self, t: float, y: np.ndarray, p: np.ndarray) -> None:
        """Go on afresh from state ``y`` at time ``t`` with parameters ``p``: no step crosses
        ``t``, so an input held constant over each output interval (zero-order hold) changes
        exactly there. ``y`` is a state the stepper returned at ``t`` (the adaptive methods step
        past their last output time, so their own state may be later). Only ``TAKES_INPUTS``.
        What the model derives from ``p`` is recomputed, as by ``set_parameters``."""
        if self.method not in self.TAKES_INPUTS:
            raise IntegrationError(f"{self.method} takes no inputs: use "
                                   f"{' or '.join(self.TAKES_INPUTS)}")
        self.p = self.model.complete_parameters(p)
        self.t = float(t)
        self._restart_after_event(self.t, np.array(y, dtype=np.float64))

    def _fail(self, status: Status) -> IntegrationError:
        return IntegrationError(f"{self.model.id}: {self.method} stopped at "
                                f"t = {self.t:.6g}: {status.reason}")


class ClosedForm(Stepper):
    """Exact propagation from an anchor state (t₀, y₀) with ``Model.propagate``."""

    method = "exact"

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float,
                 check: bool = True) -> None:
        super().__init__(model, y0, t0, tolerance)
        self.t0, self.y0 = self.t, self.y.copy()
        self.state = new_state(FIXED_STATE, self.t)
        # ``choose_method`` asked about the model's initial state; a run that goes on from
        # another state (a parameter change) is refused here, not at its next output.
        if check and model.propagate(self.t, self.y, np.array([self.t])) is None:
            raise ParameterError("method", f"exact: {model.id} ({model.formulation}) has no "
                                 f"closed form from the state at t = {self.t:.6g}: use auto "
                                 "or dop853")

    def set_model(self, model: Model) -> None:
        super().set_model(model)
        self.t0, self.y0 = self.t, self.y.copy()

    def advance(self, t_out: np.ndarray) -> np.ndarray:
        t_out = np.asarray(t_out, dtype=np.float64)
        if t_out.size == 0:
            return np.empty((0, self.y.size))
        Y = self.model.propagate(self.t0, self.y0, t_out)
        if Y is None:
            raise IntegrationError(f"{self.model.id}: no closed form for these parameters")
        if not np.isfinite(Y).all():
            raise IntegrationError(f"{self.model.id}: exact: non-finite state")
        self.state["n_evaluations"] += 1
        self.t, self.y = float(t_out[-1]), Y[-1].copy()
        self.state["t"] = self.t
        return Y


#: ``DOP853._restart``: the compiled loop's ``restart`` argument.
_NO_RESTART, _RESTART, _RESTART_KEEP_DENSE = 0, 1, 2
_NO_TIMES = np.empty(0)


def _event_directions(model: Model) -> np.ndarray:
    """The directions of the model's events (a zero standing in when it has none), made once
    per model and shared by its steppers; nothing writes it (it stays writeable: a read-only
    array is another numba type, see ``loop_signatures``)."""
    d = _EVENT_DIRECTIONS.get(model)
    if d is None:
        d = np.array([e.direction for e in model.events] or [0], dtype=np.int64)
        _EVENT_DIRECTIONS[model] = d
    return d


_EVENT_DIRECTIONS: weakref.WeakKeyDictionary[Model, np.ndarray] = weakref.WeakKeyDictionary()


class DOP853(Stepper):
    """Hairer's DOP853 with dense output, events and projection (``kernels.dop853_advance``).

    Its controller bounds the local error of every step; over a run those errors add up. So the
    local tolerance (relative and absolute) is ``LOCAL_FACTOR`` × the tolerance, floored at
    ``LOCAL_FLOOR`` (round-off): measured on every system over ten time scales, the end error
    then stays below the tolerance (relative to the state scale) for all but chaotic systems,
    where no method does better than its round-off amplified.

    A subclass with another explicit pair of the shared loop sets ``method`` (its loop is
    ``kernels.<method>_advance``), ``PAIR`` (``state.Pair``, for the restart), ``N_STAGES``
    (rows of K), ``STIFF_EDGE`` (for the message) and its own ``LOCAL_FACTOR``: ``DOPRI5``.

    ``work_terms=False``: the work terms are not integrated (for callers that read the state
    only): the loop's arithmetic and its error norm cover q and q̇ alone, and the work
    columns of what ``advance`` returns are NaN. The step control then judges the state alone,
    as scipy's would on it; the tolerance is met the same way (``tests/test_tolerance.py``)."""

    method = "dop853"
    PAIR = Pair.DOP853
    N_STAGES = 16  # 12 of the step, f at the new point, 3 of the dense output
    STIFF_EDGE = 6.1
    LOCAL_FACTOR = 1e-3
    LOCAL_FLOOR = 1e-14
    # A stiff phase is an error only when it crawls: more steps than this per output interval.
    stiff_steps_per_output = 1000.0

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float,
                 max_step: float = math.inf, max_steps: int = 10_000_000,
                 work_terms: bool = True) -> None:
        super().__init__(model, y0, t0, tolerance)
        n = self.y.size
        self.work_terms = work_terms
        self.K = np.zeros((self.N_STAGES, n))
        self.F = np.zeros((7, n))
        self.y_old = self.y.copy()
        self.comp = np.zeros(n)
        self.max_step = float(max_step)
        self.max_steps = int(max_steps)
        self.rtol = self.atol = max(self.tolerance * self.LOCAL_FACTOR, self.LOCAL_FLOOR)
        self.ev_dir = _event_directions(model)
        self.g_old = np.zeros(self.ev_dir.size)
        self.state = new_state(DOP853_STATE, self.t)
        # All of y (the modes, constant between events, with their zero rates) or q and q̇.
        self.state["n_integrated"] = n if work_terms else 2 * self.kernels.n_q
        self._t = self.state["t"]  # a view: the loop's time, without a field lookup a call
        self.ks = self.kernels.kernel_set("rhs", "project", "event")
        self._restart = _NO_RESTART
        self._reset(self.t, self.y)

    def _reset(self, t: float, y: np.ndarray, keep_dense: bool = False) -> None:
        """Start afresh at (t, y); step, rejection, evaluation and event counters are kept.
        ``keep_dense``: the last step's dense output still serves outputs before t (after an
        event at t, for output times a later ``advance`` asks for). The restart itself (f at
        (t, y), the first step, the event functions) is done by the next ``advance``, in the
        same compiled call (one call from Python fewer: 2.4 µs of a run's fixed cost); with
        constraints it is done here, since it projects ``y``, which a caller may read before."""
        self.y[:] = y
        self.state["t"] = t
        self.comp[:] = 0.0
        # Two restarts before an advance: the dense output is kept only if both keep it.
        self._restart = (_RESTART_KEEP_DENSE if keep_dense and self._restart != _RESTART
                         else _RESTART)
        if self.kernels.n_c > 0:
            self._call(_NO_TIMES, np.empty((0, self.y.size)))

    def _call(self, t_out: np.ndarray, Y: np.ndarray) -> tuple[int, int]:
        """One call of the compiled loop (the pending restart first)."""
        restart, self._restart = self._restart, _NO_RESTART
        return getattr(loops(), f"{self.method}_advance")(
            self.ks, self.state, self.y, self.y_old, self.K, self.F, self.p, t_out, Y,
            self.rtol, self.atol, self.max_step, self.max_steps, self.g_old, self.ev_dir,
            self.comp, restart)

    def set_parameters(self, p: np.ndarray) -> None:
        super().set_parameters(p)
        self._reset(float(self.state["t"][0]), self.y)

    def advance(self, t_out: np.ndarray) -> np.ndarray:
        t_out = np.ascontiguousarray(t_out, dtype=np.float64)
        Y = np.empty((t_out.size, self.y.size))
        t_start = self.t
        s = self.state
        done = 0
        while True:
            status, written = (self._call(t_out[done:], Y[done:]) if done
                               else self._call(t_out, Y))
            done += written
            self.t = float(self._t[0])
            if status == Status.OK:
                break
            h_old = float(s["h_old"][0])
            gap = (t_out[-1] - t_start) / t_out.size if t_out.size else 0.0
            if status == Status.STIFF and h_old * self.stiff_steps_per_output >= gap:
                s["stiff_positive"] = 0  # stiff but not crawling: go on, test again later
                continue
            if status != Status.EVENT:
                break
            self._handle_event(int(s["last_event"][0]))
        if status == Status.STIFF:
            raise StiffnessError(
                f"{self.model.id}: {self.method} stopped at t = {self.t:.6g}: the problem is "
                f"stiff (h·|λ| ≈ {float(s['h_lambda'][0]):.3g} > {self.STIFF_EDGE} on 15 "
                "tests: the step, "
                f"{h_old:.3g} s, is limited by stability, not accuracy, "
                f"{gap / h_old:.3g} steps per output interval; {self.n_steps} steps so "
                "far); the system's time "
                "scales are far apart (huge spring constant or damping?): soften those "
                "parameters, use a looser tolerance or a lower publish rate, or integrate it "
                "with a stiff (implicit) method such as scipy's Radau or BDF")
        if status != Status.OK:
            raise self._fail(status) from None
        if not self.work_terms:
            n_q = self.kernels.n_q
            Y[:done, 2 * n_q:2 * n_q + 2] = np.nan  # not integrated: not a value
        return Y[:done]

    def _restart_after_event(self, t: float, y: np.ndarray) -> None:
        self._reset(t, y, keep_dense=True)


class DOPRI5(DOP853):
    """Dormand and Prince's 5(4) pair (``dopri5_tableau``; 6 evaluations a step, FSAL) with
    its 4th-order dense output, in DOP853's loop: same events, projection, compensated
    summation, stiffness test, counters and error estimate. For loose tolerances, where
    DOP853's 8th order over-delivers: its steps cost half as much, but it needs 2–3× as many.
    Measured (``mechsim bench``, end error 1e-4): faster than DOP853 on the double pendulum
    (0.11–0.13 ms against 0.13), slower on the CR3BP (0.16 against 0.14) and the heavy top
    (0.4 against 0.19). Its local tolerance is ``LOCAL_FACTOR`` × the tolerance like DOP853's:
    the end error over ten time scales at 1e-4 … 1e-8 was within the tolerance on every
    non-chaotic system and formulation but two, within 2× there (central_force_3d cartesian
    1.8× at 1e-4, geodesic 1.1×)."""

    method = "dopri5"
    PAIR = Pair.DOPRI5
    N_STAGES = 7  # 6 of the step and f at the new point; the dense output needs no more
    STIFF_EDGE = 3.25
    LOCAL_FACTOR = 1e-3


class Radau15(Stepper):
    """Adaptive 15th-order Gauss–Radau predictor–corrector (the IAS15 scheme) for
    q̈ = f(t, q, q̇): machine precision over long runs, dense output within the tolerance
    (``dense_tolerance``; see ``kernels.radau15_advance``). Each ``advance`` ends on its last
    output time, so the state is always at the last output returned (or at an event)."""

    method = "radau15"
    #: The controller keeps ε_b = max|b₆| / max|F| at ε = 0.01 √tolerance, within these bounds:
    #: the global error of a 15th-order method falls as ε^(15/7), and below 1e-7 it is at
    #: round-off for every system tested (Kepler e = 0.5: 62 steps an orbit, the end error after
    #: 100 orbits at the double-precision floor, ~1e-12), so smaller steps would only add
    #: round-off.
    eps_range = (1e-7, 1e-4)
    #: The controller's floor of the acceleration scale, as a fraction of the model's natural
    #: scale at the start of the run (see ``_restart``): measured, 1e-4 lets round-off drive
    #: the step at the CR3BP's L1 (10⁷ steps in 10 time scales), 1 competes with Kepler's
    #: accelerations near apocentre (steps 3 % longer, the end error after 100 orbits 3× the
    #: round-off floor); 1e-3 … 0.1 give the same runs.
    FLOOR = 0.01

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float,
                 max_steps: int = 10_000_000) -> None:
        super().__init__(model, y0, t0, tolerance)
        m = self.kernels.n_q + 2
        self.ks = self.kernels.kernel_set("rhs", "project", "event")
        self.state = new_state(RADAU_STATE, self.t)
        self.ev_dir = np.array([e.direction for e in model.events] or [0], dtype=np.int64)
        self.g_old = np.zeros(self.ev_dir.size)
        self.tau = float(model.time_scale())
        self.a_floor = 0.0
        self.w_floor = 0.0
        self.max_steps = int(max_steps)
        self.eps = min(max(0.01 * math.sqrt(self.tolerance), self.eps_range[0]),
                       self.eps_range[1])
        self.b = np.zeros((7, m))
        self.g = np.zeros((7, m))
        self.e = np.zeros((7, m))
        self.F0 = np.zeros(m)
        self.dy = np.zeros(self.y.size)
        self.comp = np.zeros(self.y.size)
        #: Outputs inside a step come from its expansion where the estimate of that error is
        #: within a thousandth of this (relative to the state scale), else from a step of
        #: their own (``kernels._RADAU_DENSE_SHARE``).
        self.dense_tolerance = self.tolerance
        self._restart()

    def _restart(self) -> None:
        """Fresh expansion and first step at the current state (after new parameters).

        The controller's floor of the acceleration scale (``a_floor``; near an equilibrium
        q̈ and b₆ are the round-off of cancelling force terms, and without a floor the step
        would shrink to an underflow) is ``FLOOR`` times the model's natural scale
        max|q|/τ² + max|q̇|/τ here, at the start, and not along the run: a coordinate the
        forces do not depend on may grow without bound (a falling centre of mass), and a
        floor following it made the scale ~1e5 times the accelerations by |R| ~ 8e5 m,
        loosening the control of the orbit beside it to a 2e-4 end error at tolerance
        1e-13. The work terms' scale (``w_floor``: their errors are judged against it, their
        rates may be round-off of cancelling terms) is the system's energy scale here,
        max(|T|, |V|, |h|)."""
        self.kernels.project(self.t, self.y, self.p)
        n = self.kernels.n_q
        self.a_floor = self.FLOOR * float(np.max(np.abs(self.y[:n]) / self.tau**2
                                                 + np.abs(self.y[n:2 * n]) / self.tau,
                                                 initial=0.0))
        energy = np.zeros(3)
        self.kernels.energy(self.t, self.y, self.p, energy)
        self.w_floor = float(np.max(np.abs(energy)))
        self.kernels.rhs(self.t, self.y, self.p, self.dy)
        h0 = loops().erk_initial_step(self.ks, self.t, self.y, self.p, self.dy.copy(),
                                      self.tolerance, self.tolerance, 8.0, self.y.size)
        self.state["h"], self.state["h_old"] = h0, 0.0
        self.state["n_evaluations"] += 2
        self.b[:] = 0.0
        self.g[:] = 0.0
        self.e[:] = 0.0
        self.comp[:] = 0.0
        self.state["last_event"] = -1
        self.state["f0_ready"] = 0
        if self.model.events:
            self.kernels.event(self.t, self.y, self.p, self.g_old)

    @property
    def n_side(self) -> int:
        """Outputs (and event states) taken by a step of their own, where a step's expansion
        was not good enough for them."""
        return self._count("n_side")

    def set_parameters(self, p: np.ndarray) -> None:
        super().set_parameters(p)
        self._restart()

    def _restart_after_event(self, t: float, y: np.ndarray) -> None:
        self.t = t
        self.state["t"], self.state["t_comp"] = t, 0.0
        self.y[:] = y
        self._restart()

    def advance(self, t_out: np.ndarray) -> np.ndarray:
        t_out = np.ascontiguousarray(t_out, dtype=np.float64)
        if t_out.size and t_out[0] < self.t:
            raise IntegrationError(f"{self.method}: output time {t_out[0]} is in the past")
        Y = np.empty((t_out.size, self.y.size))
        advance = loops().radau15_advance
        done = 0
        while True:
            status, written = advance(
                self.ks, self.state, self.y, self.p, t_out[done:], Y[done:], self.eps,
                self.max_steps, self.comp, self.b, self.g, self.e, self.F0, self.dy,
                self.g_old, self.ev_dir, self.a_floor, self.w_floor, self.dense_tolerance)
            done += written
            self.t = float(self.state["t"][0])
            if status != Status.EVENT:
                break
            self._handle_event(int(self.state["last_event"][0]))
        if status != Status.OK:
            raise self._fail(status)
        return Y[:done]


class FixedStep(Stepper):
    """Fixed-step methods: the step is the largest ≤ ``h_max`` dividing each output gap; a
    run of equal gaps goes to the kernel in one call (``_block``). A subclass may recover
    from a failed block (``_recover``: e.g. smaller steps); otherwise the run stops.

    The step comes from the tolerance (unless given): ``_size_step`` estimates the error rate
    from a probe at the current state, at the start and again every ``CHECK_SCALES`` time
    scales along the run (the step shrinks or grows when the estimate moves by more than half);
    the estimated error committed is added to ``error_estimate``."""

    h_max: float
    order: int
    #: The error estimate over this many time scales is to stay within the tolerance.
    HORIZON_SCALES = 10.0
    CHECK_SCALES = 10.0

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float) -> None:
        super().__init__(model, y0, t0, tolerance)
        self.state = new_state(FIXED_STATE, self.t)
        self.comp = np.zeros(self.y.size)
        self.refine = 1
        self.rate = 0.0  # estimated error per unit time at h_max (relative to the state)
        self.fixed = False  # True when the step was given
        self._next_check = math.inf
        self._tau: tuple[Model, bytes, float] | None = None

    def time_scale(self) -> float:
        """The model's time scale, asked once per model and parameter vector: the step is
        re-estimated along the run, and a model may find its scale from its turning points
        (central_force: 17 ms a call, which made long yoshida8 runs 50× slower)."""
        p = self.p.tobytes()
        if self._tau is None or self._tau[0] is not self.model or self._tau[1] != p:
            self._tau = (self.model, p, float(self.model.time_scale()))
        return self._tau[2]

    def _start(self, step: float | None) -> None:
        """Size the first step (subclasses call this once their kernels are ready)."""
        self.fixed = step is not None
        self.h_max = float(step) if step is not None else self._guess()
        self.h_max = self._size_step(self.h_max)
        self._next_check = self.t + self.CHECK_SCALES * self.time_scale()

    @abstractmethod
    def _guess(self) -> float:
        """A first step for the probe: about right for a typical system at this tolerance."""

    @abstractmethod
    def _probe(self, y0: np.ndarray, t0: float, h: float, n: int) -> np.ndarray | None:
        """The state after n steps of h from (t0, y0), on scratch copies (None: it failed)."""

    def _size_step(self, h: float) -> float:
        """Richardson on a probe over a quarter time scale: runs with steps h₁ and h₁/2 differ
        by (1 − 2^−p) of the first one's error; the error per unit time goes as h^p. Returns
        the step whose rate keeps ``HORIZON_SCALES`` time scales at 80 % of the tolerance, at
        most ``_guess()`` (or h itself when the step is fixed), and sets ``rate`` to the rate
        at that step."""
        tau = self.time_scale()
        span = 0.25 * tau
        n1 = max(4, math.ceil(span / h - 1e-9))
        h1 = span / n1
        for _ in range(12):
            a = self._probe(self.y, self.t, h1, n1)
            b = self._probe(self.y, self.t, 0.5 * h1, 2 * n1)
            if a is not None and b is not None:
                break
            n1 *= 4  # the probe failed: far too long a step
            h1 = span / n1
        else:
            raise IntegrationError(f"{self.model.id}: {self.method} cannot size its step "
                                   f"near t = {self.t:.6g}: use dop853")
        scale = 1.0 + np.abs(b)
        err = float(np.max(np.abs(a - b) / scale)) / (1.0 - 2.0 ** -self.order)
        rate1 = err / span
        if self.fixed:
            self.rate = rate1 * (h / h1) ** self.order
            return h
        target = 0.8 * self.tolerance / (self.HORIZON_SCALES * tau)
        grow = (target / rate1) ** (1.0 / self.order) if rate1 > 0.0 else 1.0
        # Never coarser than the time-scale guess: a probe in an easy stretch (free flight
        # before a close encounter) must not license steps the hard one cannot take.
        h_new = min(h1 * max(grow, 1e-3), self._guess())
        self.rate = rate1 * (h_new / h1) ** self.order
        return h_new

    def _check(self) -> None:
        """Along the run: estimate again from the current state and follow it when it moved."""
        h = self._size_step(self.h_max)
        if not self.fixed and not (self.h_max / 1.5 <= h <= 1.5 * self.h_max):
            self.h_max = h
        self._next_check = self.t + self.CHECK_SCALES * self.time_scale()

    @abstractmethod
    def _block(self, Y: np.ndarray, n_sub: int, h: float) -> tuple[Status, int]:
        """Integrate len(Y) output intervals of n_sub steps of h; (status, rows written)."""

    def _recover(self, status: Status) -> bool:
        return False

    def advance(self, t_out: np.ndarray) -> np.ndarray:
        t_out = np.asarray(t_out, dtype=np.float64)
        Y = np.empty((t_out.size, self.y.size))
        k = 0
        while k < t_out.size:
            if self.t >= self._next_check:
                self._check()
            gap = t_out[k] - self.t
            if gap < 0:
                raise IntegrationError(f"{self.method}: output time {t_out[k]} is in the past")
            if gap == 0.0:
                Y[k] = self.y
                k += 1
                continue
            j = k + 1
            while (j < t_out.size and abs((t_out[j] - t_out[j - 1]) - gap) <= 1e-12 * gap
                   and t_out[j] <= self._next_check):
                j += 1
            n_sub = self.refine * max(1, math.ceil(gap / self.h_max - 1e-9))
            t_before = self.t
            status, written = self._block(Y[k:j], n_sub, gap / n_sub)
            if written:
                # Snap the clock to the requested times so round-off does not accumulate in t.
                self.t = float(t_out[k + written - 1])
                self.state["t"] = self.t
                self.y = Y[k + written - 1].copy()
                self.state["error_estimate"] += self.rate * (self.t - t_before)
            if status != Status.OK:
                if self._recover(status):
                    k += written
                    continue
                raise self._fail(status)
            k = j
        return Y


class Composition(FixedStep):
    """Symplectic composition of velocity Verlet (separable systems)."""

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float,
                 method: str = "yoshida8", step: float | None = None) -> None:
        super().__init__(model, y0, t0, tolerance)
        self.method = method
        self.weights, self.order = COMPOSITIONS[method]
        self.a = np.empty(self.kernels.n_q)
        self.ks = self.kernels.kernel_set("accel_q")
        self.kernels.accel_q(self.t, self.y[: self.a.size], self.p, self.a)
        self._start(step)

    def _guess(self) -> float:
        return self.time_scale() * 0.07 * self.tolerance ** (1.0 / self.order)

    def _probe(self, y0: np.ndarray, t0: float, h: float, n: int) -> np.ndarray | None:
        y = y0.copy()
        a = np.empty(self.a.size)
        self.kernels.accel_q(t0, y[: a.size], self.p, a)
        state, Y = new_state(FIXED_STATE, t0), np.empty((1, y.size))
        status, _ = loops().composition_advance(self.ks, state, y, self.p, 1, n, h,
                                                self.weights, Y, a, np.zeros(y.size))
        self.state["n_evaluations"] += state["n_evaluations"][0] + 1
        return Y[0] if status == Status.OK else None

    def set_parameters(self, p: np.ndarray) -> None:
        super().set_parameters(p)
        self.kernels.accel_q(self.t, self.y[: self.a.size], self.p, self.a)
        self._check()

    def _block(self, Y: np.ndarray, n_sub: int, h: float) -> tuple[Status, int]:
        return loops().composition_advance(  # type: ignore[no-any-return]
            self.ks, self.state, self.y, self.p, len(Y), n_sub, h, self.weights, Y,
            self.a, self.comp)


class Gauss(FixedStep):
    """Gauss–Legendre (order 6) on canonical variables z = [q, p, ...]."""

    method = "gauss6"
    order = 6

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float,
                 step: float | None = None) -> None:
        super().__init__(model, y0, t0, tolerance)
        self.ks = self.kernels.kernel_set("to_momenta", "from_momenta", "canonical_rhs")
        self._canonical()
        self._start(step)

    def _guess(self) -> float:
        return self.time_scale() * 0.2 * self.tolerance ** (1.0 / 6.0)

    def _stages(self, y: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """z from y, and stage guesses f(z) for the fixed-point iteration."""
        z = np.empty_like(y)
        self.kernels.to_momenta(t, y, self.p, z)
        f = np.empty_like(z)
        self.kernels.canonical_rhs(t, z, self.p, f)
        return z, np.ascontiguousarray(np.repeat(f[None, :], 3, axis=0))

    def _canonical(self) -> None:
        self.z, self.K = self._stages(self.y, self.t)
        self.comp[:] = 0.0

    def _probe(self, y0: np.ndarray, t0: float, h: float, n: int) -> np.ndarray | None:
        z, K = self._stages(y0, t0)
        state, Y = new_state(FIXED_STATE, t0), np.empty((1, y0.size))
        status, _ = loops().gauss_advance(self.ks, state, z, self.p, 1, n, h, Y, K,
                                          np.zeros(z.size))
        self.state["n_evaluations"] += state["n_evaluations"][0] + 1
        return Y[0] if status == Status.OK else None

    def set_parameters(self, p: np.ndarray) -> None:
        super().set_parameters(p)
        self._canonical()
        self._check()

    def _block(self, Y: np.ndarray, n_sub: int, h: float) -> tuple[Status, int]:
        return loops().gauss_advance(  # type: ignore[no-any-return]
            self.ks, self.state, self.z, self.p, len(Y), n_sub, h, Y, self.K,
            self.comp)

    def _recover(self, status: Status) -> bool:
        """Stage iteration did not converge: restart from the last written state with
        fresh stages and halved steps (up to 2¹⁰ times smaller)."""
        if status != Status.NOT_CONVERGED:
            return False
        if self.refine > 2**10:
            raise IntegrationError(f"{self.model.id}: gauss6 stage equations do not "
                                   f"converge near t = {self.t:.6g}: use dop853")
        self.state["t"] = self.t
        self._canonical()
        self.refine *= 2
        return True


#: Decisions of ``_dop853_meets`` for each model (by tolerance and horizon, from its initial
#: state): a model's parameters never change, so neither does the answer.
_AUTO_DECISIONS: weakref.WeakKeyDictionary[Model, dict[tuple[float, float], bool]] = (
    weakref.WeakKeyDictionary())


def _dop853_meets(model: Model, y0: np.ndarray, t0: float, tolerance: float,
                  horizon: float | None, cacheable: bool) -> bool:
    """Whether DOP853 will end the horizon (ten time scales if not given) within the
    tolerance: two probe runs over four time scales (chaos in the double pendulum shows only
    after three), at the tolerance and a hundred times tighter, give DOP853's error and how
    it grows; linear growth is extrapolated linearly, faster growth (chaotic motion
    amplifying every error) exponentially. Costs about a run of ten time scales, once per
    model, tolerance and horizon."""
    tau = model.time_scale()
    H = horizon if horizon is not None else 10.0 * tau
    key = (tolerance, H)
    if cacheable and key in _AUTO_DECISIONS.get(model, {}):
        return _AUTO_DECISIONS[model][key]
    span = min(4.0 * tau, H)
    probe = t0 + span * np.arange(1, 17) / 16
    try:
        a = DOP853(model, y0, t0, tolerance).advance(probe)
        b = DOP853(model, y0, t0, 0.01 * tolerance).advance(probe)
    except IntegrationError:
        return True  # let the run itself say what is wrong
    n = len(model.coordinates)
    err = np.zeros(probe.size)
    for lo, hi in ((0, n), (n, 2 * n)):
        scale = max(float(np.max(np.abs(b[:, lo:hi]))), 1e-300)
        err = np.maximum(err, np.max(np.abs(a[:, lo:hi] - b[:, lo:hi]), axis=1) / scale)
    # The largest error up to half the probe and up to its end (an oscillating error's
    # samples alone would misjudge its growth).
    e = (float(np.max(err[:8])), float(np.max(err)))
    if e[1] <= 2.5 * e[0] or e[0] == 0.0:
        projected = e[1] * H / span
    else:
        projected = e[1] * (e[1] / e[0]) ** ((H - span) / (0.5 * span))
    meets = bool(projected <= 0.5 * tolerance)
    if cacheable:
        _AUTO_DECISIONS.setdefault(model, {})[key] = meets
    return meets


def make_stepper(model: Model, method: str = "auto", tolerance: float = 1e-10,
                 t0: float = 0.0, y0: np.ndarray | None = None,
                 step: float | None = None, closed_form: bool = False,
                 horizon: float | None = None, work_terms: bool = True) -> Stepper:
    """A stepper for ``model`` (see ``choose_method``; ``horizon``, the span the run is to
    cover if known, informs ``auto``; ``step`` fixes the step of a fixed-step method instead
    of sizing it from the tolerance). ``work_terms=False``: the caller reads the state only;
    the explicit pairs then leave the work terms out (``DOP853``), other methods integrate
    them as ever."""
    chosen = choose_method(model, method, closed_form, tolerance, horizon)
    y = model.initial_y() if y0 is None else y0
    if (method == "auto" and chosen == "dop853" and not model.structure.dissipative
            and not _dop853_meets(model, y, t0, tolerance, horizon, y0 is None)):
        # Errors amplified by the motion: radau15 at its finest (round-off) setting.
        stepper = Radau15(model, y, t0, tolerance)
        stepper.eps = Radau15.eps_range[0]
        return stepper
    if chosen == "exact":  # from the initial state, ``choose_method`` has checked
        return ClosedForm(model, y, t0, tolerance, check=y0 is not None)
    if chosen == "gauss6":
        return Gauss(model, y, t0, tolerance, step=step)
    if chosen == "dop853":
        return DOP853(model, y, t0, tolerance, work_terms=work_terms)
    if chosen == "dopri5":
        return DOPRI5(model, y, t0, tolerance, work_terms=work_terms)
    if chosen == "radau15":
        return Radau15(model, y, t0, tolerance)
    return Composition(model, y, t0, tolerance, method=chosen, step=step)
