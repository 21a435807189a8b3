"""``radau15``: adaptive 15th-order Gauss–Radau predictor–corrector (the IAS15 scheme,
generalised to velocity-dependent forces) with events and projection; works for every model.
The end error stays at the round-off floor over long runs (energy error growing like √N). Its
steps keep their own length (landing only on the last time asked for); outputs inside a step
come from the step's expansion where its error estimate is within a thousandth of the
tolerance, otherwise from a step of their own from the step's start (``n_side``)."""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from mechsim.errors import IntegrationError
from mechsim.integrators.base import Stepper, event_directions
from mechsim.integrators.compiled import load as loops
from mechsim.integrators.model import SteppableModel as Model
from mechsim.integrators.state import RADAU_STATE, Status, new_state


class Radau15(Stepper):
    """Adaptive 15th-order Gauss–Radau predictor–corrector (the IAS15 scheme) for
    q̈ = f(t, q, q̇): machine precision over long runs, dense output within the tolerance
    (``compiled.radau.radau15_advance``). Each ``advance`` ends on its last output time, so
    the state is always at the last output returned (or at an event).

    Options: ``eps``, the controller's target for ε_b = max|b₆| / max|q̈| (default
    0.01 √tolerance, within ``EPS_RANGE``: ``auto`` asks for the finest where errors are
    amplified by the motion); ``dense_tolerance``, what outputs inside a step are held to
    (default the tolerance; see the module docstring); ``max_steps`` per ``advance``."""

    method = "radau15"
    takes_inputs = True
    takes_events = True
    #: The range of the controller's ε: the global error of a 15th-order method falls as
    #: ε^(15/7), and below the finest it is at round-off (for every system tested), so
    #: smaller steps would only add round-off.
    EPS_RANGE: ClassVar[tuple[float, float]] = (1e-7, 1e-4)
    #: The controller's floor of the acceleration scale, as a fraction of the model's natural
    #: scale at the start of the run (see ``_restart``): much smaller lets round-off drive the
    #: step near an equilibrium (the CR3BP's L1), much larger competes with the accelerations
    #: of an orbit near apocentre.
    FLOOR: ClassVar[float] = 0.01

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float, *,
                 eps: float | None = None, dense_tolerance: float | None = None,
                 max_steps: int = 10_000_000) -> None:
        super().__init__(model, y0, t0, tolerance)
        m = self.kernels.n_q + 2
        self.ks = self.kernels.kernel_set("rhs", "project", "event")
        self.state = new_state(RADAU_STATE, self.t)
        self.ev_dir = event_directions(model)
        self.g_old = np.zeros(self.ev_dir.size)
        self.tau = float(model.time_scale())
        self.a_floor = 0.0
        self.w_floor = 0.0
        self.max_steps = int(max_steps)
        lo, hi = self.EPS_RANGE
        self.eps = min(max(0.01 * math.sqrt(self.tolerance), lo), hi) if eps is None else eps
        self.dense_tolerance = self.tolerance if dense_tolerance is None else dense_tolerance
        self.b = np.zeros((7, m))
        self.g = np.zeros((7, m))
        self.e = np.zeros((7, m))
        self.F0 = np.zeros(m)
        self.dy = np.zeros(self.y.size)
        self.comp = np.zeros(self.y.size)
        self._restart()

    def _restart(self) -> None:
        """Fresh expansion and first step at the current state (after new parameters).

        The controller's floor of the acceleration scale (``a_floor``; near an equilibrium
        q̈ and b₆ are the round-off of cancelling force terms, and without a floor the step
        would shrink to an underflow) is ``FLOOR`` times the model's natural scale
        max|q|/τ² + max|q̇|/τ here, at the start, and not along the run: a coordinate the
        forces do not depend on may grow without bound (a falling centre of mass), and a floor
        following it would loosen the control of the motion beside it. The work terms' scale
        (``w_floor``: their errors are judged against it, their rates may be round-off of
        cancelling terms) is the system's energy scale here, max(|T|, |V|, |h|)."""
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
