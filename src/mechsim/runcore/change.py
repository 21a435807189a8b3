"""Parameter changes of a running system: validated completely, then committed as one.

A change (model parameters, ``method`` and the run settings of :data:`SETTINGS`, in any mix) is
planned first (:func:`plan`): every value is checked against its one range, the whole model is
built with the new values (its own checks), the method's compatibility with it
(``choose_method``) and the new stepper are checked; a structural change (a formulation, the
bead's shape or curve, a number of masses: anything that changes the equations of motion) is
derived and compiled in a child process with a time limit (``mechsim.runcore.equations``). Any
failure refuses the whole change with its reason (a MechsimError, one line) and nothing
changes; a planned :class:`Change` cannot fail any more, and ``SystemRun.commit`` changes the
model, stepper, kernels and outputs together. When each part takes effect:

- a structural change restarts the system at t = 0 from the initial state of the new values;
- another model parameter takes effect at once, from the current state; ``initial.*`` and
  ``initial_rate.*`` are stored and take effect at the next reset (or structural change);
- method and tolerance: a new stepper continues from the current state.

Epochs: ``epoch`` counts the runs with one fixed model; a reset or an accepted model change
starts a new one, so a consumer re-bases its reference values. In the samples a new epoch is a
sample whose time is not later than the previous one's: a reset restarts at t = 0, and after a
model change that keeps the state the current sample is released again (same time, new
parameters).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np

from mechsim.errors import MechsimError, ParameterError, one_line
from mechsim.integrators import METHODS, Stepper, make_stepper
from mechsim.params import (
    CONSTRAINT_LIMIT,
    EFFORT_LIMIT,
    EFFORT_TIMEOUT,
    EFFORT_WAIT,
    PUBLISH_RATE,
    REAL_TIME_FACTOR,
    TOLERANCE,
    Parameter,
    shown,
)
from mechsim.runcore.equations import prepare_model
from mechsim.runcore.stops import raise_if_stop
from mechsim.systems.base import Model

#: Run settings a running system takes changes of, each with its one range.
SETTINGS: dict[str, Parameter] = {p.name: p for p in (TOLERANCE, PUBLISH_RATE, REAL_TIME_FACTOR,
                                                       CONSTRAINT_LIMIT, EFFORT_TIMEOUT,
                                                       EFFORT_WAIT, EFFORT_LIMIT)}


@dataclass(frozen=True)
class Settings:
    """How a system runs (``SETTINGS``): integrator tolerance, samples per simulated second,
    pacing (0: stepped by its caller), the constraint guard's hard limit, the effort hold's
    timeout, a stepped closed loop's wait for its controller and the largest effort accepted."""

    tolerance: float = float(TOLERANCE.default)
    publish_rate: float = float(PUBLISH_RATE.default)
    real_time_factor: float = float(REAL_TIME_FACTOR.default)
    constraint_limit: float = float(CONSTRAINT_LIMIT.default)
    effort_timeout: float = float(EFFORT_TIMEOUT.default)
    effort_wait: float = float(EFFORT_WAIT.default)
    effort_limit: float = float(EFFORT_LIMIT.default)

    def checked(self) -> Settings:
        """These settings, each checked against its range (ParameterError naming it)."""
        return Settings(**{name: float(SETTINGS[name].check(getattr(self, name), name))
                           for name in SETTINGS})


@dataclass
class Change:
    """A validated parameter change, ready to commit (nothing in it can fail any more)."""

    values: dict[str, Any]
    method: str
    settings: Settings
    model: Model | None = None  # new model (values changed)
    structural: bool = False  # new equations of motion: restart at t = 0
    stepper: Stepper | None = None  # new stepper (method, tolerance or structure changed)
    names: list[str] = field(default_factory=list)  # the parameters changed, in order


class Running(Protocol):
    """What a change is planned against: a running system (``SystemRun``)."""

    model: Model
    stepper: Stepper
    spec: dict[str, Parameter]
    values: dict[str, Any]
    method: str
    settings: Settings
    stepped: bool
    prepare_timeout: float
    t: float
    y: np.ndarray


def reason(e: BaseException) -> str:
    """One line for an unexpected error (its type and first line, bounded)."""
    first = (str(e).splitlines() or [""])[0]
    return one_line(f"{type(e).__name__}: {first}")[:300]


def _setting(name: str, value: Any, stepped: bool) -> float:
    x = float(SETTINGS[name].validate(value))
    if name == "real_time_factor" and x == 0:
        raise ParameterError(name, "must be > 0 for a node that paces itself (0 means stepped "
                             "by a runner; ~/pause stops it)")
    if name == "real_time_factor" and stepped:
        raise ParameterError(name, "read-only: this system is stepped by its runner")
    return x


def _values(run: Running, updates: list[tuple[str, Any]]) -> Change:
    """The change's values, method and settings, each checked; nothing built yet."""
    values = dict(run.values)
    method = run.method
    settings: dict[str, float] = {}
    for name, value in updates:
        if name in run.spec:
            values[name] = run.spec[name].validate(value)
        elif name == "method":
            if not isinstance(value, str) or value not in METHODS:
                raise ParameterError(name, f"must be one of {', '.join(METHODS)} (got "
                                     f"{shown(value)})")
            method = value
        elif name in SETTINGS:
            settings[name] = _setting(name, value, run.stepped)
    return Change(values, method, replace(run.settings, **settings),
                  names=[name for name, _ in updates])


def plan(run: Running, updates: list[tuple[str, Any]]) -> Change:
    """Everything the change would do to ``run``, built and checked; MechsimError (one line)
    otherwise. ``updates``: (parameter name, value) in the order given; names that are
    neither model parameters, ``method`` nor settings are left to the caller."""
    try:
        return _plan(run, updates)
    except MechsimError:
        raise
    except Exception as e:  # noqa: BLE001 - a refused change, never an error of the run
        raise_if_stop(e)
        raise MechsimError(f"{', '.join(n for n, _ in updates)}: {reason(e)}") from None


def _plan(run: Running, updates: list[tuple[str, Any]]) -> Change:
    change = _values(run, updates)
    values, method, tolerance = change.values, change.method, change.settings.tolerance
    model = run.model
    if values != run.values:
        model = type(run.model)(**values)  # every check of the model (cheap: no derivation)
        if any(run.spec[k].kind is not float and values[k] != run.values[k] for k in values):
            # New equations of motion, possibly: derived and compiled in a child process
            # with a time limit, never unbounded here.
            prepare_model(run.model.id, values, method, tolerance, run.prepare_timeout)
        change.model = model
        change.structural = (model.kernels is not run.model.kernels
                             or model.initial_y().size != run.stepper.y.size)
    try:
        if change.structural:
            change.stepper = make_stepper(model, method, tolerance)
        elif change.model is not None or method != run.method \
                or tolerance != run.settings.tolerance:
            # Continues from the current state (an initial value waits for a reset).
            change.stepper = make_stepper(model, method, tolerance, t0=run.t, y0=run.y.copy())
    except MechsimError:
        raise
    except Exception as e:  # noqa: BLE001 - e.g. a division by zero at extreme values
        raise_if_stop(e)
        raise MechsimError(f"{', '.join(change.names)}: cannot integrate with these values "
                           f"({reason(e)})") from None
    return change
