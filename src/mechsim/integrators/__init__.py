"""Steppers: one contract, interchangeable methods, arranged as scipy's ``integrate._ivp``: a
method is a class in a module of its own, ``METHODS`` finds it by name, its settings are
constructor options, and the solver contract is written down once (``base``).

Methods (``METHODS``, in this order):

- ``auto`` (``auto``): chooses among the adaptive methods (and ``exact``) by the model, the
  tolerance and the horizon, and passes its choice to the stepper's constructor;
- ``dop853`` (``dop853``): adaptive explicit Runge–Kutta 8(5,3), dense output, events,
  constraint projection after every step; every model;
- ``dopri5`` (``dopri5``): Dormand and Prince's 5(4) pair in DOP853's loop, for loose
  tolerances; every model;
- ``radau15`` (``radau15``): adaptive 15th-order Gauss–Radau predictor–corrector (IAS15),
  events, projection, round-off over long runs; every model;
- ``gauss6`` (``gauss6``): symplectic Gauss–Legendre collocation on Hamilton's equations,
  conservative systems with a canonical form;
- ``exact`` (``closed_form``): closed-form propagation where the model has one;
- ``verlet``, ``yoshida6``, ``yoshida8`` (``composition``): symplectic compositions of
  velocity Verlet, separable Hamiltonians.

The compiled loops they drive are shared by every model (``compiled``); a stepper's typed
errors are in ``errors``. ``docs/integrators.md`` describes the methods, their options and how
``auto`` chooses.
"""

from __future__ import annotations

import numpy as np

from mechsim.errors import ParameterError
from mechsim.integrators.auto import Auto
from mechsim.integrators.base import Request, Stepper
from mechsim.integrators.closed_form import ClosedForm
from mechsim.integrators.compiled import PRECOMPILE_PARTS, loop_signatures, precompile
from mechsim.integrators.compiled import load as loops
from mechsim.integrators.composition import Composition, Verlet, Yoshida6, Yoshida8
from mechsim.integrators.dop853 import DOP853
from mechsim.integrators.dopri5 import DOPRI5
from mechsim.integrators.errors import (
    EventAccumulationError,
    NonFiniteStateError,
    NotConvergedError,
    StepLimitError,
    StepUnderflowError,
    StiffnessError,
)
from mechsim.integrators.gauss6 import Gauss6
from mechsim.integrators.model import SteppableModel as Model
from mechsim.integrators.radau15 import Radau15

__all__ = ["METHODS", "PRECOMPILE_PARTS", "Auto", "ClosedForm", "Composition", "DOP853", "DOPRI5",
           "EventAccumulationError", "Gauss6", "NonFiniteStateError", "NotConvergedError",
           "Radau15", "Request", "StepLimitError", "StepUnderflowError", "Stepper",
           "StiffnessError", "Verlet", "Yoshida6", "Yoshida8", "choose_method",
           "loop_signatures", "loops", "make_stepper", "method_class", "precompile"]

#: Every method by name: what scenes, the CLI and the nodes' ROS parameters list and accept.
METHODS: dict[str, type[Stepper] | type[Auto]] = {
    m.method: m for m in (Auto, DOP853, DOPRI5, Radau15, Gauss6, ClosedForm, Verlet,
                          Yoshida6, Yoshida8)}
#: The methods whose steppers take inputs (``Stepper.restart``).
Stepper.TAKES_INPUTS = tuple(name for name, cls in METHODS.items()
                             if issubclass(cls, Stepper) and cls.takes_inputs)


def method_class(method: str) -> type[Stepper] | type[Auto]:
    """The class of ``method`` (``ParameterError`` naming the known ones otherwise)."""
    cls = METHODS.get(method) if isinstance(method, str) else None
    if cls is None:
        raise ParameterError("method", f"must be one of {', '.join(METHODS)} (got {method!r})")
    return cls


def choose_method(model: Model, method: str, closed_form: bool = False,
                  tolerance: float = 1e-10, horizon: float | None = None) -> str:
    """The method a stepper will use: ``method`` where it fits ``model`` (``ParameterError``
    with what to use instead otherwise), or what ``auto`` chooses before its probe (see
    ``auto``; ``make_stepper`` may still take radau15 where the probe shows DOP853's error
    outgrowing the tolerance)."""
    cls = method_class(method)
    if cls is Auto:
        return Auto.choose(model, closed_form, tolerance, horizon).method
    cls.check(model)
    return method


def make_stepper(model: Model, method: str = "auto", tolerance: float = 1e-10,
                 t0: float = 0.0, y0: np.ndarray | None = None,
                 step: float | None = None, closed_form: bool = False,
                 horizon: float | None = None, work_terms: bool = True) -> Stepper:
    """A stepper of ``method`` for ``model`` from (t0, y0) (y0: the model's initial state if
    not given), each method taking from the rest the options it has (``base.Request``):
    ``step`` fixes a fixed-step method's step instead of sizing it from the tolerance;
    ``horizon``, the span the run is to cover if known, and ``closed_form`` inform ``auto``;
    ``work_terms=False``: the caller reads the state only, and the explicit pairs leave the
    work terms out."""
    cls = method_class(method)
    cls.check(model)
    y = model.initial_y() if y0 is None else y0
    request = Request(step=step, horizon=horizon, closed_form=closed_form,
                      work_terms=work_terms, given_state=y0 is not None)
    return cls.create(model, y, t0, tolerance, request)
