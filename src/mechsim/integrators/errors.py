"""Why a stepper stopped, as types: each ``Status`` a compiled loop can stop with has an
``IntegrationError`` of its own (``for_status``), as have the stops the steppers find
themselves. Every one is an ``mechsim.errors.IntegrationError`` (a one-line message naming
the system, the method and the time), so a caller that does not care which catches that."""

from __future__ import annotations

from mechsim.errors import IntegrationError
from mechsim.integrators.state import Status


class StepLimitError(IntegrationError):
    """The step budget of one ``advance`` is spent (``Status.MAX_STEPS``)."""


class StepUnderflowError(IntegrationError):
    """The step fell below round-off of the time (``Status.STEP_UNDERFLOW``)."""


class NonFiniteStateError(IntegrationError):
    """The state stopped being finite (``Status.NOT_FINITE``), or a closed form or event
    handler gave a state that is not."""


class StiffnessError(IntegrationError):
    """The explicit pairs' stiffness test fired and the stability-limited step is crawling
    (``Status.STIFF``): the state is kept at the last accepted step, whose outputs were all
    written."""


class NotConvergedError(IntegrationError):
    """Implicit stage equations did not converge (``Status.NOT_CONVERGED``), or a fixed-step
    method cannot size or recover its step."""


class EventAccumulationError(IntegrationError):
    """Events accumulate at one time (Zeno behaviour) and the model does not change mode
    there."""


#: The error of each status a loop stops with, other than OK and EVENT.
_BY_STATUS: dict[Status, type[IntegrationError]] = {
    Status.MAX_STEPS: StepLimitError,
    Status.STEP_UNDERFLOW: StepUnderflowError,
    Status.NOT_FINITE: NonFiniteStateError,
    Status.STIFF: StiffnessError,
    Status.NOT_CONVERGED: NotConvergedError,
}


def for_status(status: Status, message: str) -> IntegrationError:
    """The error of ``status`` (a loop's reason to stop) with ``message``."""
    return _BY_STATUS.get(status, IntegrationError)(message)
