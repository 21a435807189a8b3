"""The fixed-step methods' common part (``FixedStep``): the compositions
(``composition``) and Gauss–Legendre (``gauss6``) step with a fixed step sized from the
tolerance, or given (option ``step``)."""

from __future__ import annotations

import math
from abc import abstractmethod
from typing import Any, ClassVar

import numpy as np

from mechsim.errors import IntegrationError
from mechsim.integrators.base import Request, Stepper
from mechsim.integrators.errors import NotConvergedError
from mechsim.integrators.model import SteppableModel as Model
from mechsim.integrators.state import FIXED_STATE, Status, new_state


class FixedStep(Stepper):
    """Fixed-step methods: the step is the largest ≤ ``h_max`` dividing each output gap; a
    run of equal gaps goes to the kernel in one call (``_block``). A subclass may recover
    from a failed block (``_recover``: e.g. smaller steps); otherwise the run stops.

    The step comes from the tolerance (unless given): ``_size_step`` estimates the error rate
    from a probe at the current state, at the start and again every ``CHECK_SCALES`` time
    scales along the run (the step shrinks or grows when the estimate moves by more than half);
    the estimated error committed is added to ``error_estimate``."""

    h_max: float
    order: ClassVar[int]
    #: The error estimate over this many time scales is to stay within the tolerance.
    HORIZON_SCALES: ClassVar[float] = 10.0
    CHECK_SCALES: ClassVar[float] = 10.0

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float) -> None:
        super().__init__(model, y0, t0, tolerance)
        self.state = new_state(FIXED_STATE, self.t)
        self.comp = np.zeros(self.y.size)
        self.refine = 1
        self.rate = 0.0  # estimated error per unit time at h_max (relative to the state)
        self.fixed = False  # True when the step was given
        self._next_check = math.inf
        self._tau: tuple[Model, bytes, float] | None = None

    @classmethod
    def options(cls, request: Request) -> dict[str, Any]:
        return {"step": request.step}

    def time_scale(self) -> float:
        """The model's time scale, asked once per model and parameter vector: the step is
        re-estimated along the run, and a model may find its scale from its turning points
        (``central_force``), which is too slow to ask at every check."""
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
            raise NotConvergedError(f"{self.model.id}: {self.method} cannot size its step "
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
