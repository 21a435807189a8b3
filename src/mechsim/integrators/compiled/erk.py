"""The explicit Runge–Kutta pairs, DOP853 and DOPRI5, in one loop (``_erk_advance``,
``pair`` selects the tableau; entry points ``dop853_advance``, ``dopri5_advance``).

DOP853: Hairer's explicit Runge-Kutta 8(5,3) with the 7th-order dense output
(``dop853_tableau``), the error norm and step control of ``dop853.f`` (and of scipy's
``DOP853``, so tolerances mean the same thing in both). DOPRI5: Dormand and Prince's 5(4) pair
with its 4th-order dense output (``dopri5_tableau``), the error norm of ``dopri5.f`` and
DOP853's step control with exponent 1/5 (as scipy's ``RK45``; ``dopri5.f``'s small PI term is
left out), for loose tolerances: 6 evaluations a step instead of 12. Everything below holds
for both. Events as described in ``events``, located on the step's dense output.

Stiffness (Hairer's test from dop853.f and dopri5.f, read-only): every 1000th accepted step,
and every step while a test is positive, h·‖f(y_new) − f(last stage)‖ / ‖y_new − last stage‖
(both at t + h: stage 12, stage 6) estimates h|λ|; above 6.1 (DOPRI5: 3.25; the edge of the
stability region) the step is limited by stability, not accuracy. 15 positive tests before 6
negative ones in a row: the loop stops after the accepted step with status STIFF.

The helpers of the loop are inlined into it (``inline="always"``), and the loop into each
pair's entry point: there ``pair`` is a constant and the other pair's branches drop out.
"""

import math

import numpy as np
from numba import njit

from mechsim.integrators.compiled.common import (
    _any_crossed,
    _borrowed,
    _copy,
    _copy_row,
    _crossed,
    _rms_norm,
    _row,
    _zero,
)
from mechsim.integrators.compiled.events import DENSE_ERK, _dense_eval, _locate_event
from mechsim.integrators.compiled.stages import (
    _dop853_dense_stages,
    _dop853_dense_sums,
    _dop853_increment,
    _dop853_stages,
    _dopri5_dense_sum,
    _dopri5_error_fsal,
    _dopri5_increment,
    _dopri5_stages,
)
from mechsim.integrators.state import Pair, Status

#: The explicit Runge–Kutta pairs of ``_erk_advance`` (its ``pair`` argument, ``state.Pair``):
#: DOP853 and DOPRI5 share the loop, step control, dense-output evaluation, events,
#: projection and stiffness test; they differ in their stages, FSAL row (``_fsal``),
#: controller exponent (1/8, 1/5: one over the order of the error estimate plus one, as in
#: ``dop853.f`` and ``dopri5.f``) and the edge of their stability region on the negative real
#: axis (6.1, 3.25) for Hairer's stiffness test.
PAIR_DOP853 = int(Pair.DOP853)
PAIR_DOPRI5 = int(Pair.DOPRI5)


@njit(inline="always")
def _shrink(err, dopri5):
    """err^(−1/5) (DOPRI5) or err^(−1/8) (DOP853): the controller's step factor before its
    safety factor and limits; DOP853's as three square roots, cheaper than ``pow``."""
    if dopri5:
        return err ** -0.2
    return 1.0 / math.sqrt(math.sqrt(math.sqrt(err)))


@njit(inline="always")
def _fsal(pair):
    """Row of K holding f at the end of the step (the next step's first stage)."""
    return 6 if pair == PAIR_DOPRI5 else 12


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def erk_initial_step(ks, t, y, p, f0, rtol, atol, order, n):
    """First step size (Hairer's starting-step algorithm, as in ``dop853.f`` (``order`` 8) and
    ``dopri5.f`` (5)), from the first ``n`` (integrated) components."""
    scale = np.empty(n)
    for i in range(n):
        scale[i] = atol + abs(y[i]) * rtol
    d0 = _rms_norm(y[:n], scale)
    d1 = _rms_norm(f0[:n], scale)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    y1 = y.copy()
    for i in range(n):
        y1[i] += h0 * f0[i]
    f1 = np.zeros(y.size)
    ks.rhs(t + h0, y1.ctypes, p.ctypes, f1.ctypes)
    d2 = _rms_norm(f1[:n] - f0[:n], scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / order)
    return min(100.0 * h0, h1)


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def erk_restart(ks, pair, state, y, p, K, rtol, atol, g_old, keep_dense):
    """Start (or restart after an event) at the state's time and y: project y, f(t, y) into
    K[_fsal(pair)] (the next step's first stage), the first step, the event functions into
    g_old; the step, rejection, evaluation and event counters are kept. ``keep_dense``: the
    last step's dense output still serves outputs before t."""
    s = state[0]
    t = s.t
    if ks.n_c > 0:
        ks.project(t, y, p)
    last = _fsal(pair)
    ks.rhs(t, y.ctypes, p.ctypes, K[last].ctypes)
    s.h = erk_initial_step(ks, t, y, p, K[last].copy(), rtol, atol,
                           5.0 if pair == PAIR_DOPRI5 else 8.0, s.n_integrated)
    if not keep_dense:
        s.t_old = t
        s.h_old = 0.0
        s.dense_ready = 0
    s.last_event = -1
    s.stiff_positive = 0
    s.stiff_negative = 0
    s.h_lambda = 0.0
    s.n_evaluations += 2
    if ks.n_ev > 0:
        ks.event(t, y, p, g_old)


@njit(inline="always")  # into each pair's loop: ``pair`` a constant there
def _dense_prepare(ks, pair, s, y, y_old, K, F, p):
    """Interpolation coefficients for the last accepted step (t_old, t] (DOP853: with its
    three extra stages; DOPRI5 needs none and leaves F[4 … 6] at zero, where ``_dense_eval``
    reads its 4th-order interpolant)."""
    n = s.n_integrated
    h = s.h_old
    last = _fsal(pair)
    if pair == PAIR_DOP853:
        # F[6] as the stages' scratch state (the entries not integrated as at the step's
        # start, for the kernels; zero again after, so that ``_dense_eval`` keeps them): the
        # coefficients below overwrite it.
        for i in range(n, y.size):
            F[6, i] = y_old[i]
        _dop853_dense_stages(ks, s.t_old, y_old, h, K, F[6], p, n)
        for i in range(n, y.size):
            F[6, i] = 0.0
        s.n_evaluations += 3
    for i in range(n):
        dlt = y[i] - y_old[i]
        F[0, i] = dlt
        F[1, i] = h * K[0, i] - dlt
        F[2, i] = 2.0 * dlt - h * (K[last, i] + K[0, i])
        if pair == PAIR_DOP853:
            d0, d1, d2, d3 = _dop853_dense_sums(K, i)
            F[3, i] = h * d0
            F[4, i] = h * d1
            F[5, i] = h * d2
            F[6, i] = h * d3
        else:
            F[3, i] = h * _dopri5_dense_sum(K, i)
    s.dense_ready = 1


@njit(inline="always")  # into each pair's loop: ``pair`` a constant there
def _dense_output(ks, pair, s, y, y_old, K, F, p, t, out):
    """The state at t in the last accepted step (t_old, t_new] from its dense output,
    projected onto the constraints."""
    if s.dense_ready == 0:
        _dense_prepare(ks, pair, s, y, y_old, K, F, p)
    _dense_eval(F, y_old, (t - s.t_old) / s.h_old, out)
    if ks.n_c > 0:
        ks.project(t, out, p)


@njit(cache=True, inline="always")
def _take_increment(i, h, sums, y, comp, y_new, inc, err5, err3):
    """From a pair's ``(Σ b_j k_j, Σ E5_j k_j, Σ E3_j k_j)`` of component i: y_new[i] =
    y[i] + h Σ b_j k_j with the compensation carried from the last step, the increment taken
    kept in ``inc`` (the new compensation is what of it y_new lost), the error sums."""
    b, a5, a3 = sums
    d = h * b + comp[i]
    y_new[i] = y[i] + d
    inc[i] = d
    err5[i] = a5
    err3[i] = a3


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def dop853_advance(ks, state, y, y_old, K, F, p, t_out, Y_out, rtol, atol, h_max, max_steps,
                   g_old, ev_dir, comp, restart):
    """Advance with DOP853 (``_erk_advance``). ``restart``: first start afresh at the state's
    time and y (``erk_restart``; 2: keeping the last step's dense output)."""
    if restart > 0:
        erk_restart(ks, PAIR_DOP853, state, y, p, K, rtol, atol, g_old, restart == 2)
    return _dop853_steps(ks, state, y, y_old, K, F, p, t_out, Y_out, rtol, atol, h_max,
                         max_steps, g_old, ev_dir, comp, _erk_work(ks, state, y))


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def dopri5_advance(ks, state, y, y_old, K, F, p, t_out, Y_out, rtol, atol, h_max, max_steps,
                   g_old, ev_dir, comp, restart):
    """Advance with DOPRI5, as ``dop853_advance``."""
    if restart > 0:
        erk_restart(ks, PAIR_DOPRI5, state, y, p, K, rtol, atol, g_old, restart == 2)
    return _dopri5_steps(ks, state, y, y_old, K, F, p, t_out, Y_out, rtol, atol, h_max,
                         max_steps, g_old, ev_dir, comp, _erk_work(ks, state, y))


@njit(inline="always")
def _erk_work(ks, state, y):
    """The loop's scratch arrays: y_new and the last stage's y (copies of y: the entries not
    integrated stay as they are), the increments, the error scale, the two error sums, and
    the event functions at the end of a step."""
    n = state[0].n_integrated
    return (y.copy(), y.copy(), np.empty(n), np.empty(n), np.empty(n), np.empty(n),
            np.empty(max(ks.n_ev, 1)))


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _dop853_steps(ks, state, y, y_old, K, F, p, t_out, Y_out, rtol, atol, h_max, max_steps,
                  g_old, ev_dir, comp, work):
    return _erk_advance(ks, PAIR_DOP853, state, y, y_old, K, F, p, t_out, Y_out, rtol, atol,
                        h_max, max_steps, g_old, ev_dir, comp, work)


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _dopri5_steps(ks, state, y, y_old, K, F, p, t_out, Y_out, rtol, atol, h_max, max_steps,
                  g_old, ev_dir, comp, work):
    return _erk_advance(ks, PAIR_DOPRI5, state, y, y_old, K, F, p, t_out, Y_out, rtol, atol,
                        h_max, max_steps, g_old, ev_dir, comp, work)


@njit(inline="always")  # into each pair's loop: its ``pair`` a constant there, the other
# pair's branches drop out of the compiled loop
def _erk_advance(ks, pair, state, y, y_old, K, F, p, t_out, Y_out, rtol, atol, h_max,
                 max_steps, g_old, ev_dir, comp, work):
    """Advance with the explicit pair ``pair`` (``PAIR_DOP853``, ``PAIR_DOPRI5``) until every
    time in ``t_out`` (increasing, >= the start of the last step) is written to ``Y_out``.
    ``state``: a ``DOP853_STATE`` record; ``y`` the current state with its compensation
    ``comp``; ``y_old``/``K``/``F`` the last step's data, with K[_fsal(pair)] = f(t, y) on
    entry (made by ``erk_restart`` on a restart); ``g_old`` the event functions at (t, y)
    (likewise), ``ev_dir`` their directions.
    Returns (status, number of outputs written); on EVENT the state is at the event time
    (outputs before it written) and ``last_event`` is its index; on STIFF the state is at the
    end of the last accepted step (outputs up to it written). ``work``: the loop's scratch
    arrays (``_erk_work``); the arrays are borrowed (see ``common``)."""
    y, y_old, K, F, p, t_out, Y_out, g_old, ev_dir, comp = (
        _borrowed(y), _borrowed(y_old), _borrowed(K), _borrowed(F), _borrowed(p),
        _borrowed(t_out), _borrowed(Y_out), _borrowed(g_old), _borrowed(ev_dir),
        _borrowed(comp))
    y_new, ytmp, inc, scale, err5, err3, g_new = (
        _borrowed(work[0]), _borrowed(work[1]), _borrowed(work[2]), _borrowed(work[3]),
        _borrowed(work[4]), _borrowed(work[5]), _borrowed(work[6]))
    s = state[0]
    rhs = ks.rhs
    pp = p.ctypes
    n = s.n_integrated  # the first n components; the rest (modes, work terms left out) kept
    dopri5 = pair == PAIR_DOPRI5
    last = _fsal(pair)  # f(t + h, y_new); the stage before it is at t + h too
    n_out = t_out.size
    k = _erk_outputs_so_far(ks, pair, s, y, y_old, K, F, p, t_out, Y_out)
    steps = 0
    rejected = False
    while k < n_out:
        t = s.t
        h = min(s.h, h_max)
        status = _step_status(steps, max_steps, t, h)
        if status != Status.OK:
            return status, k
        _first_stage(K, last, n, rejected)
        if dopri5:
            _dopri5_stages(ks, t, y, h, K, ytmp, p, n)
        else:
            _dop853_stages(ks, t, y, h, K, ytmp, p, n)
        _erk_increments(pair, h, y, comp, K, y_new, inc, err5, err3, n)
        rhs(t + h, y_new.ctypes, pp, _row(K, last))
        s.n_evaluations += last  # the stages after the first, and f at the new point
        err = _erk_error(pair, h, y, y_new, K, err5, err3, scale, rtol, atol, n)
        if err >= 1.0:
            s.h = h * max(0.2, 0.9 * _shrink(err, dopri5))
            s.n_rejected += 1
            rejected = True
            continue
        stiff = False
        if _stiffness_due(s):
            stiff = _stiffness_test(s, pair, h, K, y_new, ytmp, n)
        factor = _step_factor(err, dopri5, rejected)
        rejected = False
        if not _all_finite(y_new, n):
            return Status.NOT_FINITE, k
        _erk_compensation(y, y_old, y_new, inc, comp, n)
        if ks.n_c > 0:
            ks.project(t + h, y_new, p)
            rhs(t + h, y_new.ctypes, pp, _row(K, last))
            s.n_evaluations += 1
            comp[:] = 0.0  # the projection moved the state: nothing left to carry
        _erk_accept(s, t, h, factor, err * rtol, y, y_new)
        steps += 1
        if ks.n_ev > 0:
            ks.event(s.t, y, p, g_new)
            if _any_crossed(g_old, g_new, ev_dir):
                return Status.EVENT, _erk_event(ks, pair, s, t, h, y, y_old, K, F, inc, p, comp,
                                                g_old, g_new, ev_dir, t_out, Y_out, k)
            _copy(g_old, g_new)
        while _output_due(t_out, k, s.t):  # outputs in the step just taken
            if t_out[k] == s.t:
                _copy_row(Y_out, k, y)
            else:
                _dense_output(ks, pair, s, y, y_old, K, F, p, t_out[k], Y_out[k])
            k += 1
        if stiff:
            return Status.STIFF, k
    return Status.OK, k


@njit(inline="always")
def _step_status(steps, max_steps, t, h):
    """Whether a step of h from t may be taken after ``steps`` of this call: OK, or
    MAX_STEPS, or STEP_UNDERFLOW where h is below round-off of t."""
    status = Status.OK
    if steps >= max_steps:
        status = Status.MAX_STEPS
    elif h < 10.0 * abs(np.nextafter(t, np.inf) - t):
        status = Status.STEP_UNDERFLOW
    return status


@njit(inline="always")
def _output_due(t_out, k, t):
    """Whether output k (if any is left) falls at or before t."""
    return k < t_out.size and t_out[k] <= t


@njit(inline="always")
def _stiffness_due(s):
    """The stiffness test runs every 1000th step, and on every step while it is positive."""
    return s.n_steps % 1000 == 0 or s.stiff_positive > 0


@njit(inline="always")
def _erk_outputs_in_step(ks, pair, s, y, y_old, K, F, p, t_out, Y_out, k):
    """Write the outputs from index k on that fall in the last accepted step (t_old, t] (at
    t: the state; before: the dense output); returns the next index."""
    t_new = s.t
    while k < t_out.size and t_out[k] <= t_new:
        if t_out[k] == t_new:
            _copy_row(Y_out, k, y)
        else:
            _dense_output(ks, pair, s, y, y_old, K, F, p, t_out[k], Y_out[k])
        k += 1
    return k


@njit(inline="always")
def _erk_outputs_so_far(ks, pair, s, y, y_old, K, F, p, t_out, Y_out):
    """Write the outputs a call asks for up to the current time: those in the last accepted
    step, if there is one, and those at the current time; returns how many."""
    k = 0
    if s.h_old > 0.0:
        k = _erk_outputs_in_step(ks, pair, s, y, y_old, K, F, p, t_out, Y_out, 0)
    while k < t_out.size and t_out[k] == s.t:
        _copy_row(Y_out, k, y)
        k += 1
    return k


@njit(inline="always")
def _first_stage(K, last, n, rejected):
    """FSAL: f at the end of the last accepted step becomes the next step's first stage (a
    step redone after a rejection has it already)."""
    if not rejected:
        for i in range(n):
            K[0, i] = K[last, i]


@njit(inline="always")
def _erk_increments(pair, h, y, comp, K, y_new, inc, err5, err3, n):
    """From the stages in K: y_new with the compensation carried from the last step, the
    increments taken and the error sums (``_take_increment``)."""
    if pair == PAIR_DOPRI5:
        for i in range(n):
            _take_increment(i, h, _dopri5_increment(K, i), y, comp, y_new, inc, err5, err3)
    else:
        for i in range(n):
            _take_increment(i, h, _dop853_increment(K, i), y, comp, y_new, inc, err5, err3)


@njit(inline="always")
def _all_finite(x, n):
    finite = True
    for i in range(n):
        if not math.isfinite(x[i]):
            finite = False
    return finite


@njit(inline="always")
def _erk_error(pair, h, y, y_new, K, err5, err3, scale, rtol, atol, n):
    """The step's error estimate in the norm of ``dop853.f`` (DOPRI5: with its FSAL stage's
    share, the plain RMS norm), relative to atol + rtol·max(|y|, |y_new|); 1e10 where it is
    not finite."""
    dopri5 = pair == PAIR_DOPRI5
    for i in range(n):
        if dopri5:
            err5[i] += _dopri5_error_fsal(K, i)
        scale[i] = atol + max(abs(y[i]), abs(y_new[i])) * rtol
        err5[i] /= scale[i]
        err3[i] /= scale[i]
    e5 = 0.0
    e3 = 0.0
    for i in range(n):
        e5 += err5[i] * err5[i]
        e3 += err3[i] * err3[i]
    if e5 == 0.0 and e3 == 0.0:
        err = 0.0
    else:  # DOPRI5 (e3 = 0): h √(e5 / n), the plain RMS norm
        err = h * e5 / math.sqrt((e5 + 0.01 * e3) * n)
    if not math.isfinite(err):
        err = 1e10
    return err


@njit(inline="always")
def _step_factor(err, dopri5, rejected):
    """The next step's factor after an accepted one (at most 1 right after a rejection)."""
    if err == 0.0:
        factor = 10.0
    else:
        factor = min(10.0, 0.9 * _shrink(err, dopri5))
    if rejected:
        factor = min(1.0, factor)
    return factor


@njit(inline="always")
def _stiffness_test(s, pair, h, K, y_new, ytmp, n):
    """Hairer's stiffness test on the step just accepted (see the module docstring): records
    h|λ| and the positive and negative tests in a row; True when it fires."""
    last = _fsal(pair)
    # The last stage (ytmp, K[last - 1]) and y_new (K[last]) are both at t + h.
    stnum = 0.0
    stden = 0.0
    for i in range(n):
        stnum += (K[last, i] - K[last - 1, i]) ** 2
        stden += (y_new[i] - ytmp[i]) ** 2
    stiff = False
    if stden > 0.0:
        s.h_lambda = h * math.sqrt(stnum / stden)
        if s.h_lambda > (3.25 if pair == PAIR_DOPRI5 else 6.1):
            s.stiff_negative = 0
            s.stiff_positive += 1
            stiff = s.stiff_positive >= 15
        else:
            s.stiff_negative += 1
            if s.stiff_negative >= 6:
                s.stiff_positive = 0
    return stiff


@njit(inline="always")
def _erk_compensation(y, y_old, y_new, inc, comp, n):
    """Before the step is taken: y_old the state before it, the new compensation what of the
    increments y_new lost."""
    _copy(y_old, y)
    for i in range(n):
        comp[i] = inc[i] - (y_new[i] - y[i])


@njit(inline="always")
def _erk_accept(s, t, h, factor, error, y, y_new):
    """Take the step of h from t (to y_new, projected): the next step ``factor`` × h,
    ``error`` added to the estimate."""
    _copy(y, y_new)
    s.t_old = t
    s.h_old = h
    s.t = t + h
    s.dense_ready = 0
    s.h = h * factor
    s.error_estimate += error
    s.n_steps += 1


@njit(inline="always")
def _erk_event(ks, pair, s, t, h, y, y_old, K, F, inc, p, comp, g_old, g_new, ev_dir, t_out,
               Y_out, k):
    """The step of h from t crossed an event (event functions ``g_old`` at its start,
    ``g_new`` at its end): the earliest one, located on the dense output; the outputs before
    it written and the state left at it. Returns the next output index."""
    t_new = s.t
    first = -1
    t_ev = t_new
    for i in range(ks.n_ev):
        if _crossed(g_old[i], g_new[i], ev_dir[i]):
            if s.dense_ready == 0:
                _dense_prepare(ks, pair, s, y, y_old, K, F, p)
            # (the search on the dense output is free: no evaluations to count)
            ti = _locate_event(ks, DENSE_ERK, F, inc, y_old, inc, t, 0.0, h, p, 0.0,
                               np.zeros(3, dtype=np.int64), i, t, g_old[i], t_new, g_new[i])
            if first < 0 or ti < t_ev:
                first = i
                t_ev = ti
    while k < t_out.size and t_out[k] < t_ev:
        _dense_output(ks, pair, s, y, y_old, K, F, p, t_out[k], Y_out[k])
        k += 1
    if t_ev < t_new:
        _dense_output(ks, pair, s, y, y_old, K, F, p, t_ev, y)
    _zero(comp)
    s.t = t_ev
    s.last_event = first
    s.n_events += 1
    return k
