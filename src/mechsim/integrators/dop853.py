"""``dop853``: Hairer's explicit Runge–Kutta 8(5,3) with dense output, events and constraint
projection after every step (constraint residuals stay at round-off); works for every model.
Its loop (``compiled.erk``) is shared with ``dopri5``.

Stiffness: Hairer's stiffness test runs inside the loop; when it fires and the
stability-limited step is also crawling — more than ``stiff_steps_per_output`` steps per output
interval — the stepper raises ``StiffnessError`` (naming the system, with what to change)
instead of crawling on. A stiff but cheap phase (a damped system settled at rest, big steps)
goes on. The test only reads the state: it never changes a non-stiff run.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np

from mechsim.integrators.base import Request, Stepper, event_directions
from mechsim.integrators.compiled import load as loops
from mechsim.integrators.errors import StiffnessError
from mechsim.integrators.model import SteppableModel as Model
from mechsim.integrators.state import DOP853_STATE, Pair, Status, new_state

#: ``DOP853._restart``: the compiled loop's ``restart`` argument.
_NO_RESTART, _RESTART, _RESTART_KEEP_DENSE = 0, 1, 2
_NO_TIMES = np.empty(0)


class DOP853(Stepper):
    """Hairer's DOP853 with dense output, events and projection (``compiled.erk``).

    Its controller bounds the local error of every step; over a run those errors add up. So the
    local tolerance (relative and absolute) is ``LOCAL_FACTOR`` × the tolerance, floored at
    ``LOCAL_FLOOR`` (round-off): over ten time scales the end error then stays below the
    tolerance (relative to the state scale) for all but chaotic systems, where no method does
    better than its round-off amplified.

    A subclass with another explicit pair of the shared loop sets ``method`` (its loop is
    ``<method>_advance``), ``PAIR`` (``state.Pair``), ``N_STAGES`` (rows of K), ``STIFF_EDGE``
    (for the message) and its own ``LOCAL_FACTOR``: ``DOPRI5``.

    Options: ``max_step`` (no step longer), ``max_steps`` (per ``advance``), ``work_terms``
    (False: the work terms are not integrated, for callers that read the state only; the
    loop's arithmetic and its error norm cover q and q̇ alone, the work columns of what
    ``advance`` returns are NaN, and the tolerance is met the same way) and
    ``stiff_steps_per_output`` (a stiff phase is an error only when it crawls: more steps
    than this per output interval)."""

    method = "dop853"
    takes_inputs = True
    takes_events = True
    PAIR: ClassVar[Pair] = Pair.DOP853
    N_STAGES: ClassVar[int] = 16  # 12 of the step, f at the new point, 3 of the dense output
    STIFF_EDGE: ClassVar[float] = 6.1
    LOCAL_FACTOR: ClassVar[float] = 1e-3
    LOCAL_FLOOR: ClassVar[float] = 1e-14

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float, *,
                 max_step: float = math.inf, max_steps: int = 10_000_000,
                 work_terms: bool = True, stiff_steps_per_output: float = 1000.0) -> None:
        super().__init__(model, y0, t0, tolerance)
        n = self.y.size
        self.work_terms = work_terms
        self.max_step = float(max_step)
        self.max_steps = int(max_steps)
        self.stiff_steps_per_output = float(stiff_steps_per_output)
        self.K = np.zeros((self.N_STAGES, n))
        self.F = np.zeros((7, n))
        self.y_old = self.y.copy()
        self.comp = np.zeros(n)
        self.rtol = self.atol = max(self.tolerance * self.LOCAL_FACTOR, self.LOCAL_FLOOR)
        self.ev_dir = event_directions(model)
        self.g_old = np.zeros(self.ev_dir.size)
        self.state = new_state(DOP853_STATE, self.t)
        # All of y (the modes, constant between events, with their zero rates) or q and q̇.
        self.state["n_integrated"] = n if work_terms else 2 * self.kernels.n_q
        self._t = self.state["t"]  # a view: the loop's time, without a field lookup a call
        self.ks = self.kernels.kernel_set("rhs", "project", "event")
        self._loop = getattr(loops(), f"{self.method}_advance")
        self._restart = _NO_RESTART
        self._reset(self.t, self.y)

    @classmethod
    def options(cls, request: Request) -> dict[str, Any]:
        return {"work_terms": request.work_terms}

    def _reset(self, t: float, y: np.ndarray, keep_dense: bool = False) -> None:
        """Start afresh at (t, y); step, rejection, evaluation and event counters are kept.
        ``keep_dense``: the last step's dense output still serves outputs before t (after an
        event at t, for output times a later ``advance`` asks for). The restart itself (f at
        (t, y), the first step, the event functions) is done by the next ``advance``, in the
        same compiled call; with constraints it is done here, since it projects ``y``, which a
        caller may read before."""
        self.y[:] = y
        self.state["t"] = t
        self.comp[:] = 0.0
        # Two restarts before an advance: the dense output is kept only if both keep it.
        self._restart = (_RESTART_KEEP_DENSE if keep_dense and self._restart != _RESTART
                         else _RESTART)
        if self.kernels.n_c > 0:
            self._call(_NO_TIMES, np.empty((0, self.y.size)))

    def _call(self, t_out: np.ndarray, Y: np.ndarray) -> tuple[Status, int]:
        """One call of the compiled loop (the pending restart first)."""
        restart, self._restart = self._restart, _NO_RESTART
        return self._loop(  # type: ignore[no-any-return]
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
            raise self._stiff(h_old, gap)
        if status != Status.OK:
            raise self._fail(status) from None
        if not self.work_terms:
            n_q = self.kernels.n_q
            Y[:done, 2 * n_q:2 * n_q + 2] = np.nan  # not integrated: not a value
        return Y[:done]

    def _stiff(self, h_old: float, gap: float) -> StiffnessError:
        return StiffnessError(
            f"{self.model.id}: {self.method} stopped at t = {self.t:.6g}: the problem is "
            f"stiff (h·|λ| ≈ {float(self.state['h_lambda'][0]):.3g} > {self.STIFF_EDGE} on 15 "
            "tests: the step, "
            f"{h_old:.3g} s, is limited by stability, not accuracy, "
            f"{gap / h_old:.3g} steps per output interval; {self.n_steps} steps so "
            "far); the system's time "
            "scales are far apart (huge spring constant or damping?): soften those "
            "parameters, use a looser tolerance or a lower publish rate, or integrate it "
            "with a stiff (implicit) method such as scipy's Radau or BDF")

    def _restart_after_event(self, t: float, y: np.ndarray) -> None:
        self._reset(t, y, keep_dense=True)
