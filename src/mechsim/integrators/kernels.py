"""Integrator loops, compiled by numba inside each model's generated kernel module.

Everything below the marker line is pasted into the generated module (see ``mechsim.codegen``),
where ``rhs``, ``project``, ``accel_q`` and the output functions are the model's own. The loops
are resumable: their whole state lives in arrays the caller keeps between calls, so a node can
advance a run output by output with no restart cost and no forced short steps.

DOP853: Hairer's explicit Runge-Kutta 8(5,3) with the 7th-order dense output, the coefficients
taken from scipy (``scipy.integrate._ivp.dop853_coefficients``), the same error norm and step
control as scipy's ``DOP853`` so that tolerances mean the same thing in both.
Events (models with N_EV > 0 only; the code is compiled out otherwise, so DOP853 is unchanged
for every other model): after each accepted step the event functions are evaluated; a sign
change in an event's declared direction is bracketed in (t_old, t] and its time found on the
dense output (Illinois false position with bisection fallback, to ~1e-14 relative in t). The
earliest event of the step wins: outputs before it are written, the state is left at the event
time (on the side of the sign change the event reached) and ``dop853_advance`` returns EVENT.
The step's dense output stays valid for (t_old, t_event], so outputs before the event that a
later call asks for still come from it after the caller has restarted at the event.
Stiffness (Hairer's test from dop853.f, read-only, so non-stiff runs are bit for bit as
before): every 1000th accepted step, and every step while a test is positive, h·‖f(y_new) −
f(stage 12)‖ / ‖y_new − stage 12‖ (both at t + h) estimates h|λ|; above 6.1 (the edge of the
stability region) the step is limited by stability, not accuracy. 15 positive tests before 6
negative ones in a row: the loop stops after the accepted step with status STIFF.
Composition: a symmetric composition of velocity Verlet (kick-drift-kick) with given weights.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from mechsim.integrators.contract import (
    N_C,
    N_EV,
    N_FRAMES,
    N_INV,
    N_OBS,
    N_Q,
    N_Y,
    accel_q,
    canonical_rhs,
    energy,
    event,
    frames,
    from_momenta,
    invariants,
    observables,
    project,
    rhs,
)

# === kernel body ===
from scipy.integrate._ivp import dop853_coefficients as _dop  # noqa: E402

# Status codes shared with mechsim.integrators.STATUS.
OK = 0
MAX_STEPS = 1
STEP_UNDERFLOW = 2
NOT_FINITE = 3
EVENT = 4
STIFF = 5

_DOP_A = np.ascontiguousarray(_dop.A)
_DOP_B = np.ascontiguousarray(_dop.B)
_DOP_C = np.ascontiguousarray(_dop.C)
_DOP_D = np.ascontiguousarray(_dop.D)
_DOP_E3 = np.ascontiguousarray(_dop.E3)
_DOP_E5 = np.ascontiguousarray(_dop.E5)


@njit(cache=True)
def _solve(A, b):
    """Solve A x = b (small dense system) by Gaussian elimination with partial pivoting."""
    n = b.size
    M = A.copy()
    x = b.copy()
    for k in range(n):
        piv = k
        big = abs(M[k, k])
        for i in range(k + 1, n):
            if abs(M[i, k]) > big:
                big = abs(M[i, k])
                piv = i
        if piv != k:
            for j in range(n):
                tmp = M[k, j]
                M[k, j] = M[piv, j]
                M[piv, j] = tmp
            tmp = x[k]
            x[k] = x[piv]
            x[piv] = tmp
        d = M[k, k]
        for i in range(k + 1, n):
            f = M[i, k] / d
            if f != 0.0:
                for j in range(k, n):
                    M[i, j] -= f * M[k, j]
                x[i] -= f * x[k]
    for k in range(n - 1, -1, -1):
        s = x[k]
        for j in range(k + 1, n):
            s -= M[k, j] * x[j]
        x[k] = s / M[k, k]
    return x


@njit(cache=True)
def _project_onto(G, r, x):
    """x -= Gᵀ (G Gᵀ)⁻¹ r: the least-norm correction that removes the residual r.
    A zero row of G (a released constraint, with r = 0 there) is skipped."""
    nc = r.size
    GG = np.empty((nc, nc))
    for i in range(nc):
        for j in range(nc):
            s = 0.0
            for k in range(x.size):
                s += G[i, k] * G[j, k]
            GG[i, j] = s
        if GG[i, i] == 0.0:
            GG[i, i] = 1.0
    mu = _solve(GG, r)
    for k in range(x.size):
        s = 0.0
        for i in range(nc):
            s += G[i, k] * mu[i]
        x[k] -= s


@njit(cache=True)
def _rms_norm(x, scale):
    s = 0.0
    for i in range(x.size):
        z = x[i] / scale[i]
        s += z * z
    return math.sqrt(s / x.size)


@njit(cache=True)
def dop853_initial_step(t, y, p, f0, rtol, atol):
    n = y.size
    scale = np.empty(n)
    for i in range(n):
        scale[i] = atol + abs(y[i]) * rtol
    d0 = _rms_norm(y, scale)
    d1 = _rms_norm(f0, scale)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    y1 = y + h0 * f0
    f1 = np.zeros(n)
    rhs(t + h0, y1, p, f1)
    d2 = _rms_norm(f1 - f0, scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100.0 * h0, h1)


@njit(cache=True)
def _rk_stages(t0, y0, h, K, first, last, ytmp, p):
    """Stages ``first`` … ``last − 1`` of the DOP853 tableau from (t0, y0) into K."""
    n = y0.size
    for s in range(first, last):
        for i in range(n):
            acc = 0.0
            for j in range(s):
                acc += _DOP_A[s, j] * K[j, i]
            ytmp[i] = y0[i] + h * acc
        rhs(t0 + _DOP_C[s] * h, ytmp, p, K[s])


@njit(cache=True)
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


@njit(cache=True)
def _dense_prepare(st, y, y_old, K, F, p):
    """Extra stages and interpolation coefficients for the last accepted step (t_old, t]."""
    n = y.size
    t_old = st[2]
    h = st[3]
    _rk_stages(t_old, y_old, h, K, 13, 16, np.empty(n), p)
    for i in range(n):
        dlt = y[i] - y_old[i]
        F[0, i] = dlt
        F[1, i] = h * K[0, i] - dlt
        F[2, i] = 2.0 * dlt - h * (K[12, i] + K[0, i])
        for r in range(4):
            acc = 0.0
            for j in range(16):
                acc += _DOP_D[r, j] * K[j, i]
            F[3 + r, i] = h * acc
    st[4] = 1.0


@njit(cache=True)
def _crossed(g0, g1, direction):
    """A sign change from g0 to g1 in ``direction`` (+1 rising, -1 falling, 0 either)."""
    if direction >= 0 and g0 < 0.0 <= g1:
        return True
    return direction <= 0 and g0 > 0.0 >= g1


@njit(cache=True)
def _event_at(t, F, y_old, t_old, h, p, ytmp, g, i):
    """Event function ``i`` on the dense output of the last step at time t (projected)."""
    _dense_eval(F, y_old, (t - t_old) / h, ytmp)
    if N_C > 0:
        project(t, ytmp, p)
    event(t, ytmp, p, g)
    return g[i]


@njit(cache=True)
def _locate_event(F, y_old, t_old, h, p, i, a, fa, b, fb):
    """Root of event ``i`` bracketed by (a, fa) and (b, fb), fb on the far side of the sign
    change or zero: Illinois false position, bisecting when the bracket shrinks slowly.
    Returns the bracket end on the far side (so the event has happened there)."""
    ytmp = np.empty(y_old.size)
    g = np.empty(N_EV)
    side = 0
    slow = 0
    for _ in range(200):
        width = b - a
        tol = max(1e-14 * max(abs(a), abs(b)), 4.0 * (np.nextafter(b, np.inf) - b))
        if width <= tol or fb == 0.0:
            break
        if slow >= 2:
            c = 0.5 * (a + b)
            slow = 0
        else:
            c = b - fb * (b - a) / (fb - fa)
            if not (a < c < b):
                c = 0.5 * (a + b)
        fc = _event_at(c, F, y_old, t_old, h, p, ytmp, g, i)
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


@njit(cache=True)
def dop853_advance(st, y, y_old, K, F, p, t_out, Y_out, rtol, atol, h_max, max_steps,
                   g_old, ev_dir):
    """Advance until every time in ``t_out`` (increasing, >= st[0] of the last step start) is
    written to ``Y_out``. State ``st`` = [t, h_next, t_old, h_old, dense_ready, n_steps,
    n_rejected, n_rhs, last_event, n_events, stiff_positive, stiff_negative, h_lambda];
    ``y`` current state, ``y_old``/``K``/``F`` the last step's data, with K[12] = f(t, y) on
    entry; ``g_old`` the event functions at (t, y), ``ev_dir`` their directions. Returns
    (status, number of outputs written); on EVENT the state is at the event time st[0]
    (outputs before it written) and st[8] is its index; on STIFF the state is at the end of
    the last accepted step (outputs up to it written)."""
    n = y.size
    y_new = np.empty(n)
    ytmp = np.empty(n)
    scale = np.empty(n)
    err5 = np.empty(n)
    err3 = np.empty(n)
    n_out = t_out.size
    k = 0
    steps = 0
    # Outputs that fall in the last accepted step (t_old, t].
    while k < n_out and st[3] > 0.0 and t_out[k] <= st[0]:
        if t_out[k] == st[0]:
            Y_out[k, :] = y
        else:
            if st[4] == 0.0:
                _dense_prepare(st, y, y_old, K, F, p)
            _dense_eval(F, y_old, (t_out[k] - st[2]) / st[3], Y_out[k])
            if N_C > 0:
                project(t_out[k], Y_out[k], p)
        k += 1
    while k < n_out and t_out[k] == st[0]:
        Y_out[k, :] = y
        k += 1
    rejected = False
    while k < n_out:
        if steps >= max_steps:
            return MAX_STEPS, k
        t = st[0]
        h = min(st[1], h_max)
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        if h < min_step:
            return STEP_UNDERFLOW, k
        if not rejected:
            # FSAL: f(t, y) of the last accepted step end becomes this step's first stage.
            for i in range(n):
                K[0, i] = K[12, i]
        _rk_stages(t, y, h, K, 1, 12, ytmp, p)
        for i in range(n):
            acc = 0.0
            for j in range(12):
                acc += _DOP_B[j] * K[j, i]
            y_new[i] = y[i] + h * acc
        rhs(t + h, y_new, p, K[12])
        st[7] += 12.0
        for i in range(n):
            scale[i] = atol + max(abs(y[i]), abs(y_new[i])) * rtol
            a5 = 0.0
            a3 = 0.0
            for j in range(13):
                a5 += _DOP_E5[j] * K[j, i]
                a3 += _DOP_E3[j] * K[j, i]
            err5[i] = a5 / scale[i]
            err3[i] = a3 / scale[i]
        e5 = 0.0
        e3 = 0.0
        for i in range(n):
            e5 += err5[i] * err5[i]
            e3 += err3[i] * err3[i]
        if e5 == 0.0 and e3 == 0.0:
            err = 0.0
        else:
            err = h * e5 / math.sqrt((e5 + 0.01 * e3) * n)
        if not math.isfinite(err):
            err = 1e10
        if err < 1.0:
            stiff = False
            if st[5] % 1000.0 == 0.0 or st[10] > 0.0:
                # Stage 12 (ytmp, K[11]) and y_new (K[12]) are both at t + h.
                stnum = 0.0
                stden = 0.0
                for i in range(n):
                    stnum += (K[12, i] - K[11, i]) ** 2
                    stden += (y_new[i] - ytmp[i]) ** 2
                if stden > 0.0:
                    st[12] = h * math.sqrt(stnum / stden)
                    if st[12] > 6.1:
                        st[11] = 0.0
                        st[10] += 1.0
                        stiff = st[10] >= 15.0
                    else:
                        st[11] += 1.0
                        if st[11] >= 6.0:
                            st[10] = 0.0
            if err == 0.0:
                factor = 10.0
            else:
                factor = min(10.0, 0.9 * err ** (-1.0 / 8.0))
            if rejected:
                factor = min(1.0, factor)
            rejected = False
            for i in range(n):
                if not math.isfinite(y_new[i]):
                    return NOT_FINITE, k
            y_old[:] = y
            t_new = t + h
            if N_C > 0:
                project(t_new, y_new, p)
                rhs(t_new, y_new, p, K[12])
                st[7] += 1.0
            y[:] = y_new
            st[2] = t
            st[3] = h
            st[0] = t_new
            st[4] = 0.0
            st[1] = h * factor
            steps += 1
            st[5] += 1.0
            if N_EV > 0:
                g_new = np.empty(N_EV)
                event(t_new, y, p, g_new)
                first = -1
                t_ev = t_new
                for i in range(N_EV):
                    if _crossed(g_old[i], g_new[i], ev_dir[i]):
                        if st[4] == 0.0:
                            _dense_prepare(st, y, y_old, K, F, p)
                        ti = _locate_event(F, y_old, t, h, p, i, t, g_old[i], t_new, g_new[i])
                        if first < 0 or ti < t_ev:
                            first = i
                            t_ev = ti
                if first >= 0:
                    while k < n_out and t_out[k] < t_ev:
                        _dense_eval(F, y_old, (t_out[k] - t) / h, Y_out[k])
                        if N_C > 0:
                            project(t_out[k], Y_out[k], p)
                        k += 1
                    if t_ev < t_new:
                        _dense_eval(F, y_old, (t_ev - t) / h, y)
                        if N_C > 0:
                            project(t_ev, y, p)
                    st[0] = t_ev
                    st[8] = first
                    st[9] += 1.0
                    return EVENT, k
                g_old[:] = g_new
            while k < n_out and t_out[k] <= t_new:
                if t_out[k] == t_new:
                    Y_out[k, :] = y
                else:
                    if st[4] == 0.0:
                        _dense_prepare(st, y, y_old, K, F, p)
                    _dense_eval(F, y_old, (t_out[k] - t) / h, Y_out[k])
                    if N_C > 0:
                        project(t_out[k], Y_out[k], p)
                k += 1
            if stiff:
                return STIFF, k
        else:
            st[1] = h * max(0.2, 0.9 * err ** (-1.0 / 8.0))
            st[6] += 1.0
            rejected = True
    return OK, k


@njit(cache=True)
def composition_advance(st, y, p, n_out, n_sub, h, weights, Y_out, a):
    """Fixed-step symmetric composition of velocity Verlet for separable systems.
    ``st`` = [t, n_steps, n_force]; ``a`` holds accel_q(q) on entry and on exit. Writes the
    state after each block of ``n_sub`` steps to Y_out[0..n_out). Returns (status, written)."""
    nq = N_Q
    q = y[:nq]
    v = y[nq:2 * nq]
    nw = weights.size
    # Kick-drift-kick stages with each closing half-kick merged into the next opening one:
    # kick coefficients (w_s + w_{s+1}) h / 2 inside a step, w h / 2 at its ends.
    kick = np.empty(nw + 1)
    kick[0] = 0.5 * weights[0] * h
    for s in range(1, nw):
        kick[s] = 0.5 * (weights[s - 1] + weights[s]) * h
    kick[nw] = 0.5 * weights[nw - 1] * h
    for k in range(n_out):
        for _ in range(n_sub):
            for i in range(nq):
                v[i] += kick[0] * a[i]
            for s in range(nw):
                hw = weights[s] * h
                for i in range(nq):
                    q[i] += hw * v[i]
                accel_q(st[0], q, p, a)
                c = kick[s + 1]
                for i in range(nq):
                    v[i] += c * a[i]
            st[0] += h
            st[1] += 1.0
        st[2] += n_sub * nw
        for i in range(nq):
            if not (math.isfinite(q[i]) and math.isfinite(v[i])):
                return NOT_FINITE, k
        Y_out[k, :] = y
    return OK, n_out


_S15 = math.sqrt(15.0)
_GL_C = np.array([0.5 - _S15 / 10.0, 0.5, 0.5 + _S15 / 10.0])
_GL_A = np.array([[5.0 / 36.0, 2.0 / 9.0 - _S15 / 15.0, 5.0 / 36.0 - _S15 / 30.0],
                  [5.0 / 36.0 + _S15 / 24.0, 2.0 / 9.0, 5.0 / 36.0 - _S15 / 24.0],
                  [5.0 / 36.0 + _S15 / 30.0, 2.0 / 9.0 + _S15 / 15.0, 5.0 / 36.0]])
_GL_B = np.array([5.0 / 18.0, 4.0 / 9.0, 5.0 / 18.0])
NOT_CONVERGED = 6


@njit(cache=True)
def gauss_advance(st, z, p, n_out, n_sub, h, Y_out, K):
    """Three-stage Gauss–Legendre collocation (order 6, symplectic) on the canonical
    variables z = [q, p, work terms] of a conservative system, fixed step ``h``, stage
    equations solved by fixed-point iteration started from the last step's stages (``K``,
    shape (3, N_Y), kept between calls). Writes y = [q, q̇, ...] after each block of ``n_sub``
    steps. ``st`` = [t, n_steps, n_rhs]. Returns (status, written)."""
    n = z.size
    zs = np.empty(n)
    Knew = np.empty((3, n))
    for k in range(n_out):
        for _ in range(n_sub):
            t = st[0]
            converged = False
            previous = math.inf
            for _it in range(60):
                for i in range(3):
                    for m in range(n):
                        acc = 0.0
                        for j in range(3):
                            acc += _GL_A[i, j] * K[j, m]
                        zs[m] = z[m] + h * acc
                    canonical_rhs(t + _GL_C[i] * h, zs, p, Knew[i])
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
                st[2] += 3.0
                if not finite:
                    break  # the iteration diverged: not converged
                delta = change / (size + 1e-300)
                # Converged at round-off, or stagnating there (no further decrease).
                if delta <= 4e-16 or (delta >= previous and delta < 1e-12):
                    converged = True
                    break
                previous = delta
            if not converged:
                return NOT_CONVERGED, k
            for m in range(n):
                z[m] += h * (_GL_B[0] * K[0, m] + _GL_B[1] * K[1, m] + _GL_B[2] * K[2, m])
            st[0] = t + h
            st[1] += 1.0
        for m in range(n):
            if not math.isfinite(z[m]):
                return NOT_FINITE, k
        from_momenta(st[0], z, p, Y_out[k])
    return OK, n_out


@njit(cache=True)
def evaluate_outputs(ts, Y, p, want_energy, want_inv, want_obs, want_frames,
                     E_out, I_out, O_out, F_out):
    """Energy terms, invariants, observables and frames at each sample, only those wanted."""
    for k in range(ts.size):
        if want_energy:
            energy(ts[k], Y[k], p, E_out[k])
        if want_inv and N_INV > 0:
            invariants(ts[k], Y[k], p, I_out[k])
        if want_obs and N_OBS > 0:
            observables(ts[k], Y[k], p, O_out[k])
        if want_frames and N_FRAMES > 0:
            frames(ts[k], Y[k], p, F_out[k])
