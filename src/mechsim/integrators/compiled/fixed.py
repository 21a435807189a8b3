"""The fixed-step loops: ``composition_advance``, a symmetric composition of velocity Verlet
(kick-drift-kick) with given weights, for separable systems; ``gauss_advance``, three-stage
Gauss–Legendre collocation on Hamilton's equations."""

import math

import numpy as np
from numba import njit

from mechsim.integrators.compiled.common import _add_compensated, _borrowed, _copy_row, _row
from mechsim.integrators.state import Status


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


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def composition_advance(ks, state, y, p, n_out, n_sub, h, weights, Y_out, a, comp):
    """Fixed-step symmetric composition of velocity Verlet for separable systems.
    ``state``: a ``FIXED_STATE`` record; ``a`` holds accel_q(q) on entry and on exit;
    ``comp`` the compensation of y. Writes the state after each block of ``n_sub`` steps to
    Y_out[0..n_out). Returns (status, written).

    Kick-drift-kick stages, each closing half-kick merged into the next opening one: kick
    coefficients (w_s + w_{s+1}) h / 2 inside a step, w h / 2 at its ends. Within a step the
    stages move q and v by increments dq, dv that start at zero (small numbers, added to
    without loss; the force is evaluated at q₀ + dq); the step's total increments are added
    to the state once, compensated. The steps are taken by ``_composition_steps``."""
    nw = weights.size
    kick = np.empty(nw + 1)
    drift = np.empty(nw)
    kick[0] = 0.5 * weights[0] * h
    for j in range(1, nw):
        kick[j] = 0.5 * (weights[j - 1] + weights[j]) * h
    kick[nw] = 0.5 * weights[nw - 1] * h
    for j in range(nw):
        drift[j] = weights[j] * h
    nq = ks.n_q
    return _composition_steps(ks, state, y, p, n_out, n_sub, h, Y_out, a, comp,
                              (kick, drift, np.empty(nq), np.empty(2 * nq)))


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _composition_steps(ks, state, y, p, n_out, n_sub, h, Y_out, a, comp, work):
    """``composition_advance``'s steps, on the arrays borrowed (see ``common``); ``work``:
    the kick and drift coefficients, scratch for q and for the increments [dq, dv]."""
    y, p, Y_out, a, comp = (_borrowed(y), _borrowed(p), _borrowed(Y_out), _borrowed(a),
                            _borrowed(comp))
    kick, drift, q, d = (_borrowed(work[0]), _borrowed(work[1]), _borrowed(work[2]),
                         _borrowed(work[3]))
    s = state[0]
    nq = ks.n_q
    accel = ks.accel_q
    nw = drift.size
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
        _copy_row(Y_out, k, y)
    return Status.OK, n_out


_S15 = math.sqrt(15.0)
_GL_C = np.array([0.5 - _S15 / 10.0, 0.5, 0.5 + _S15 / 10.0])
_GL_A = np.array([[5.0 / 36.0, 2.0 / 9.0 - _S15 / 15.0, 5.0 / 36.0 - _S15 / 30.0],
                  [5.0 / 36.0 + _S15 / 24.0, 2.0 / 9.0, 5.0 / 36.0 - _S15 / 24.0],
                  [5.0 / 36.0 + _S15 / 30.0, 2.0 / 9.0 + _S15 / 15.0, 5.0 / 36.0]])
_GL_B = np.array([5.0 / 18.0, 4.0 / 9.0, 5.0 / 18.0])


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def gauss_advance(ks, state, z, p, n_out, n_sub, h, Y_out, K, comp):
    """Three-stage Gauss–Legendre collocation (order 6, symplectic) on the canonical
    variables z = [q, p, work terms] of a conservative system, fixed step ``h``, stage
    equations solved by fixed-point iteration started from the last step's stages (``K``,
    shape (3, N_Y), kept between calls), z updated with compensation ``comp``. Writes
    y = [q, q̇, ...] after each block of ``n_sub`` steps. Returns (status, written). The steps
    are taken by ``_gauss_steps``, on the arrays borrowed (see ``common``)."""
    n = z.size
    return _gauss_steps(ks, state, z, p, n_out, n_sub, h, Y_out, K, comp,
                        (np.empty(n), np.empty(n), np.empty((3, n))))


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _gauss_steps(ks, state, z, p, n_out, n_sub, h, Y_out, K, comp, work):
    """``gauss_advance``'s steps; ``work``: scratch (the stages' z, the increments, the new
    stages)."""
    z, p, Y_out, K, comp = (_borrowed(z), _borrowed(p), _borrowed(Y_out), _borrowed(K),
                            _borrowed(comp))
    zs, inc, Knew = _borrowed(work[0]), _borrowed(work[1]), _borrowed(work[2])
    s = state[0]
    pp = p.ctypes
    zp = zs.ctypes
    n = z.size
    for k in range(n_out):
        for _ in range(n_sub):
            t = s.t
            if not _gauss_stages(ks.canonical_rhs, s, t, h, z, K, Knew, zs, zp, pp):
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


@njit(inline="always")
def _gauss_stages(f, s, t, h, z, K, Knew, zs, zp, pp):
    """Solve the stage equations of the step of h from (t, z) by fixed-point iteration from
    the stages in ``K`` (left there); whether it converged at round-off, or stagnated there
    (no further decrease). ``Knew`` and ``zs`` (pointer ``zp``) are scratch; ``pp`` is the
    pointer of the parameters."""
    n = z.size
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
            return False  # the iteration diverged
        delta = change / (size + 1e-300)
        if delta <= 4e-16 or (delta >= previous and delta < 1e-12):
            return True
        previous = delta
    return False
