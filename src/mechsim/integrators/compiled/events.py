"""The state inside the step just taken, and the events located there.

Events (models with events only): after each accepted step the event functions are evaluated;
a sign change in an event's declared direction is bracketed in (t_old, t] and its time found
on the step's interior (``_state_in_step``: the explicit pairs' dense output, or radau15's
expansion or side steps) by Illinois false position with a bisection fallback, to 4 ulps of t
(the late side of each bracket adds up over a run of many events: a relative tolerance would
shift a bouncing particle's positions measurably over a long run). The earliest event of the
step wins: outputs before it are written, the state is left at the event time (on the side of
the sign change the event reached) and the loop returns EVENT. The step's interior stays valid
for (t_old, t_event], so outputs before the event that a later call asks for still come from
it after the caller has restarted at the event.
"""

import math

import numpy as np
from numba import njit

from mechsim.integrators.compiled.radau_basis import _radau_dense_at
from mechsim.integrators.compiled.radau_iteration import _radau_side_step

#: How a step's interior is evaluated for event location: the explicit pairs' dense output
#: (DOP853, DOPRI5; F = its coefficients), the Gauss–Radau expansion of radau15 (F = b, with
#: F0 and the compensation), or, where that expansion's error bound is not good enough, a
#: Gauss–Radau step of its own from the start of the step (``_radau_side_step``: what
#: landing there would give).
DENSE_ERK = 0
DENSE_RADAU = 1
DENSE_RADAU_STEP = 2


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _dense_eval(F, y_old, x, out):
    n = y_old.size
    for i in range(n):
        acc = 0.0
        for j in range(6, -1, -1):
            acc += F[j, i]
            if (6 - j) % 2 == 0:
                acc *= x
            else:
                acc *= 1.0 - x
        out[i] = acc + y_old[i]


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _state_in_step(ks, mode, t, F, F0, y0, comp, t0, tc, h, p, w_floor, cost, out):
    """The state at t inside the step that started at (t0 + tc, y0) with length h
    (unprojected; tc, the low-order part of the start time, keeps the offset into the step
    exact where t is large);
    ``cost`` counts the evaluations and iterations of a side step. False: a side step's
    iteration did not converge."""
    frac = ((t - t0) - tc) / h
    if mode == DENSE_ERK:
        _dense_eval(F, y0, frac, out)
        return True
    if mode == DENSE_RADAU:
        out[:] = y0
        _radau_dense_at(frac, ks.n_q, y0, F0, F, h, comp, out)
        return True
    return _radau_side_step(ks, t0 + tc, y0, comp, F0, F, h, frac, p, w_floor, cost, out)


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _event_at(ks, mode, t, F, F0, y0, comp, t0, tc, h, p, w_floor, cost, ytmp, g, i):
    """Event function ``i`` at time t inside the last step (state projected); NaN where a
    side step did not converge."""
    if not _state_in_step(ks, mode, t, F, F0, y0, comp, t0, tc, h, p, w_floor, cost, ytmp):
        return math.nan
    if ks.n_c > 0:
        ks.project(t, ytmp, p)
    ks.event(t, ytmp, p, g)
    return g[i]


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _locate_event(ks, mode, F, F0, y0, comp, t0, tc, h, p, w_floor, cost, i, a, fa, b, fb):
    """Root of event ``i`` bracketed by (a, fa) and (b, fb), fb on the far side of the sign
    change or zero: Illinois false position, bisecting when the bracket shrinks slowly.
    Returns the bracket end on the far side (so the event has happened there); NaN where
    the state inside the step could not be had (a side step did not converge)."""
    ytmp = np.empty(y0.size)
    g = np.empty(ks.n_ev)
    side = 0
    slow = 0
    for _ in range(200):
        width = b - a
        tol = 4.0 * (np.nextafter(b, np.inf) - b)
        if width <= tol or fb == 0.0:
            break
        if slow >= 2:
            c = 0.5 * (a + b)
            slow = 0
        else:
            c = b - fb * (b - a) / (fb - fa)
            if not (a < c < b):
                c = 0.5 * (a + b)
        fc = _event_at(ks, mode, c, F, F0, y0, comp, t0, tc, h, p, w_floor, cost, ytmp, g,
                       i)
        if math.isnan(fc):
            return fc
        if (fc > 0.0) == (fb > 0.0) or fc == 0.0:
            b = c
            fb = fc
            if side == 1:
                fa *= 0.5
            side = 1
        else:
            a = c
            fa = fc
            if side == -1:
                fb *= 0.5
            side = -1
        if b - a > 0.5 * width:
            slow += 1
        else:
            slow = 0
    return b
