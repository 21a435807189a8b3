"""The effort input: generalized forces from a controller, held over each sample period.

A command is one generalized force per coordinate, in the order of the state (N for a length,
N·m for an angle). It takes effect at the next sample and is held over each sample period
(zero-order hold) for ``effort_timeout`` simulated seconds, then the effort returns to zero;
its work is part of ``work_external``, and from the first nonzero effort of an epoch the laws
that still hold are only ``Model.laws_under_effort``. A command of the wrong length, with a
non-finite value or a value beyond ``effort_limit`` (per coordinate), to a system whose
kernels take none (not Lagrangian: rigid_body, moving_frames, the quaternion top) or under a
method that integrates without it (exact, yoshida*, verlet, gauss6) is refused with its reason.

No peer on the effort topic can stall or stop a run:

- **Waiting.** A run stepped by a runner (fast) waits for a controller only once it has
  answered: a command accepted in this run. Then it steps sample by sample and, after each,
  waits up to ``effort_wait`` wall seconds for the controller's answer to it. A wait that ends
  without one marks the controller silent: no more waits until it answers again; after
  :data:`MAX_MISSED` such waits the run waits no more at all. So a publisher that never
  answers is never waited for, and the time a run can lose waiting in vain is at most
  ``MAX_MISSED × effort_wait`` whatever its peers do (counted: ``waits``, ``missed``,
  ``unwaited``).
- **Bounds.** Values beyond ``effort_limit`` are refused (counted in ``rejected``).
- **Failure.** A step that fails while an effort acts (the integrator gives up, a guard
  fires) drops the effort: the run goes on from the last good sample without it, and says so
  (``SystemRun``, ``Observer.effort_notice``).
"""

from __future__ import annotations

import math
import threading

import numpy as np

from mechsim.integrators import Stepper
from mechsim.systems.base import Model

#: Waits that may end without the controller's answer in one run; then the run no longer
#: waits for it (its commands still apply when they come).
MAX_MISSED = 3


class EffortHold:
    """The commands accepted and the effort held (zero-order hold with a timeout). Commands
    arrive from any thread (``offer``); the run takes them between samples (``next``)."""

    def __init__(self, timeout: float, limit: float = math.inf) -> None:
        self.timeout = timeout
        self.limit = limit
        self.received = 0  # commands accepted
        self.rejected = 0  # commands refused
        #: Samples released when the latest accepted command arrived (a stepped closed loop
        #: waits for the answer to its latest sample).
        self.answered = -1
        #: A controller answered and has not missed a wait since: a stepped run waits for it.
        self.responsive = False
        self.waits = 0  # waits for an answer begun
        self.missed = 0  # waits that ended without one
        #: Samples stepped with a controller present that was not waited for (it never
        #: answered, or fell silent).
        self.unwaited = 0
        self.dropped = 0  # efforts dropped because a step failed under them
        self._lock = threading.Lock()
        self._inbox: np.ndarray | None = None  # newest accepted command, not applied yet
        #: Where the effort sits in the parameter vector (None: the model takes none).
        self.at: slice | None = None
        self.held_until: float | None = None  # effort held (nonzero) until this sim time
        self.acted = False  # a nonzero effort acted in this epoch

    def reset(self, at: slice | None, new_epoch: bool) -> None:
        """A new model or stepper starts without effort (its parameter vector's zero); the next
        command applies again. A new epoch also restores the full set of laws."""
        with self._lock:
            self._inbox = None
        self.at = at
        self.held_until = None
        if new_epoch:
            self.acted = False

    def refusal(self, u: np.ndarray, model: Model, method: str) -> tuple[str, str] | None:
        """Why the command ``u`` is refused, as (kind, reason); None if it is valid."""
        names = [c.name for c in model.coordinates]
        if self.at is None:
            return "system", (f"{model.id} ({model.formulation}) takes no effort (its kernels "
                              "are not derived from a Lagrangian)")
        if method not in Stepper.TAKES_INPUTS:
            return "method", (f"method {method} integrates without the effort: use dop853, "
                              "dopri5, radau15 or auto")
        if u.size != len(names):
            return "length", (f"{u.size} values, expected {len(names)} (one per coordinate: "
                              f"{', '.join(names)})")
        if not np.isfinite(u).all():
            i = int(np.argmin(np.isfinite(u)))
            return "finite", f"value {i} ({names[i]}) is {u[i]}, not finite"
        if (np.abs(u) > self.limit).any():
            i = int(np.argmax(np.abs(u) > self.limit))
            return "limit", (f"value {i} ({names[i]}) is {u[i]:.6g}, beyond effort_limit "
                             f"{self.limit:g}")
        return None

    def offer(self, u: np.ndarray, model: Model, method: str,
              released: int) -> tuple[str, str] | None:
        """A command from a controller (``released``: samples released so far): accepted for
        the next sample, or refused with (kind, reason)."""
        refusal = self.refusal(u, model, method)
        if refusal is None:
            with self._lock:
                self._inbox = u
            self.received += 1
            self.answered = released
            self.responsive = self.missed < MAX_MISSED
        else:
            self.rejected += 1
        return refusal

    def miss(self) -> bool:
        """A wait ended without an answer: the controller is silent until it answers again.
        True when this was the last wait the run allows (:data:`MAX_MISSED`)."""
        self.missed += 1
        self.responsive = False
        return self.missed == MAX_MISSED

    def drop(self) -> None:
        """The effort acting is dropped (a step failed under it): nothing held."""
        self.held_until = None
        self.dropped += 1

    @property
    def pending(self) -> bool:
        """A command waits to be applied."""
        return self._inbox is not None

    def next(self, t: float, publish_rate: float) -> np.ndarray | None:
        """The effort that applies from the sample at ``t`` if it changes there: the newest
        command, or zero once a held effort has timed out; None otherwise."""
        assert self.at is not None
        with self._lock:
            u, self._inbox = self._inbox, None
        if u is not None:
            self.held_until = t + self.timeout if u.any() else None
        elif self.held_until is not None and t >= self.held_until - 1e-9 / publish_rate:
            u, self.held_until = np.zeros(self.at.stop - self.at.start), None
        return u
