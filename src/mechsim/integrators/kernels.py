"""The integrator loops, compiled once per machine and shared by every model.

Each loop takes the model's ``KernelSet`` (``mechsim.codegen.contract``): the model's compiled
functions as first-class function values and its sizes, so one compiled loop serves every
model and the calls into the model stay compiled. This file is not imported directly:
``mechsim.integrators`` loads it through ``mechsim.codegen.load_module`` under a name that
hashes its text and every module it reads (tableau, state records, contract), so numba's disk
cache can never serve a loop compiled from older inputs.

The loops are resumable: their whole state lives in arrays the caller keeps between calls (a
state record of ``mechsim.integrators.state`` and work arrays), so a node can advance a run
output by output with no restart cost and no forced short steps. Every loop updates the
state with compensated (Kahan) summation: the low-order bits lost when a small increment is
added to a large state are kept in ``comp`` and added back at the next step, so round-off
does not accumulate in long runs.

DOP853: Hairer's explicit Runge-Kutta 8(5,3) with the 7th-order dense output
(``dop853_tableau``), the error norm and step control of ``dop853.f`` (and of scipy's
``DOP853``, so tolerances mean the same thing in both). DOPRI5: Dormand and Prince's 5(4) pair
with its 4th-order dense output (``dopri5_tableau``), the error norm of ``dopri5.f`` and
DOP853's step control with exponent 1/5 (as scipy's ``RK45``; ``dopri5.f``'s small PI term is
left out), for loose tolerances: 6 evaluations a step instead of 12. Both run in one loop
(``_erk_advance``, ``pair`` selects the tableau; entry points ``dop853_advance``,
``dopri5_advance``): everything below holds for both.
Events (models with events only): after each accepted step the event functions are evaluated;
a sign change in an event's declared direction is bracketed in (t_old, t] and its time found
on the dense output (Illinois false position with bisection fallback, to 4 ulps of t: a
relative 1e-14 let the late side of each bracket add up over the 16000 bounces of 2000 s of
``gas_in_box`` to 1.5e-8 in the positions, 4 ulps to 9e-10). The earliest event of the
step wins: outputs before it are written, the state is left at the event time (on the side
of the sign change the event reached) and the loop returns EVENT.
The step's dense output stays valid for (t_old, t_event], so outputs before the event that a
later call asks for still come from it after the caller has restarted at the event.
Stiffness (Hairer's test from dop853.f and dopri5.f, read-only): every 1000th accepted step,
and every step while a test is positive, h·‖f(y_new) − f(last stage)‖ / ‖y_new − last stage‖
(both at t + h: stage 12, stage 6) estimates h|λ|; above 6.1 (DOPRI5: 3.25; the edge of the
stability region) the step is limited by stability, not accuracy. 15 positive tests before 6
negative ones in a row: the loop stops after the accepted step with status STIFF.
Composition: a symmetric composition of velocity Verlet (kick-drift-kick) with given weights.
Gauss: three-stage Gauss–Legendre collocation on Hamilton's equations.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from mechsim.integrators.state import Pair, Status


@intrinsic
def _row(typingctx, a, i):  # type: ignore[no-untyped-def]
    """``a[i].ctypes`` of a C-contiguous 2-D float64 array without making the view ``a[i]``:
    a view costs an atomic reference-count increment and decrement, and a DOP853 step passes
    twelve rows to the kernel (their atomics were ≈ 7 % of a Kepler run)."""
    def codegen(context, builder, sig, args):  # type: ignore[no-untyped-def]
        ary = context.make_array(sig.args[0])(context, builder, args[0])
        zero = context.get_constant(types.intp, 0)
        return cgutils.get_item_pointer(context, builder, sig.args[0], ary, [args[1], zero])
    return types.CPointer(types.float64)(a, types.intp), codegen


# >>> stubs: ``mechsim.integrators.loops`` replaces this block with the ``loop_source()`` of
# ``dop853_tableau`` and ``dopri5_tableau``, the stage sums written out from the tableaus.


def _dop853_stages(ks, t0, y0, h, K, ytmp, p, n):
    """Stages 2 … 12 from (t0, y0) into K[1 … 11]; ytmp ends as stage 12's y."""
    raise NotImplementedError


def _dop853_dense_stages(ks, t0, y0, h, K, ytmp, p, n):
    """Stages 14 … 16 (dense output only) into K[13 … 15]."""
    raise NotImplementedError


def _dop853_increment(K, i):
    """(Σ b_j k_j, Σ E5_j k_j, Σ E3_j k_j) of component i."""
    raise NotImplementedError


def _dop853_dense_sums(K, i):
    """Σ_j D[r][j] k_j of component i, r = 0 … 3."""
    raise NotImplementedError


def _dopri5_stages(ks, t0, y0, h, K, ytmp, p, n):
    """Stages 2 … 6 from (t0, y0) into K[1 … 5]; ytmp ends as stage 6's y."""
    raise NotImplementedError


def _dopri5_increment(K, i):
    """(Σ b_j k_j, Σ_{j<7} E_j k_j, 0) of component i."""
    raise NotImplementedError


def _dopri5_error_fsal(K, i):
    """E_7 k_7 of component i (k_7: f at the new point)."""
    raise NotImplementedError


def _dopri5_dense_sum(K, i):
    """Σ_j D_j k_j of component i."""
    raise NotImplementedError


# <<< stubs

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
    safety factor and limits; DOP853's as three square roots, a third of the cost of ``pow``
    (which took ≈ 6 % of a Kepler run)."""
    if dopri5:
        return err ** -0.2
    return 1.0 / math.sqrt(math.sqrt(math.sqrt(err)))


@njit(cache=True)
def _fsal(pair):
    """Row of K holding f at the end of the step (the next step's first stage)."""
    return 6 if pair == PAIR_DOPRI5 else 12


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _rms_norm(x, scale):
    s = 0.0
    for i in range(x.size):
        z = x[i] / scale[i]
        s += z * z
    return math.sqrt(s / x.size)


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
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


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
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


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
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


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _crossed(g0, g1, direction):
    """A sign change from g0 to g1 in ``direction`` (+1 rising, -1 falling, 0 either)."""
    if direction >= 0 and g0 < 0.0 <= g1:
        return True
    return direction <= 0 and g0 > 0.0 >= g1


#: How a step's interior is evaluated for event location: the explicit pairs' dense output
#: (DOP853, DOPRI5; F = its coefficients), the Gauss–Radau expansion of radau15 (F = b, with
#: F0 and the compensation), or, where that expansion's error bound is not good enough, a
#: Gauss–Radau step of its own from the start of the step (``_radau_side_step``: what
#: landing there would give).
DENSE_ERK = 0
DENSE_RADAU = 1
DENSE_RADAU_STEP = 2


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
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


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _event_at(ks, mode, t, F, F0, y0, comp, t0, tc, h, p, w_floor, cost, ytmp, g, i):
    """Event function ``i`` at time t inside the last step (state projected); NaN where a
    side step did not converge."""
    if not _state_in_step(ks, mode, t, F, F0, y0, comp, t0, tc, h, p, w_floor, cost, ytmp):
        return math.nan
    if ks.n_c > 0:
        ks.project(t, ytmp, p)
    ks.event(t, ytmp, p, g)
    return g[i]


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
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


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def dop853_advance(ks, state, y, y_old, K, F, p, t_out, Y_out, rtol, atol, h_max, max_steps,
                   g_old, ev_dir, comp, restart):
    """``_erk_advance`` with DOP853."""
    return _erk_advance(ks, PAIR_DOP853, state, y, y_old, K, F, p, t_out, Y_out, rtol, atol,
                        h_max, max_steps, g_old, ev_dir, comp, restart)


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def dopri5_advance(ks, state, y, y_old, K, F, p, t_out, Y_out, rtol, atol, h_max, max_steps,
                   g_old, ev_dir, comp, restart):
    """``_erk_advance`` with DOPRI5."""
    return _erk_advance(ks, PAIR_DOPRI5, state, y, y_old, K, F, p, t_out, Y_out, rtol, atol,
                        h_max, max_steps, g_old, ev_dir, comp, restart)


@njit(inline="always")  # into each pair's entry point: its ``pair`` a constant there, the
# other pair's branches drop out of the compiled loop (a run-time ``pair`` cost DOP853 3–6 %)
def _erk_advance(ks, pair, state, y, y_old, K, F, p, t_out, Y_out, rtol, atol, h_max,
                 max_steps, g_old, ev_dir, comp, restart):
    """Advance with the explicit pair ``pair`` (``PAIR_DOP853``, ``PAIR_DOPRI5``) until every
    time in ``t_out`` (increasing, >= the start of the last step) is written to ``Y_out``.
    ``state``: a ``DOP853_STATE`` record; ``y`` the current state with its compensation
    ``comp``; ``y_old``/``K``/``F`` the last step's data, with K[_fsal(pair)] = f(t, y) on
    entry (or made by ``restart``, below); ``g_old`` the event functions at (t, y) (likewise),
    ``ev_dir`` their directions.
    Returns (status, number of outputs written); on EVENT the state is at the event time
    (outputs before it written) and ``last_event`` is its index; on STIFF the state is at the
    end of the last accepted step (outputs up to it written). ``restart``: first start afresh
    at the state's time and y (``erk_restart``; 2: keeping the last step's dense output)."""
    if restart > 0:
        erk_restart(ks, pair, state, y, p, K, rtol, atol, g_old, restart == 2)
    s = state[0]
    rhs = ks.rhs
    pp = p.ctypes
    n = s.n_integrated  # the first n components; the rest (modes, work terms left out) kept
    n_c = ks.n_c
    n_ev = ks.n_ev
    y_new = y.copy()
    inc = np.empty(n)
    ytmp = y.copy()
    scale = np.empty(n)
    err5 = np.empty(n)
    err3 = np.empty(n)
    no_cost = np.zeros(3, dtype=np.int64)  # the event search on the dense output is free
    dopri5 = pair == PAIR_DOPRI5
    last = _fsal(pair)  # f(t + h, y_new); the stage before it is at t + h too
    n_new = last  # evaluations of a step
    stiff_edge = 3.25 if dopri5 else 6.1
    n_out = t_out.size
    k = 0
    steps = 0
    # Outputs that fall in the last accepted step (t_old, t].
    while k < n_out and s.h_old > 0.0 and t_out[k] <= s.t:
        if t_out[k] == s.t:
            Y_out[k, :] = y
        else:
            _dense_output(ks, pair, s, y, y_old, K, F, p, t_out[k], Y_out[k])
        k += 1
    while k < n_out and t_out[k] == s.t:
        Y_out[k, :] = y
        k += 1
    rejected = False
    while k < n_out:
        if steps >= max_steps:
            return Status.MAX_STEPS, k
        t = s.t
        h = min(s.h, h_max)
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        if h < min_step:
            return Status.STEP_UNDERFLOW, k
        if not rejected:
            # FSAL: f(t, y) of the last accepted step end becomes this step's first stage.
            for i in range(n):
                K[0, i] = K[last, i]
        if dopri5:
            _dopri5_stages(ks, t, y, h, K, ytmp, p, n)
            for i in range(n):
                _take_increment(i, h, _dopri5_increment(K, i), y, comp, y_new, inc, err5,
                                err3)
        else:
            _dop853_stages(ks, t, y, h, K, ytmp, p, n)
            for i in range(n):
                _take_increment(i, h, _dop853_increment(K, i), y, comp, y_new, inc, err5,
                                err3)
        rhs(t + h, y_new.ctypes, pp, _row(K, last))
        s.n_evaluations += n_new
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
        if err < 1.0:
            stiff = False
            if s.n_steps % 1000 == 0 or s.stiff_positive > 0:
                # The last stage (ytmp, K[last - 1]) and y_new (K[last]) are both at t + h.
                stnum = 0.0
                stden = 0.0
                for i in range(n):
                    stnum += (K[last, i] - K[last - 1, i]) ** 2
                    stden += (y_new[i] - ytmp[i]) ** 2
                if stden > 0.0:
                    s.h_lambda = h * math.sqrt(stnum / stden)
                    if s.h_lambda > stiff_edge:
                        s.stiff_negative = 0
                        s.stiff_positive += 1
                        stiff = s.stiff_positive >= 15
                    else:
                        s.stiff_negative += 1
                        if s.stiff_negative >= 6:
                            s.stiff_positive = 0
            if err == 0.0:
                factor = 10.0
            else:
                factor = min(10.0, 0.9 * _shrink(err, dopri5))
            if rejected:
                factor = min(1.0, factor)
            rejected = False
            for i in range(n):
                if not math.isfinite(y_new[i]):
                    return Status.NOT_FINITE, k
            y_old[:] = y
            t_new = t + h
            for i in range(n):
                comp[i] = inc[i] - (y_new[i] - y[i])
            if n_c > 0:
                ks.project(t_new, y_new, p)
                rhs(t_new, y_new.ctypes, pp, _row(K, last))
                s.n_evaluations += 1
                comp[:] = 0.0  # the projection moved the state: nothing left to carry
            y[:] = y_new
            s.t_old = t
            s.h_old = h
            s.t = t_new
            s.dense_ready = 0
            s.h = h * factor
            s.error_estimate += err * rtol
            steps += 1
            s.n_steps += 1
            if n_ev > 0:
                g_new = np.empty(n_ev)
                ks.event(t_new, y, p, g_new)
                first = -1
                t_ev = t_new
                for i in range(n_ev):
                    if _crossed(g_old[i], g_new[i], ev_dir[i]):
                        if s.dense_ready == 0:
                            _dense_prepare(ks, pair, s, y, y_old, K, F, p)
                        ti = _locate_event(ks, DENSE_ERK, F, inc, y_old, inc, t, 0.0, h, p,
                                           0.0, no_cost, i, t, g_old[i], t_new, g_new[i])
                        if first < 0 or ti < t_ev:
                            first = i
                            t_ev = ti
                if first >= 0:
                    while k < n_out and t_out[k] < t_ev:
                        _dense_output(ks, pair, s, y, y_old, K, F, p, t_out[k], Y_out[k])
                        k += 1
                    if t_ev < t_new:
                        _dense_output(ks, pair, s, y, y_old, K, F, p, t_ev, y)
                    comp[:] = 0.0
                    s.t = t_ev
                    s.last_event = first
                    s.n_events += 1
                    return Status.EVENT, k
                g_old[:] = g_new
            while k < n_out and t_out[k] <= t_new:
                if t_out[k] == t_new:
                    Y_out[k, :] = y
                else:
                    _dense_output(ks, pair, s, y, y_old, K, F, p, t_out[k], Y_out[k])
                k += 1
            if stiff:
                return Status.STIFF, k
        else:
            s.h = h * max(0.2, 0.9 * _shrink(err, dopri5))
            s.n_rejected += 1
            rejected = True
    return Status.OK, k


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _add_compensated(x, inc, comp, lo, hi):
    """x[lo:hi] += inc[lo:hi] with Kahan compensation carried in comp[lo:hi]."""
    for i in range(lo, hi):
        d = inc[i] + comp[i]
        xn = x[i] + d
        comp[i] = d - (xn - x[i])
        x[i] = xn


@njit(inline="always")
def _composition_step(nq, accel, t, y, p, a, kick, drift, q, d, comp):
    """One step of the composition (see ``composition_advance``); ``nq`` is a constant where
    the caller knows it, so the short loops over coordinates unroll."""
    nw = drift.size
    for i in range(2 * nq):
        d[i] = 0.0
    for j in range(nw):
        c = kick[j]
        w = drift[j]
        for i in range(nq):
            dv = d[nq + i] + c * a[i]
            d[nq + i] = dv
            # dq += w (v₀ + dv), with the part known before the force returned kept off
            # the path from the force to the next position
            partial = d[i] + w * y[nq + i]
            q[i] = (y[i] + partial) + w * dv
            d[i] = partial + w * dv
        accel(t, q, p, a)
    c = kick[nw]
    for i in range(nq):
        d[nq + i] += c * a[i]
    _add_compensated(y, d, comp, 0, 2 * nq)


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def composition_advance(ks, state, y, p, n_out, n_sub, h, weights, Y_out, a, comp):
    """Fixed-step symmetric composition of velocity Verlet for separable systems.
    ``state``: a ``FIXED_STATE`` record; ``a`` holds accel_q(q) on entry and on exit;
    ``comp`` the compensation of y. Writes the state after each block of ``n_sub`` steps to
    Y_out[0..n_out). Returns (status, written).

    Kick-drift-kick stages, each closing half-kick merged into the next opening one: kick
    coefficients (w_s + w_{s+1}) h / 2 inside a step, w h / 2 at its ends. Within a step the
    stages move q and v by increments dq, dv that start at zero (small numbers, added to
    without loss; the force is evaluated at q₀ + dq); the step's total increments are added
    to the state once, compensated."""
    s = state[0]
    nq = ks.n_q
    accel = ks.accel_q
    nw = weights.size
    kick = np.empty(nw + 1)
    drift = np.empty(nw)
    kick[0] = 0.5 * weights[0] * h
    for j in range(1, nw):
        kick[j] = 0.5 * (weights[j - 1] + weights[j]) * h
    kick[nw] = 0.5 * weights[nw - 1] * h
    for j in range(nw):
        drift[j] = weights[j] * h
    q = np.empty(nq)
    d = np.empty(2 * nq)  # [dq, dv]
    for k in range(n_out):
        for _ in range(n_sub):
            if nq == 1:
                _composition_step(1, accel, s.t, y, p, a, kick, drift, q, d, comp)
            elif nq == 2:
                _composition_step(2, accel, s.t, y, p, a, kick, drift, q, d, comp)
            elif nq == 3:
                _composition_step(3, accel, s.t, y, p, a, kick, drift, q, d, comp)
            else:
                _composition_step(nq, accel, s.t, y, p, a, kick, drift, q, d, comp)
            s.t += h
            s.n_steps += 1
        s.n_evaluations += n_sub * nw
        for i in range(2 * nq):
            if not math.isfinite(y[i]):
                return Status.NOT_FINITE, k
        Y_out[k, :] = y
    return Status.OK, n_out


_S15 = math.sqrt(15.0)
_GL_C = np.array([0.5 - _S15 / 10.0, 0.5, 0.5 + _S15 / 10.0])
_GL_A = np.array([[5.0 / 36.0, 2.0 / 9.0 - _S15 / 15.0, 5.0 / 36.0 - _S15 / 30.0],
                  [5.0 / 36.0 + _S15 / 24.0, 2.0 / 9.0, 5.0 / 36.0 - _S15 / 24.0],
                  [5.0 / 36.0 + _S15 / 30.0, 2.0 / 9.0 + _S15 / 15.0, 5.0 / 36.0]])
_GL_B = np.array([5.0 / 18.0, 4.0 / 9.0, 5.0 / 18.0])


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def gauss_advance(ks, state, z, p, n_out, n_sub, h, Y_out, K, comp):
    """Three-stage Gauss–Legendre collocation (order 6, symplectic) on the canonical
    variables z = [q, p, work terms] of a conservative system, fixed step ``h``, stage
    equations solved by fixed-point iteration started from the last step's stages (``K``,
    shape (3, N_Y), kept between calls), z updated with compensation ``comp``. Writes
    y = [q, q̇, ...] after each block of ``n_sub`` steps. Returns (status, written)."""
    s = state[0]
    f = ks.canonical_rhs
    zs = np.empty(z.size)
    pp = p.ctypes
    zp = zs.ctypes
    n = z.size
    inc = np.empty(n)
    Knew = np.empty((3, n))
    for k in range(n_out):
        for _ in range(n_sub):
            t = s.t
            converged = False
            previous = math.inf
            for _it in range(60):
                for i in range(3):
                    for m in range(n):
                        acc = 0.0
                        for j in range(3):
                            acc += _GL_A[i, j] * K[j, m]
                        zs[m] = z[m] + h * acc
                    f(t + _GL_C[i] * h, zp, pp, _row(Knew, i))
                change = 0.0
                size = 0.0
                finite = True
                for i in range(3):
                    for m in range(n):
                        if not math.isfinite(Knew[i, m]):
                            finite = False
                        change = max(change, abs(Knew[i, m] - K[i, m]))
                        size = max(size, abs(Knew[i, m]))
                        K[i, m] = Knew[i, m]
                s.n_evaluations += 3
                if not finite:
                    break  # the iteration diverged: not converged
                delta = change / (size + 1e-300)
                # Converged at round-off, or stagnating there (no further decrease).
                if delta <= 4e-16 or (delta >= previous and delta < 1e-12):
                    converged = True
                    break
                previous = delta
            if not converged:
                return Status.NOT_CONVERGED, k
            for m in range(n):
                inc[m] = h * (_GL_B[0] * K[0, m] + _GL_B[1] * K[1, m] + _GL_B[2] * K[2, m])
            _add_compensated(z, inc, comp, 0, n)
            s.t = t + h
            s.n_steps += 1
        for m in range(n):
            if not math.isfinite(z[m]):
                return Status.NOT_FINITE, k
        ks.from_momenta(s.t, z, p, Y_out[k])
    return Status.OK, n_out


# --- Gauss–Radau (IAS15 scheme) ------------------------------------------------------------
# The 8 nodes of Gauss–Radau quadrature on [0, 1] with the left end fixed: 0 and the roots of
# P₇(2s − 1) + P₈(2s − 1) (Legendre polynomials), the spacings of IAS15 (Rein & Spiegel 2015,
# MNRAS 446, 1424, §2). Computed to 30 digits; ``tests/test_radau15.py`` checks them.
_RADAU_NODES = np.array([
    0.0, 0.0562625605369221464656521910323, 0.180240691736892364987579942809,
    0.352624717113169637373907770171, 0.547153626330555383001448557652,
    0.734210177215410531523210608307, 0.885320946839095768090359762932,
    0.977520613561287501891174500429])


def _newton_to_monomial(nodes):
    """c[j, k]: s Π_{m=1…j} (s − h_m) = Σ_k c[j, k] s^(k+1), j = 0 … 6."""
    c = np.zeros((7, 7))
    poly = np.array([1.0])  # Π (s − h_m), lowest power first
    for j in range(7):
        if j > 0:
            poly = np.convolve(poly, np.array([-nodes[j], 1.0]))
        c[j, : poly.size] = poly
    return c


_RADAU_C = _newton_to_monomial(_RADAU_NODES)
# b = Cᵀ g and back: g = (Cᵀ)⁻¹ b (both triangular).
_RADAU_D = np.ascontiguousarray(np.linalg.inv(_RADAU_C.T))
# Factors of the single and double integrals of s^(k+1): 1/(k+2) and 1/((k+2)(k+3)).
# (One more for the dense output's expansion, of degree 8.)
_RADAU_V = np.array([1.0 / (k + 2) for k in range(8)])
_RADAU_X = np.array([1.0 / ((k + 2) * (k + 3)) for k in range(8)])
# Binomial coefficients C(j+1, k+1) for moving the expansion to the next step.
_RADAU_SHIFT = np.array([[math.comb(j + 1, k + 1) for k in range(7)] for j in range(7)],
                        dtype=np.float64)
# A step that would end short of the last requested time by less than this fraction of its
# length is stretched to land on it: otherwise the next step is the remainder, a few ulps
# when the planned step ends a few ulps before that time, and the run stops with a step-size
# underflow.
_LANDING_STRETCH = 0.01
# Predictor–corrector iterations of a step at most. A step whose iteration needed more than
# _RADAU_SLOW of them and contracted by a factor ρ per iteration (measured while the change
# is above _RADAU_RHO_FLOOR, clear of round-off) is followed by one at most
# _RADAU_CONTRACTION / ρ times as long: ρ grows with the step where the forces depend on the
# velocities (gyroscopic terms: the quaternion rigid body). Before this limit, the steps there
# ran out of 12 iterations, were redone four times shorter, and grew back into the same
# failure: a rejection per step, ~20 iterations each; measured on the rigid body and the
# heavy top, 0.25 … 0.6 with 30 … 40 iterations all give about a third of the evaluations.
_RADAU_MAX_ITERATIONS = 30
_RADAU_CONTRACTION = 0.4
_RADAU_RHO_FLOOR = 1e-10
_RADAU_SLOW = 6
# The iteration is settled when what it still owes to the state at the end of the step is
# below this fraction of the state's scale: a 64th of the unit round-off. What is left is of
# one sign along an orbit, so it adds up like N, not like the √N of round-off: owing up to
# the unit round-off took the pendulum's energy error over 10⁴ periods (3·10⁵ steps) to
# 5e-13, where the fully converged iteration (IAS15's test alone) ends at 3e-14 … 9e-14; a
# 64th ends there too (6e-14), with a third fewer evaluations than the full convergence.
_RADAU_ROUND_OFF = 2.0**-59
# Once the iteration stagnates, a change within this fraction of the state's scale settles
# it (a few units of round-off): a work term whose rate is round-off of cancelling terms
# changes by that much from one iteration to the next, however long the iteration goes on.
_RADAU_NOISE = 4.0 * 2.0**-53


def _defect_factors(nodes):
    """max over s in [0, 1] of |∫₀ˢ ω| and |∫₀ˢ∫₀ᵘ ω|, divided by |ω(1)|, ω(s) = Π (s − h_i)
    over the eight nodes (see ``_radau_interpolant_error``)."""
    w = np.poly1d(np.poly(nodes))
    w1 = np.polyint(w)
    w2 = np.polyint(w1)
    s = np.linspace(0.0, 1.0, 20001)
    return (float(np.max(np.abs(w1(s)))) / abs(w(1.0)),
            float(np.max(np.abs(w2(s)))) / abs(w(1.0)))


_RADAU_DEFECT_V, _RADAU_DEFECT_X = _defect_factors(_RADAU_NODES)
# ω(s)/ω(1) = Σ_k _RADAU_OMEGA[k] s^(k+1), k = 0 … 7 (ω(0) = 0: the first node is 0).
_RADAU_OMEGA = np.ascontiguousarray(
    np.poly(_RADAU_NODES)[::-1][1:] / np.prod(1.0 - _RADAU_NODES))


def _newton_factors(nodes):
    """max over s in [0, 1] of |∫₀ˢ w_k| and |∫₀ˢ∫₀ᵘ w_k| for the Newton basis
    w_k(s) = s Π_{m=1…k} (s − h_m) of the divided differences g_k, k = 0 … 6."""
    s = np.linspace(0.0, 1.0, 20001)
    v = np.empty(7)
    x = np.empty(7)
    for k in range(7):
        w = np.poly1d([1.0, 0.0])
        for j in range(1, k + 1):
            w = w * np.poly1d([1.0, -nodes[j]])
        w1 = np.polyint(w)
        v[k] = np.max(np.abs(w1(s)))
        x[k] = np.max(np.abs(np.polyint(w1)(s)))
    return v, x


_RADAU_NEWTON_V, _RADAU_NEWTON_X = _newton_factors(_RADAU_NODES)
# Σ_k C[j, k] V_k and Σ_k C[j, k] X_k: a change of g_j moves the step's end by that (times
# dt, dt²) in v and q.
_RADAU_CV = np.ascontiguousarray(_RADAU_C @ _RADAU_V[:7])
_RADAU_CX = np.ascontiguousarray(_RADAU_C @ _RADAU_X[:7])
# An output inside a step comes from the step's (corrected) expansion when the estimate of
# the error of its own expansion is within this share of the tolerance, else from a side step
# of its own. The corrected expansion is off by at most that error plus the correction, each
# about the estimate. Measured against side steps (the state landing there would give), the
# corrected expansion's error over a run stayed within 2.1 × the largest estimate (Kepler,
# double and spherical pendulum, CR3BP, bead on wire, rigid body, symmetric top; tolerances
# 1e-3 … 1e-10), mostly far below it. A thousandth (as DOP853's local tolerance): outputs
# then stay near the integration's own error, not just within the tolerance — a twentieth
# let the pendulum's sampled energy error over 10⁴ periods at the default 1e-10 reach
# 2e-12 where the steps' own is 1e-13; this costs side steps for 1 % of the double
# pendulum's 100 Hz outputs, 7 % of the bead on a wire's.
_RADAU_DENSE_SHARE = 0.001
# ... or within this much of the state scale (64 units of round-off, what a run's own
# round-off soon exceeds), up to half the tolerance: at tolerances near round-off a thousandth
# would have side steps take nearly every output.
_RADAU_DENSE_FLOOR = 2.0**-47
# ... and what the iteration still owes inside the step within this share of the tolerance.
_RADAU_INSIDE_SHARE = 1e-4


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_state_at(s, n, y0, F0, b, dt, comp, ys):
    """y at t₀ + s·dt from the expansion F(s) = F₀ + Σ_k b_k s^(k+1) (7 rows) of the second
    derivatives of q and the first derivatives of the work terms (compensation of y₀
    included)."""
    m = F0.size
    for j in range(m):
        iv = 0.0
        ix = 0.0
        for k in range(6, -1, -1):
            iv = iv * s + b[k, j] * _RADAU_V[k]
            ix = ix * s + b[k, j] * _RADAU_X[k]
        # first integral (v or W): y[n + j]; second (q) only for the accelerations
        ys[n + j] = y0[n + j] + (comp[n + j] + s * dt * (F0[j] + s * iv))
        if j < n:
            ys[j] = y0[j] + (comp[j] + s * dt * (y0[n + j] + s * dt * (0.5 * F0[j] + s * ix)))


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_dense_at(s, n, y0, F0, b8, dt, comp, ys):
    """``_radau_state_at`` for the dense output's expansion (8 rows,
    ``_radau_dense_expansion``): its first 7 rows as the step's own, plus the eighth row's
    term b₇ s⁸, integrated (kept apart: the step's 7-row loop, with its bound a constant, is
    the iteration's hot path)."""
    _radau_state_at(s, n, y0, F0, b8[:7], dt, comp, ys)
    s9 = s**9
    for j in range(F0.size):
        ys[n + j] += dt * s9 * b8[7, j] * _RADAU_V[7]
        if j < n:
            ys[j] += dt * dt * s9 * s * b8[7, j] * _RADAU_X[7]


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_g_from_b(b, g):
    """The divided differences g of the expansion b (g = (Cᵀ)⁻¹ b, upper triangular)."""
    m = b.shape[1]
    for j in range(m):
        for k in range(7):
            acc = 0.0
            for i in range(k, 7):
                acc += _RADAU_D[k, i] * b[i, j]
            g[k, j] = acc


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_predict(b, g, e, q):
    """Move the expansion of the step just taken to the next one, of q times its length:
    F(1 + q s') − F(1) = Σ_k q^(k+1) Σ_{i≥k} C(i+1, k+1) b_i s'^(k+1), plus the correction the
    corrector made to the last prediction (``e``, which becomes the new prediction): the
    start of the next predictor–corrector iteration (as in IAS15, Rein & Spiegel 2015)."""
    m = b.shape[1]
    for j in range(m):
        for k in range(7):
            acc = 0.0
            for i in range(k, 7):
                acc += _RADAU_SHIFT[i, k] * b[i, j]
            g[k, j] = acc  # scratch: the shifted coefficients
        qk = q
        for k in range(7):
            shifted = g[k, j] * qk
            b[k, j] = shifted + (b[k, j] - e[k, j])
            e[k, j] = shifted
            qk *= q
    _radau_g_from_b(b, g)


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_rescale(b, g, e, q):
    """The expansion for a step q times as long (b_k q^(k+1)), which becomes the prediction
    ``e`` too."""
    m = b.shape[1]
    qk = q
    for kk in range(7):
        for j in range(m):
            b[kk, j] *= qk
            e[kk, j] = b[kk, j]
        qk *= q
    _radau_g_from_b(b, g)


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _kahan(x, comp, i, inc):
    """x[i] += inc, with the low-order bits lost kept in comp[i] and added next time."""
    d = inc + comp[i]
    xn = x[i] + d
    comp[i] = d - (xn - x[i])
    x[i] = xn


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _settled(change, last, theta_b6, bound, noise):
    """Whether a linearly converging iteration whose last two changes were ``last`` and
    ``change`` still owes at most ``bound``: with θ the larger of change / last and
    ``theta_b6`` (the contraction of b₆, the slowest to settle: the ratio of the first two
    changes alone undercounts what is left once the fast parts have died out, measured on
    Kepler at 25 steps an orbit), θ < 0.5 and θ/(1 − θ) · change ≤ bound (the rest of a
    geometric series); or, where the iteration stagnates (``noise``: from the third iteration
    on, b₆ no longer falling; at round-off the changes are noise and θ means nothing), a
    change within the bound or ``_RADAU_NOISE``."""
    if change == 0.0 or (noise and change <= max(bound, _RADAU_NOISE)):
        return True
    if not last > 0.0:
        return False
    theta = max(change / last, theta_b6)
    return theta < 0.5 and theta / (1.0 - theta) * change <= bound


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_iterate(ks, t0, y, comp, F0, b, g, dt, p, w_floor, inside_tol, cost, ys, dy, dg):
    """Predictor–corrector iteration of the step of length dt from (t0, y): the expansion
    ``b`` (with its divided differences ``g``) is corrected in place until it is settled.
    Returns (converged, iterations, contraction ρ of b₆ measured above round-off); ``dy`` ends
    as f at the last node; ``ys`` and ``dg`` (7, N_Q + 2) are scratch; ``cost`` counts
    evaluations and iterations.

    Settled (``_settled``, from the second iteration on, the contraction θ measured on the
    last two changes and on b₆): what the iteration still owes to the state at the step's
    end, which the run carries on from, is below ``_RADAU_ROUND_OFF`` of the state's scale (the
    largest |q| and |q̇|, or their changes over the step where those are larger; each work
    term's size, at least ``w_floor``, the system's energy scale: their rates may be
    round-off of cancelling terms); and what it owes anywhere inside the step (bounded on the
    Newton basis of g: Σ_k |Δg_k| max|∫ w_k| dt for v and the work terms,
    Σ_k |Δg_k| max|∫∫ w_k| dt² for q) is within ``inside_tol`` relative (what outputs inside
    the step read; ``inf`` where only the end is used). Also converged: the change of b₆ at
    round-off relative to the accelerations (IAS15's test, on the accelerations only), or,
    after three iterations, that change no longer falling (stagnating at round-off:
    converged if below 1e-13)."""
    n = ks.n_q
    m = n + 2
    ny = y.size
    yp = ys.ctypes
    dyp = dy.ctypes
    pp = p.ctypes
    inside_wanted = inside_tol < math.inf
    previous = math.inf
    converged = False
    rho = 0.0
    iterations = 0
    last_end = 0.0
    last_inside = 0.0
    # the state's scale: the largest |q| and |q̇| (or their changes over the step)
    scale_q = 0.0
    scale_v = 0.0
    for j in range(n):
        scale_q = max(scale_q, abs(y[j]), dt * abs(y[n + j]))
        scale_v = max(scale_v, abs(y[n + j]), dt * abs(F0[j]))
    for it in range(_RADAU_MAX_ITERATIONS):
        for i in range(ny):
            ys[i] = y[i]
        for node in range(1, 8):
            h = _RADAU_NODES[node]
            _radau_state_at(h, n, y, F0, b, dt, comp, ys)
            ks.rhs(t0 + h * dt, yp, pp, dyp)
            for j in range(m):
                r = (dy[n + j] - F0[j]) / h
                for jj in range(1, node):
                    r = (r - g[jj - 1, j]) / (h - _RADAU_NODES[jj])
                delta = r - g[node - 1, j]
                g[node - 1, j] = r
                dg[node - 1, j] = delta  # this iteration's change of g (b = Cᵀ g)
                for kk in range(node):
                    b[kk, j] += _RADAU_C[node - 1, kk] * delta
        cost[0] += 7
        cost[1] += 1
        # b₆ of the accelerations (the work rates do not act back on the motion: theirs
        # settles with it, and may be round-off of cancelling terms amplified)
        change = 0.0
        scale = 0.0
        for j in range(n):
            change = max(change, abs(_RADAU_C[6, 6] * dg[6, j]))
            scale = max(scale, abs(dy[n + j]))
        pc = change / scale if scale > 0.0 else 0.0
        if _RADAU_RHO_FLOOR < previous < math.inf:
            rho = max(rho, pc / previous)
        iterations = it + 1
        # this iteration's change of the state, relative to the state's scale
        end = 0.0
        inside = 0.0
        for j in range(m):
            ev = 0.0
            ex = 0.0
            iv = 0.0
            ix = 0.0
            for kk in range(7):
                d = dg[kk, j]
                ev += d * _RADAU_CV[kk]
                ex += d * _RADAU_CX[kk]
                if inside_wanted:
                    iv += abs(d) * _RADAU_NEWTON_V[kk]
                    ix += abs(d) * _RADAU_NEWTON_X[kk]
            sv = scale_v if j < n else max(abs(y[n + j]), dt * abs(F0[j]), w_floor)
            if ev != 0.0:
                end = max(end, dt * abs(ev) / sv if sv > 0.0 else math.inf)
            if iv > 0.0:
                inside = max(inside, dt * iv / sv if sv > 0.0 else math.inf)
            if j < n and ex != 0.0:
                end = max(end, dt * dt * abs(ex) / scale_q if scale_q > 0.0 else math.inf)
            if j < n and ix > 0.0:
                inside = max(inside, dt * dt * ix / scale_q if scale_q > 0.0 else math.inf)
        theta_b6 = pc / previous if previous > 0.0 else 1.0
        noise = it >= 2 and pc >= previous  # stagnating: the changes are noise
        settled = (it >= 1 and _settled(end, last_end, theta_b6, _RADAU_ROUND_OFF, noise)
                   and _settled(inside, last_inside, theta_b6, inside_tol, noise))
        last_end = end
        last_inside = inside
        if settled or pc < 1e-16 or (it >= 2 and pc >= previous):
            converged = settled or pc < 1e-13  # settled, at round-off, or stagnating there
            break
        previous = pc
    return converged, iterations, rho


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_increments(n, y, F0, b, dt, inc):
    """Increments of q, v and the work terms over the whole step (Gauss–Radau quadrature of
    the expansion: exact for it, the step's 15th-order end point)."""
    for j in range(n + 2):
        iv = 0.0
        ix = 0.0
        for kk in range(6, -1, -1):
            iv = iv + b[kk, j] * _RADAU_V[kk]
            ix = ix + b[kk, j] * _RADAU_X[kk]
        inc[n + j] = dt * (F0[j] + iv)
        if j < n:
            inc[j] = dt * (y[n + j] + dt * (0.5 * F0[j] + ix))


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_side_step(ks, t0, y0, comp0, F0, b, dt, frac, p, w_floor, cost, out):
    """The state at t₀ + frac·dt by a Gauss–Radau step of its own from the start (t0, y0,
    comp0, F0) of the step just taken, with that step's expansion ``b`` restricted to
    [0, frac] as the prediction (b_k frac^(k+1)): the state landing there would have given,
    without changing the run. Returns whether its iteration converged."""
    n = ks.n_q
    m = n + 2
    bs = np.empty((7, m))
    gs = np.empty((7, m))
    fk = frac
    for kk in range(7):
        for j in range(m):
            bs[kk, j] = b[kk, j] * fk
        fk *= frac
    _radau_g_from_b(bs, gs)
    cost[2] += 1
    inc = np.empty(y0.size)
    dy = np.empty(y0.size)
    converged, _, _ = _radau_iterate(ks, t0, y0, comp0, F0, bs, gs, frac * dt, p, w_floor,
                                     math.inf, cost, inc, dy, np.empty((7, m)))
    _radau_increments(n, y0, F0, bs, frac * dt, inc)
    c = comp0.copy()
    out[:] = y0
    for i in range(2 * n + 2):
        _kahan(out, c, i, inc[i])
    return converged


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_dense_expansion(F0, b, F1, b8):
    """The expansion the outputs inside the step read (8 rows, degree 8 in s): the step's,
    through F at its eight nodes, plus (F1 − F(1)) ω(s)/ω(1), which also goes through F1,
    f at the step's end — the leading term of the defect ``_radau_interpolant_error``
    estimates, taken out (the correction is at most that estimate, and vanishes at both
    ends of the step in q and v)."""
    m = F0.size
    for j in range(m):
        end = F0[j]
        for kk in range(7):
            end += b[kk, j]
        c = F1[j] - end
        for kk in range(7):
            b8[kk, j] = b[kk, j] + c * _RADAU_OMEGA[kk]
        b8[7, j] = c * _RADAU_OMEGA[7]


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_derivatives(s_, rhs, t, y, inc, pp, dy, n, out):
    """``out`` ← the second derivatives of q and the work rates at (t, y) (one evaluation,
    counted; ``inc`` and ``dy`` are scratch)."""
    for i in range(y.size):
        inc[i] = y[i]
    rhs(t, inc.ctypes, pp, dy.ctypes)
    s_.n_evaluations += 1
    for j in range(out.size):
        out[j] = dy[n + j]


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_interpolant_error(n, y0, y1, F0, b, F1, dt, w_floor):
    """Bound of the error of the step's expansion between its ends, relative to the state
    scale (the larger of max|q|, max|q̇| at both ends; for each work term its size there, at
    least ``w_floor``, the system's energy scale).

    The collocation polynomial's defect d(s) = F(s) − f(t, y(s)) vanishes at the eight
    nodes and, to leading order, is d(1) ω(s)/ω(1) with ω(s) = Π (s − h_i); d(1) is free:
    F1, f at the step's end (the next step's F₀), minus the expansion there. The error of
    the state it integrates is then dt ∫₀ˢ d for v and the work terms and dt² ∫₀ˢ∫₀ᵘ d for
    q, at most ``_RADAU_DEFECT_V`` dt |d(1)| and ``_RADAU_DEFECT_X`` dt² |d(1)| (both
    integrals vanish at s = 1: the quadrature's exactness, the end point is of order 15)."""
    sq = 0.0
    sv = 0.0
    for j in range(n):
        sq = max(sq, abs(y0[j]), abs(y1[j]))
        sv = max(sv, abs(y0[n + j]), abs(y1[n + j]))
    worst = 0.0
    for j in range(n + 2):
        end = F0[j]
        for kk in range(7):
            end += b[kk, j]
        d = abs(F1[j] - end)
        if d == 0.0:
            continue
        ev = _RADAU_DEFECT_V * dt * d
        if j < n:
            worst = max(worst, _RADAU_DEFECT_X * dt * dt * d / sq, ev / sv)
        else:
            worst = max(worst, ev / max(abs(y0[n + j]), abs(y1[n + j]), w_floor))
    return worst


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def radau15_advance(ks, state, y, p, t_out, Y_out, eps, max_steps, comp, b, g, e, F0, dy,
                    g_old, ev_dir, a_floor, w_floor, dense_tol):
    """Adaptive 15th-order Gauss–Radau predictor–corrector on q̈ = f(t, q, q̇) (the scheme of
    IAS15, Rein & Spiegel 2015, with velocity-dependent forces and the work terms integrated
    alongside as first-order components): within a step the second derivatives are a degree-7
    polynomial in s = (t − t₀)/dt, F(s) = F₀ + Σ_k b_k s^(k+1), collocated at the 7 non-zero
    Gauss–Radau nodes and corrected by fixed-point iteration until settled at round-off
    (``_radau_iterate``); the step adapts so that max|b₆| / max|q̈| stays at ``eps``
    (dt_new = dt (eps / ε_b)^(1/7), a step whose proposal shrinks below a quarter is redone;
    so is one whose iteration does not converge), and so that the iteration converges fast
    enough (see ``_RADAU_CONTRACTION``). Near an equilibrium q̈ is round-off and so
    is b₆: the acceleration scale is floored at ``a_floor`` (the stepper's: the model's own
    scale at the start of the run), so that noise does not drive the step to zero; the work
    terms are judged against ``w_floor`` (the system's energy scale at the start of the run).
    The state and the time are updated with compensated summation.

    Dense output: the steps keep their natural length and land only on the last requested
    time (or are stretched by up to ``_LANDING_STRETCH`` of their length to reach it); an
    output inside a step is the step's expansion (through f at its end as well:
    ``_radau_dense_expansion``) integrated to it, when the estimate of the error of the
    step's own expansion (``_radau_interpolant_error``; the correction is at most that) is
    within ``_RADAU_DENSE_SHARE`` × ``dense_tol`` (or ``_RADAU_DENSE_FLOOR``, up to half of
    ``dense_tol``; relative to the state scale), and
    otherwise a side step of its own from the step's start (``_radau_side_step``), as landing
    would give (``n_side`` counts them; ``dense_error`` keeps the largest estimate seen); a
    side step that does not converge has the step redone, landing on its output. The step's
    end is committed once its outputs are written. f at the end of a step is the next step's
    F₀ (``f0_ready``).
    ``b``, ``g`` (7, N_Q + 2) hold the expansion between calls and ``e`` its prediction,
    ``F0`` f at the current state when ``f0_ready``, ``dy`` scratch. Events as in
    ``dop853_advance``, located on the step's expansion (or on side steps where its bound
    fails; ``g_old``: event functions at the current state, ``ev_dir`` their directions); on
    EVENT the state is at the event, outputs before it written. Returns (status, outputs
    written)."""
    s_ = state[0]
    n = ks.n_q
    m = n + 2  # accelerations and the two work rates
    ny = y.size
    rhs = ks.rhs
    pp = p.ctypes
    inc = np.empty(ny)
    b_start = np.empty((7, m))
    F1 = np.empty(m)
    n_ev = ks.n_ev
    y_new = np.empty(ny)
    comp_new = np.empty(ny)
    b8 = np.empty((8, m))
    dg = np.empty((7, m))
    g_new = np.empty(max(n_ev, 1))
    cost = np.zeros(3, dtype=np.int64)  # evaluations, iterations, side steps
    # what the outputs inside a step may be off by
    dense_limit = max(_RADAU_DENSE_SHARE * dense_tol, min(0.5 * dense_tol, _RADAU_DENSE_FLOOR))
    # what outputs inside a step read of its iteration (nothing when they all take side
    # steps; never better than round-off)
    dense_inside = (max(_RADAU_INSIDE_SHARE * dense_tol, _RADAU_ROUND_OFF) if dense_tol > 0.0
                    else math.inf)
    n_out = t_out.size
    k = 0
    steps = 0
    # outputs at the current time, or a few ulps after it, closer than a step can go (an
    # event located that close before the output time the step landed on)
    near = 10.0 * abs(np.nextafter(s_.t, np.inf) - s_.t)
    while k < n_out and t_out[k] - s_.t <= near:
        Y_out[k, :] = y
        k += 1
    t_last = t_out[n_out - 1] if n_out > 0 else s_.t
    t_target = t_last  # the time to land on (an earlier output where a side step failed)
    while k < n_out:
        if steps >= max_steps:
            return Status.MAX_STEPS, k
        t0 = s_.t
        tc0 = s_.t_comp
        dt = s_.h
        landing = False
        if t0 + dt * (1.0 + _LANDING_STRETCH) >= t_target:
            # from the compensated time t₀ + t_comp (t_target − t₀ is exact once t₀ ≥
            # t_target/2, Sterbenz): the state is integrated over exactly the span the clock
            # advances, leaving no time shift at a landing
            dt = (t_target - t0) - tc0
            landing = True
            _radau_rescale(b, g, e, dt / s_.h)  # the prediction, for this step's length
        if dt <= 10.0 * abs(np.nextafter(t0, np.inf) - t0):
            return Status.STEP_UNDERFLOW, k
        if s_.f0_ready == 0:  # F₀ at the start of the step
            _radau_derivatives(s_, rhs, t0, y, inc, pp, dy, n, F0)
            s_.f0_ready = 1
        b_start[:, :] = b
        dt_first = dt  # the step b_start predicts
        while True:
            cost[:] = 0
            # the inside of the step matters only where an output falls in it
            inside_tol = dense_inside if t_out[k] - t0 < dt else math.inf
            converged, iterations, rho = _radau_iterate(ks, t0, y, comp, F0, b, g, dt, p,
                                                        w_floor, inside_tol, cost, inc, dy, dg)
            s_.n_evaluations += cost[0]
            s_.n_iterations += cost[1]
            for j in range(m):
                if not math.isfinite(b[6, j]):
                    return Status.NOT_FINITE, k
            # step size control on the accelerations' last coefficient (the work rates do
            # not act back on the motion, and may be round-off around zero)
            big_b6 = 0.0
            big_a = a_floor
            for j in range(n):
                big_b6 = max(big_b6, abs(b[6, j]))
                big_a = max(big_a, abs(dy[n + j]))
            err = big_b6 / big_a if big_a > 0.0 else 0.0
            if err > 0.0:
                dt_new = dt * (eps / err) ** (1.0 / 7.0)
            else:
                dt_new = 4.0 * dt
            if not converged:
                dt_new = min(dt_new, 0.25 * dt)
            if dt_new < 0.25 * dt or not converged:
                # rejected: the prediction the step started from, for the shorter step
                s_.n_rejected += 1
                b[:, :] = b_start
                _radau_rescale(b, g, e, dt_new / dt_first)
                dt = dt_new
                landing = False
                continue
            break
        # the step's end, not committed yet (a side step to an output inside the step that
        # does not converge has the step redone, landing on that output)
        _radau_increments(n, y, F0, b, dt, inc)
        y_new[:] = y
        comp_new[:] = comp
        local = 0.0
        scale = 1.0
        for j in range(n):
            local = max(local, abs(b[6, j]) * _RADAU_X[6] * dt * dt)
        for i in range(2 * n + 2):
            _kahan(y_new, comp_new, i, inc[i])
        for i in range(2 * n):
            if not math.isfinite(y_new[i]):
                return Status.NOT_FINITE, k
            scale = max(scale, abs(y_new[i]))
        # the time, compensated too (or exactly the output time landed on)
        if landing:
            t_new = t_target
            tc_new = 0.0
        else:
            dtc = dt + tc0
            t_new = t0 + dtc
            tc_new = dtc - (t_new - t0)
        # f at the end: the defect that estimates the expansion's error (on the expansion's
        # own end, before the projection moves it), and the next step's F₀
        _radau_derivatives(s_, rhs, t_new, y_new, inc, pp, dy, n, F1)
        bound = _radau_interpolant_error(n, y, y_new, F0, b, F1, dt, w_floor)
        _radau_dense_expansion(F0, b, F1, b8)
        if ks.n_c > 0:
            ks.project(t_new, y_new, p)
            comp_new[:] = 0.0
            _radau_derivatives(s_, rhs, t_new, y_new, inc, pp, dy, n, F1)
        s_.dense_error = max(s_.dense_error, bound)
        mode = DENSE_RADAU if bound <= dense_limit else DENSE_RADAU_STEP
        cost[:] = 0
        redo = -1
        if n_ev > 0:
            ks.event(t_new, y_new, p, g_new)
            first = -1
            t_ev = t_new
            for i in range(n_ev):
                if _crossed(g_old[i], g_new[i], ev_dir[i]):
                    ti = _locate_event(ks, mode, b8, F0, y, comp, t0, tc0, dt, p, w_floor,
                                       cost, i, t0, g_old[i], t_new, g_new[i])
                    if math.isnan(ti):  # a side step of the search did not converge
                        return Status.NOT_CONVERGED, k
                    if first < 0 or ti < t_ev:
                        first = i
                        t_ev = ti
            if first >= 0:
                k2 = _radau_outputs(ks, mode, t_out, Y_out, k, t_ev, y_new, False, b8, F0, y,
                                    comp, t0, tc0, dt, p, w_floor, cost)
                if k2 >= 0:
                    k = k2
                    if t_ev < t_new:
                        if not _state_in_step(ks, mode, t_ev, b8, F0, y, comp, t0, tc0, dt, p,
                                              w_floor, cost, y_new):
                            return Status.NOT_CONVERGED, k
                        if ks.n_c > 0:
                            ks.project(t_ev, y_new, p)
                    s_.n_evaluations += cost[0]
                    s_.n_iterations += cost[1]
                    s_.n_side += cost[2]
                    y[:] = y_new
                    comp[:] = 0.0
                    s_.t = t_ev
                    s_.t_comp = 0.0
                    s_.f0_ready = 0
                    s_.n_steps += 1
                    s_.last_event = first
                    s_.n_events += 1
                    return Status.EVENT, k
                redo = -k2 - 1
        if redo < 0:
            k2 = _radau_outputs(ks, mode, t_out, Y_out, k, t_new, y_new, True, b8, F0, y, comp,
                                t0, tc0, dt, p, w_floor, cost)
            if k2 >= 0:
                k = k2
            else:
                redo = -k2 - 1
        s_.n_evaluations += cost[0]
        s_.n_iterations += cost[1]
        s_.n_side += cost[2]
        if redo >= 0:
            # outputs before t_out[redo] are written; the step is redone, landing there
            k = redo
            t_target = t_out[redo]
            s_.n_rejected += 1
            b[:, :] = b_start
            _radau_rescale(b, g, e, s_.h / dt_first)
            continue
        t_target = t_last
        y[:] = y_new
        comp[:] = comp_new
        s_.t = t_new
        s_.t_comp = tc_new
        if n_ev > 0:
            g_old[:] = g_new
        for j in range(m):
            F0[j] = F1[j]
        s_.f0_ready = 1
        s_.error_estimate += local / scale
        steps += 1
        s_.n_steps += 1
        s_.h_old = dt
        planned = s_.h
        dt_new = min(dt_new, 4.0 * dt)
        if iterations > _RADAU_SLOW and rho > _RADAU_CONTRACTION:
            # the iteration converged slowly (forces depending strongly on velocities, or
            # stiff ones): a longer step would not converge within the iteration budget
            dt_new = min(dt_new, dt * _RADAU_CONTRACTION / rho)
        if landing:  # a step shortened to land keeps the controller's plan
            dt_new = max(dt_new, planned)
        q = dt_new / dt
        if q <= 4.0:
            _radau_predict(b, g, e, q)
        else:  # too far to extrapolate: start the corrector from F = F₀
            b[:, :] = 0.0
            g[:, :] = 0.0
            e[:, :] = 0.0
        s_.h = dt_new
    return Status.OK, k


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_outputs(ks, mode, t_out, Y_out, k, t_end, y_end, inclusive, b, F0, y0, comp0, t0,
                   tc, dt, p, w_floor, cost):
    """Write the outputs from index k on that fall before t_end (and at t_end when
    ``inclusive``: the state ``y_end``) inside the step that started at (t0, y0), from its
    expansion (``mode`` DENSE_RADAU) or from side steps, projected onto the constraints.
    Returns the next index, or −(index + 1) where a side step did not converge."""
    n_out = t_out.size
    while k < n_out and (t_out[k] < t_end or (inclusive and t_out[k] == t_end)):
        t = t_out[k]
        if t == t_end:
            Y_out[k, :] = y_end
        else:
            if not _state_in_step(ks, mode, t, b, F0, y0, comp0, t0, tc, dt, p, w_floor, cost,
                                  Y_out[k]):
                return -(k + 1)
            if ks.n_c > 0:
                ks.project(t, Y_out[k], p)
        k += 1
    return k


@njit(cache=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def evaluate_outputs(ks, ts, Y, p, want_energy, want_inv, want_obs, want_frames,
                     E_out, I_out, O_out, F_out):
    """Energy terms, invariants, observables and frames at each sample, only those wanted."""
    for k in range(ts.size):
        if want_energy:
            ks.energy(ts[k], Y[k], p, E_out[k])
        if want_inv and ks.n_inv > 0:
            ks.invariants(ts[k], Y[k], p, I_out[k])
        if want_obs and ks.n_obs > 0:
            ks.observables(ts[k], Y[k], p, O_out[k])
        if want_frames and ks.n_frames > 0:
            ks.frames(ts[k], Y[k], p, F_out[k])
