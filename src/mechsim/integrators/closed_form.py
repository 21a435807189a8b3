"""``exact``: closed-form propagation (``Model.propagate``) where the model has one for its
parameters (harmonic, damped and driven oscillators, planar and coupled oscillators, Kepler via
Kepler's equation, the free rigid body): exact to round-off at any output times, no steps."""

from __future__ import annotations

from typing import Any

import numpy as np

from mechsim.errors import IntegrationError, ParameterError
from mechsim.integrators.base import Request, Stepper
from mechsim.integrators.errors import NonFiniteStateError
from mechsim.integrators.model import SteppableModel as Model
from mechsim.integrators.state import FIXED_STATE, new_state


class ClosedForm(Stepper):
    """Exact propagation from an anchor state (t₀, y₀) with ``Model.propagate``. Option:
    ``check_state`` (whether the closed form is checked from this state, not only from the
    model's initial one, which ``check`` asks about: a run that goes on from another state, a
    parameter change, is then refused here, not at its next output)."""

    method = "exact"

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float, *,
                 check_state: bool = True) -> None:
        super().__init__(model, y0, t0, tolerance)
        self.t0, self.y0 = self.t, self.y.copy()
        self.state = new_state(FIXED_STATE, self.t)
        if check_state and model.propagate(self.t, self.y, np.array([self.t])) is None:
            raise ParameterError("method", f"exact: {model.id} ({model.formulation}) has no "
                                 f"closed form from the state at t = {self.t:.6g}: use auto "
                                 "or dop853")

    @classmethod
    def check(cls, model: Model) -> None:
        if not model.has_closed_form():
            raise ParameterError("method", f"exact: {model.id} ({model.formulation}) has no "
                                 "closed form for these parameters: use auto or dop853")

    @classmethod
    def options(cls, request: Request) -> dict[str, Any]:
        return {"check_state": request.given_state}

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
            raise NonFiniteStateError(f"{self.model.id}: exact: non-finite state")
        self.state["n_evaluations"] += 1
        self.t, self.y = float(t_out[-1]), Y[-1].copy()
        self.state["t"] = self.t
        return Y
