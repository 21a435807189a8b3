"""What the compiled loops and the Python steppers share: the status a loop returns and the
named fields of each stepper's state record.

A stepper keeps its state in a one-element structured array of one of the dtypes below; the
compiled loops read and write it as a record (``s = state[0]; s.n_steps += 1``) and Python
reads the same fields by name (``stepper.state["n_steps"][0]``), so no field has a magic
index. The stepping loops return a ``Status`` member, which arrives in Python as that member;
the whole-run loops (``compiled.runs``) return its value, a plain int that compares equal to
it (boxing a member goes through the Python enum class on every call).
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np


class Status(IntEnum):
    """Why a compiled loop returned."""

    OK = 0  # every requested output written
    MAX_STEPS = 1  # the step budget is spent
    STEP_UNDERFLOW = 2  # the step fell below round-off of t
    NOT_FINITE = 3  # the state stopped being finite
    EVENT = 4  # stopped at a state event (index in ``last_event``)
    STIFF = 5  # DOP853's stiffness test fired
    NOT_CONVERGED = 6  # implicit stage equations did not converge

    @property
    def reason(self) -> str:
        return _REASONS[self]


class Pair(IntEnum):
    """The explicit Runge–Kutta pair the shared loop (``compiled.erk._erk_advance``) steps with."""

    DOP853 = 0
    DOPRI5 = 1


_REASONS = {
    Status.OK: "ok", Status.MAX_STEPS: "too many steps",
    Status.STEP_UNDERFLOW: "step size underflow", Status.NOT_FINITE: "non-finite state",
    Status.EVENT: "event", Status.STIFF: "stiff",
    Status.NOT_CONVERGED: "stage equations did not converge",
}

_F = np.float64
_I = np.int64

#: Fields every state record has: the time reached, counters, and the accumulated estimate of
#: the local errors committed (in the tolerance's norm, relative to the state scale).
_COMMON = [("t", _F), ("n_steps", _I), ("n_evaluations", _I), ("n_rejected", _I),
           ("error_estimate", _F)]

#: DOP853 and DOPRI5 (the explicit pairs): next step h, the last accepted step (t_old, h_old)
#: whose dense output is ready when ``dense_ready``; event bookkeeping; Hairer's stiffness
#: test (positive and negative tests in a row, last h·|λ|); how many leading components of
#: y are integrated (the rest are kept as they are: the modes, constant between events, and
#: the work terms where nothing reads them).
DOP853_STATE = np.dtype(_COMMON + [
    ("h", _F), ("t_old", _F), ("h_old", _F), ("dense_ready", _I), ("last_event", _I),
    ("n_events", _I), ("stiff_positive", _I), ("stiff_negative", _I), ("h_lambda", _F),
    ("n_integrated", _I)])

#: Fixed-step methods (compositions, Gauss–Legendre): the counters only.
FIXED_STATE = np.dtype(_COMMON)

#: Gauss–Radau (IAS15 scheme): next step h, last accepted step h_old, the predictor–corrector
#: iterations spent, the compensation of t, event bookkeeping; whether F₀ (f at the current
#: state) is ready, outputs (or event states) computed by side steps of their own where the
#: expansion's error bound was too large, and the largest such bound seen (relative).
RADAU_STATE = np.dtype(_COMMON + [("h", _F), ("h_old", _F), ("n_iterations", _I),
                                  ("t_comp", _F), ("last_event", _I), ("n_events", _I),
                                  ("f0_ready", _I), ("n_side", _I), ("dense_error", _F)])


def new_state(dtype: np.dtype, t: float) -> np.ndarray:
    state = np.zeros(1, dtype=dtype)
    state["t"] = t
    return state
