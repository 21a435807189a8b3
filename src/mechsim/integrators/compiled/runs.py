"""Whole runs in one compiled call: a run of one model (``erk_run``, ``radau15_run``: the
start, the steps and the outputs of ``mechsim.simulate`` without a Python stepper in between)
and runs of many members at once, in parallel over the cores (``erk_many``, ``radau15_many``,
``outputs_many``: ``mechsim.simulate_many``).

Each does exactly what the steppers do, in the same order and with the same arithmetic, so
that its rows equal theirs bit for bit: the explicit pairs start (``erk_restart``) inside
their loop as a stepper's first ``advance`` does; radau15 starts with ``radau15_restart``,
the compiled form of ``Radau15._restart``. A member of an ensemble is a slice of each stacked
array (its state record, state, stages, parameters, output times and rows), advanced by the
same loop a stepper calls; a member that stops at an event returns to Python (its stepper's
event handling, on views of these arrays), which sets its ``restart`` flag, and the call goes
on for those members alone.

The ensembles' members are independent (``prange``): their rows do not depend on the number
of threads or on numba's threading layer.
"""

import math

import numpy as np
from numba import carray, njit, prange

from mechsim.integrators.compiled.common import _item, _row
from mechsim.integrators.compiled.erk import dop853_advance, dopri5_advance, erk_initial_step
from mechsim.integrators.compiled.outputs import evaluate_outputs
from mechsim.integrators.compiled.radau import radau15_advance
from mechsim.integrators.state import DOP853_STATE, RADAU_STATE, Status


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def radau15_restart(ks, state, y, p, dy, b, g, e, comp, g_old, tau, tau2, floor, tolerance):
    """``Radau15._restart`` compiled, operation for operation: project, the floors of the
    acceleration and work scales (returned), f at the state, the first step, a fresh
    expansion and the event functions. ``tau2``: τ² as Python computes it."""
    s = state[0]
    t = s.t
    ks.project(t, y, p)
    n = ks.n_q
    top = 0.0  # np.max(|q|/τ² + |q̇|/τ, initial=0)
    for i in range(n):
        v = abs(y[i]) / tau2 + abs(y[n + i]) / tau
        if v > top:
            top = v
    energy = np.zeros(3)
    ks.energy(t, y, p, energy)
    w_floor = max(abs(energy[0]), abs(energy[1]), abs(energy[2]))
    ks.rhs(t, y.ctypes, p.ctypes, dy.ctypes)
    h0 = erk_initial_step(ks, t, y, p, dy.copy(), tolerance, tolerance, 8.0, y.size)
    s.h = h0
    s.h_old = 0.0
    s.n_evaluations += 2
    b[:] = 0.0
    g[:] = 0.0
    e[:] = 0.0
    comp[:] = 0.0
    s.last_event = -1
    s.f0_ready = 0
    if ks.n_ev > 0:
        ks.event(t, y, p, g_old)
    return floor * top, w_floor


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _counters(state, status, k):
    """What a run returns, its status as a plain int (``state.Status``)."""
    s = state[0]
    return status.value, k, s.n_steps, s.n_evaluations, s.n_rejected, s.error_estimate, s.t


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def erk_run(ks, pair, n_stages, n_integrated, state, y, p, t_out, Y_out, rtol, atol, h_max,
            max_steps, ev_dir, want_e, want_i, want_o, want_f, E, I, O, F):
    """A DOP853 (``pair`` 0) or DOPRI5 (1) run from (state.t, y) to every time of ``t_out``,
    as ``DOP853(model, y, t, tolerance).advance(t_out)``, then the outputs wanted at the rows
    written (``evaluate_outputs``). Returns (status, rows written, steps, evaluations,
    rejections, error estimate, t reached)."""
    n = y.size
    K = np.zeros((n_stages, n))
    dense = np.zeros((7, n))
    y_old = y.copy()
    comp = np.zeros(n)
    g_old = np.zeros(ev_dir.size)
    state[0].n_integrated = n_integrated
    if pair == 0:
        status, k = dop853_advance(ks, state, y, y_old, K, dense, p, t_out, Y_out, rtol, atol,
                                   h_max, max_steps, g_old, ev_dir, comp, 1)
    else:
        status, k = dopri5_advance(ks, state, y, y_old, K, dense, p, t_out, Y_out, rtol, atol,
                                   h_max, max_steps, g_old, ev_dir, comp, 1)
    if k > 0 and (want_e or want_i or want_o or want_f):
        evaluate_outputs(ks, t_out[:k], Y_out[:k], p, want_e, want_i, want_o, want_f, E, I,
                         O, F)
    return _counters(state, status, k)


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def radau15_run(ks, state, y, p, t_out, Y_out, eps, max_steps, ev_dir, tau, tau2, floor,
                tolerance, dense_tol, want_e, want_i, want_o, want_f, E, I, O, F):
    """A radau15 run, as ``Radau15(model, y, t, tolerance, eps=eps).advance(t_out)``, then the
    outputs wanted; returns as ``erk_run``."""
    m = ks.n_q + 2
    b = np.zeros((7, m))
    g = np.zeros((7, m))
    e = np.zeros((7, m))
    F0 = np.zeros(m)
    dy = np.zeros(y.size)
    comp = np.zeros(y.size)
    g_old = np.zeros(ev_dir.size)
    a_floor, w_floor = radau15_restart(ks, state, y, p, dy, b, g, e, comp, g_old, tau, tau2,
                                       floor, tolerance)
    status, k = radau15_advance(ks, state, y, p, t_out, Y_out, eps, max_steps, comp, b, g, e,
                                F0, dy, g_old, ev_dir, a_floor, w_floor, dense_tol)
    if k > 0 and (want_e or want_i or want_o or want_f):
        evaluate_outputs(ks, t_out[:k], Y_out[:k], p, want_e, want_i, want_o, want_f, E, I,
                         O, F)
    return _counters(state, status, k)


# A call (``erk_call``, ``radau15_call``, ``closed_call``): a whole run from a fixed initial
# state to fixed output times, its rows, outputs and counters written into one buffer the
# caller made (``integrators.runs.RunLayout``: Y | t | E | I | O | F | p | counters, in a
# 2-D array of rows as wide as Y's, so that Y is its first rows). Its arguments are three
# arrays (each one costs its unboxing on every call): ``ints``, the layout and the integer
# options (``CALL_INTS``, then the events' directions), and ``data``, the float options
# (``n_floats`` of them), the initial state, the parameters and the output times.
CALL_INTS = ("want_e", "want_i", "want_o", "want_f", "cols_i", "cols_o", "frames",
             "work_external", "work_dissipated", "n_y", "n_p", "samples", "n_floats",
             "max_steps", "pair", "n_stages", "n_integrated")
COUNTERS = 6  # rows written, steps, evaluations, rejections, error estimate, time reached


@njit(cache=True, nogil=True, error_model="numpy")
def _laid_out(buf, ints, data):
    """The float options and the initial state (views of ``data``), then the views of ``buf``
    (t, Y, E, I, O, F, p, counters; borrowed, ``common._item``) with the output times and
    parameters copied in."""
    n, n_p, m, n_f = ints[9], ints[10], ints[11], ints[12]
    flat = carray(_row(buf, 0), buf.size)
    Y = carray(_row(buf, 0), (m, n))
    o = m * n
    t = flat[o:o + m]
    t[:] = data[n_f + n + n_p:n_f + n + n_p + m]
    o += m
    ce = 3 if ints[0] else 0
    E = carray(_item(flat, o), (m, ce))
    o += m * ce
    ci = ints[4] if ints[1] else 0
    I = carray(_item(flat, o), (m, ci))  # noqa: E741
    o += m * ci
    co = ints[5] if ints[2] else 0
    O = carray(_item(flat, o), (m, co))  # noqa: E741
    o += m * co
    cf = ints[6] if ints[3] else 0
    F = carray(_item(flat, o), (m, cf, 7))
    o += m * cf * 7
    p = flat[o:o + n_p]
    p[:] = data[n_f + n:n_f + n + n_p]
    o += n_p
    return data[:n_f], data[n_f:n_f + n], t, Y, E, I, O, F, p, flat[o:o + COUNTERS]


@njit(cache=True, nogil=True, error_model="numpy")
def _finish(counters, Y, ints, status, k, n_steps, n_evaluations, n_rejected, error_estimate,
            t_reached):
    """The counters into their place; the work columns NaN where they are not wanted
    (``ints[7]``, ``ints[8]`` ≥ 0), after the outputs, as ``simulate`` does; the status."""
    counters[0] = k
    counters[1] = n_steps
    counters[2] = n_evaluations
    counters[3] = n_rejected
    counters[4] = error_estimate
    counters[5] = t_reached
    if ints[7] >= 0:
        for i in range(Y.shape[0]):
            Y[i, ints[7]] = np.nan
            Y[i, ints[8]] = np.nan
    return status


_EVENTS = len(CALL_INTS)  # where the events' directions start in ``ints``


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def erk_call(ks, ints, data, buf):
    """``erk_run`` from a fresh state record and a copy of the initial state into ``buf``
    (see above; float options: rtol, atol, h_max); returns the status."""
    floats, y0, t, Y, E, I, O, F, p, counters = _laid_out(buf, ints, data)  # noqa: E741
    status, k, n_steps, n_ev, n_rej, err, t_reached = erk_run(
        ks, ints[14], ints[15], ints[16], np.zeros(1, DOP853_STATE), y0.copy(), p, t, Y,
        floats[0], floats[1], floats[2], ints[13], ints[_EVENTS:], ints[0] != 0, ints[1] != 0,
        ints[2] != 0, ints[3] != 0, E, I, O, F)
    return _finish(counters, Y, ints, status, k, n_steps, n_ev, n_rej, err, t_reached)


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def radau15_call(ks, ints, data, buf):
    """``radau15_run`` as ``erk_call`` (float options: eps, τ, τ², floor, tolerance, dense
    tolerance)."""
    floats, y0, t, Y, E, I, O, F, p, counters = _laid_out(buf, ints, data)  # noqa: E741
    status, k, n_steps, n_ev, n_rej, err, t_reached = radau15_run(
        ks, np.zeros(1, RADAU_STATE), y0.copy(), p, t, Y, floats[0], ints[13],
        ints[_EVENTS:], floats[1], floats[2], floats[3], floats[4], floats[5], ints[0] != 0,
        ints[1] != 0, ints[2] != 0, ints[3] != 0, E, I, O, F)
    return _finish(counters, Y, ints, status, k, n_steps, n_ev, n_rej, err, t_reached)


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def closed_call(motion, ks, ints, data, buf):
    """``exact`` as ``integrators.runs.ClosedFormPlan.run`` does it, into ``buf``: the
    closed form ``motion`` (``codegen.contract.Motion``, its constants the float options)
    from the initial state at 0 to the output times, then the outputs wanted; ``ints`` as
    ``erk_call``'s up to ``n_floats``, then the entries of each row that must be finite.
    Returns the status: NOT_CONVERGED where there is no closed form from the initial state,
    NOT_FINITE where a row is not."""
    c, y0, t, Y, E, I, O, F, p, counters = _laid_out(buf, ints, data)  # noqa: E741
    if not motion.rows(0.0, y0, t, c, Y):
        return _finish(counters, Y, ints, Status.NOT_CONVERGED.value, 0, 0, 0, 0, 0.0, 0.0)
    for i in range(t.size):
        for j in range(ints[13]):
            if not math.isfinite(Y[i, j]):
                return _finish(counters, Y, ints, Status.NOT_FINITE.value, 0, 0, 0, 0, 0.0,
                               0.0)
    if ints[0] != 0 or ints[1] != 0 or ints[2] != 0 or ints[3] != 0:
        evaluate_outputs(ks, t, Y, p, ints[0] != 0, ints[1] != 0, ints[2] != 0, ints[3] != 0,
                         E, I, O, F)
    return _finish(counters, Y, ints, Status.OK.value, t.size, 0, 1, 0, 0.0, t[t.size - 1])


@njit(cache=True, error_model="numpy", parallel=True)
def erk_many(ks, pair, active, state, y, y_old, K, F, P, t_out, done, Y_out, rtol, atol, h_max,
             max_steps, g_old, ev_dir, comp, restart, status):
    """Members ``active`` of an ensemble advanced by DOP853 or DOPRI5 (``pair``), each from
    its own state to the output times it has not written yet (``done[i]`` of ``t_out``; rows
    into ``Y_out[i]``), each as its stepper's ``advance`` would (``restart[i]``: its pending
    restart, then cleared); its status into ``status``, the rows written added to ``done``."""
    for j in prange(active.size):
        i = active[j]
        d = done[i]
        if pair == 0:
            st, k = dop853_advance(ks, state[i:i + 1], y[i], y_old[i], K[i], F[i], P[i],
                                   t_out[d:], Y_out[i, d:], rtol[i], atol[i], h_max,
                                   max_steps, g_old[i], ev_dir, comp[i], restart[i])
        else:
            st, k = dopri5_advance(ks, state[i:i + 1], y[i], y_old[i], K[i], F[i], P[i],
                                   t_out[d:], Y_out[i, d:], rtol[i], atol[i], h_max,
                                   max_steps, g_old[i], ev_dir, comp[i], restart[i])
        restart[i] = 0
        status[i] = st
        done[i] = d + k


@njit(cache=True, error_model="numpy", parallel=True)
def radau15_many(ks, active, state, y, P, t_out, done, Y_out, eps, max_steps, comp, b, g, e,
                 F0, dy, g_old, ev_dir, floors, tau, tau2, floor, tolerance, dense_tol, restart,
                 status):
    """Members ``active`` advanced by radau15, as ``erk_many``; a pending restart is
    ``radau15_restart`` (the floors it sets kept in ``floors[i]``)."""
    for j in prange(active.size):
        i = active[j]
        d = done[i]
        if restart[i] > 0:
            a_floor, w_floor = radau15_restart(ks, state[i:i + 1], y[i], P[i], dy[i], b[i],
                                               g[i], e[i], comp[i], g_old[i], tau[i], tau2[i],
                                               floor, tolerance[i])
            floors[i, 0] = a_floor
            floors[i, 1] = w_floor
            restart[i] = 0
        st, k = radau15_advance(ks, state[i:i + 1], y[i], P[i], t_out[d:], Y_out[i, d:],
                                eps[i], max_steps, comp[i], b[i], g[i], e[i], F0[i], dy[i],
                                g_old[i], ev_dir, floors[i, 0], floors[i, 1], dense_tol[i])
        status[i] = st
        done[i] = d + k


@njit(cache=True, error_model="numpy", parallel=True)
def outputs_many(ks, t, Y, P, want_e, want_i, want_o, want_f, E, I, O, F):
    """``evaluate_outputs`` of every member's samples, members in parallel."""
    for i in prange(Y.shape[0]):
        evaluate_outputs(ks, t, Y[i], P[i], want_e, want_i, want_o, want_f, E[i], I[i], O[i],
                         F[i])
