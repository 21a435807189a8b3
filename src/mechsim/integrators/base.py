"""The solver contract: what every stepper promises (``Stepper``), written down once.

A stepper owns the integration state of one model (``model.SteppableModel``) and advances it
to the output times a caller asks for. Each method is a subclass in a module of its own and an
entry of ``mechsim.integrators.METHODS``; ``make_stepper`` makes one by name.

Construction. ``Method(model, y0, t0, tolerance, **options)``: the state ``y0`` at time ``t0``
(``y = [q, q̇, work_external, work_dissipated, modes]``), the tolerance in (0, 1)
(``ParameterError`` otherwise), and the method's own settings as keyword-only options, fixed
for the stepper's life (nothing retunes a stepper from outside). ``check(model)`` raises
``ParameterError`` naming the field ``method`` and what to use instead where the method does
not fit the model (a composition needs a separable Hamiltonian, ``gauss6`` a canonical form,
``exact`` a closed form); ``create(model, y0, t0, tolerance, request)`` makes the stepper
with the options that follow from what a caller knows of the run (``Request``);
``make_stepper`` checks, then creates.

The tolerance. It bounds the error at the end of a run of ten time scales, relative to the
state's scale (``tests/test_tolerance.py`` checks it for every system): every method sizes its
steps from it, the adaptive ones step by step, the fixed-step ones from an error estimate at
the start, checked along the run.

``advance(t_out) -> Y``: one row of the state per time of ``t_out`` (increasing, not before
the last time returned), in order; the stepper's ``t`` and ``y`` are then at the last row (an
adaptive explicit pair keeps its own state at the end of its last step, beyond; the next call
goes on from there, with no restart and no short step). A call either returns every row or
raises: an ``IntegrationError`` whose type says why (``integrators.errors``: the step budget
spent, a step below round-off, a state no longer finite, a stiff problem, stage equations not
converging, events accumulating), with one line naming the system, the method and the time.

Events (``takes_events``: ``dop853``, ``dopri5``, ``radau15``). A model may declare state
events (``Model.events``) and discrete modes. The compiled loop locates the earliest sign
change of an event function inside a step (to 4 ulps of t), writes the outputs before it and
stops there; the stepper calls ``model.handle_event(index, t, y) -> y_new`` (a velocity jump,
a new mode, or y unchanged to record a time), restarts there (projection, first stage and
step; counters kept) and goes on, so ``advance`` still returns every row asked for (a row at
exactly the event time holds the state after the handler). Each event is recorded in
``events`` as (t, name). The other methods refuse models with events (``check``).

Inputs (``takes_inputs``: the methods that integrate the full right-hand side, where an
effort the model reads from ``p`` acts). ``restart(t, y, p)`` goes on afresh from a state the
stepper returned at ``t`` with parameters ``p``: no step crosses ``t``, so an input held over
an output interval changes exactly there. The others raise ``IntegrationError``.

Parameters. ``set_parameters(p)`` takes a parameter vector of the model's layout (what the
model derives from it recomputed: ``Model.complete_parameters``); ``set_model(model)`` the
same system with new parameter values. The state carries over.

Counters (what a run cost): ``n_steps``, ``n_evaluations`` (right-hand side, or force, calls),
``n_rejected``, ``error_estimate`` (the sum of the local error estimates, relative to the state
scale), ``events``. They are fields of the stepper's ``state`` record (``integrators.state``),
which the compiled loops update.
"""

from __future__ import annotations

import math
import weakref
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from mechsim.errors import IntegrationError, ParameterError
from mechsim.integrators.errors import EventAccumulationError, NonFiniteStateError, for_status
from mechsim.integrators.model import SteppableModel as Model
from mechsim.integrators.state import Status


@dataclass(frozen=True)
class Request:
    """What a caller of ``make_stepper`` knows of the run besides the model, the state and
    the tolerance, from which each method takes the options it has: ``step`` fixes a
    fixed-step method's step (else it is sized from the tolerance); ``horizon``, the span the
    run is to cover, informs ``auto``; ``closed_form`` lets ``auto`` take ``exact``;
    ``work_terms=False``: the caller reads the state only (the explicit pairs then leave the
    work terms out); ``given_state``: the state is not the model's initial one (``exact``
    then checks its closed form from it)."""

    step: float | None = None
    horizon: float | None = None
    closed_form: bool = False
    work_terms: bool = True
    given_state: bool = False


class Stepper(ABC):
    """Integration state of one model; the solver contract is the module docstring."""

    #: The method's name in ``METHODS``.
    method: ClassVar[str]
    #: Whether the method integrates the model's full right-hand side, inputs included
    #: (``restart``).
    takes_inputs: ClassVar[bool] = False
    #: Whether the method handles the model's events.
    takes_events: ClassVar[bool] = False
    #: The methods that take inputs, by name (set from ``METHODS`` where it is made).
    TAKES_INPUTS: ClassVar[tuple[str, ...]] = ()

    state: np.ndarray  # one record of a dtype of ``state.py``

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

    @classmethod
    def check(cls, model: Model) -> None:
        """Raise ``ParameterError`` (field ``method``) where the method does not fit
        ``model``; by default it fits every model."""

    @classmethod
    def options(cls, request: Request) -> dict[str, Any]:
        """The constructor options that follow from ``request`` (default: none)."""
        return {}

    @classmethod
    def create(cls, model: Model, y0: np.ndarray, t0: float, tolerance: float,
               request: Request) -> Stepper:
        """A stepper of this method for ``model`` from (t0, y0) with the options ``request``
        implies (``make_stepper`` has checked that the method fits)."""
        return cls(model, y0, t0, tolerance, **cls.options(request))

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
        """Apply the model's event handler at the event time and restart there
        (``_restart_after_event``)."""
        t = self.t
        # (the handler gets a copy of its own: what it returns is not shared)
        y_new = np.asarray(self.model.handle_event(index, t, self.y.copy()), dtype=np.float64)
        if y_new.shape != self.y.shape or not np.isfinite(y_new).all():
            raise NonFiniteStateError(f"{self.model.id}: handler of event "
                                      f"{self.model.events[index].name} returned a bad state")
        if t - self._last_event_t <= 1e-12 * max(1.0, abs(t)):
            self._stalled += 1
            if self._stalled > 100:
                raise EventAccumulationError(
                    f"{self.model.id}: events accumulate at t = {t:.6g} (Zeno behaviour); "
                    "the model must change mode there")
        else:
            self._stalled = 0
        self._last_event_t = t
        self.events.append((t, self.model.events[index].name))
        self._restart_after_event(t, y_new)

    def _restart_after_event(self, t: float, y: np.ndarray) -> None:
        raise NotImplementedError

    def restart(self, t: float, y: np.ndarray, p: np.ndarray) -> None:
        """Go on afresh from state ``y`` at time ``t`` with parameters ``p``: no step crosses
        ``t``, so an input held constant over each output interval (zero-order hold) changes
        exactly there. ``y`` is a state the stepper returned at ``t`` (the adaptive methods step
        past their last output time, so their own state may be later). Only the methods that
        take inputs (``TAKES_INPUTS``). What the model derives from ``p`` is recomputed, as by
        ``set_parameters``."""
        if not self.takes_inputs:
            raise IntegrationError(f"{self.method} takes no inputs: use "
                                   f"{' or '.join(self.TAKES_INPUTS)}")
        self.p = self.model.complete_parameters(p)
        self.t = float(t)
        self._restart_after_event(self.t, np.array(y, dtype=np.float64))

    def _fail(self, status: Status) -> IntegrationError:
        return for_status(status, f"{self.model.id}: {self.method} stopped at "
                                  f"t = {self.t:.6g}: {status.reason}")


def event_directions(model: Model) -> np.ndarray:
    """The directions of the model's events (a zero standing in when it has none), as the
    compiled loops take them: made once per model and shared by its steppers; nothing writes
    it (it stays writeable: a read-only array is another numba type, see
    ``compiled.loop_signatures``)."""
    d = _EVENT_DIRECTIONS.get(model)
    if d is None:
        d = np.array([e.direction for e in model.events] or [0], dtype=np.int64)
        _EVENT_DIRECTIONS[model] = d
    return d


_EVENT_DIRECTIONS: weakref.WeakKeyDictionary[Model, np.ndarray] = weakref.WeakKeyDictionary()
