"""The predictor–corrector iteration of a radau15 step (``_radau_iterate``): the expansion
of the step is corrected at the seven non-zero nodes until what it still owes to the state is
at round-off; a side step (``_radau_side_step``) is the same iteration to a point inside the
step just taken."""

import math

import numpy as np
from numba import njit

from mechsim.integrators.compiled.common import _copy, _kahan
from mechsim.integrators.compiled.radau_basis import (
    _RADAU_C,
    _RADAU_CV,
    _RADAU_CX,
    _RADAU_NEWTON_V,
    _RADAU_NEWTON_X,
    _RADAU_NODES,
    _radau_g_from_b,
    _radau_increments,
    _radau_state_at,
)

# Predictor–corrector iterations of a step at most. A step whose iteration needed more than
# _RADAU_SLOW of them and contracted by a factor ρ per iteration (measured while the change
# is above _RADAU_RHO_FLOOR, clear of round-off) is followed by one at most
# _RADAU_CONTRACTION / ρ times as long: ρ grows with the step where the forces depend on the
# velocities (gyroscopic terms: the quaternion rigid body). Without this limit the steps
# there run out of iterations, are redone four times shorter and grow back into the same
# failure, a rejection a step.
_RADAU_MAX_ITERATIONS = 30
_RADAU_CONTRACTION = 0.4
_RADAU_RHO_FLOOR = 1e-10
_RADAU_SLOW = 6
# A side step's iteration (an output or event state inside a step, which the run does not
# carry on from) is settled when what it still owes to the state at its end is below this
# fraction of the state's scale: a 64th of the unit round-off. A step the run carries on from
# is not settled on such an estimate (see ``_radau_iterate``): what a cut-short iteration
# leaves is of one sign along an orbit (the prediction's error, contracted), so it adds up
# like N, not like the √N of round-off, however small the bound.
_RADAU_ROUND_OFF = 2.0**-59
# Once the iteration stagnates, a change within this fraction of the state's scale settles
# it (a few units of round-off): a work term whose rate is round-off of cancelling terms
# changes by that much from one iteration to the next, however long the iteration goes on.
_RADAU_NOISE = 4.0 * 2.0**-53


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _settled(change, last, theta_b6, bound, noise):
    """Whether a linearly converging iteration whose last two changes were ``last`` and
    ``change`` still owes at most ``bound``: with θ the larger of change / last and
    ``theta_b6`` (the contraction of b₆, the slowest to settle: the ratio of the first two
    changes alone undercounts what is left once the fast parts have died out), θ < 0.5 and
    θ/(1 − θ) · change ≤ bound (the rest of a geometric series); or, where the iteration
    stagnates (``noise``: from the third iteration on, b₆ no longer falling; at round-off the
    changes are noise and θ means nothing), a change within the bound or ``_RADAU_NOISE``."""
    if change == 0.0 or (noise and change <= max(bound, _RADAU_NOISE)):
        return True
    if not last > 0.0:
        return False
    theta = max(change / last, theta_b6)
    return theta < 0.5 and theta / (1.0 - theta) * change <= bound


@njit(inline="always")
def _end_settled(carried, end, last_end, theta_b6, noise):
    """Whether the iteration is settled at the step's end: where the run carries on from it,
    only once an iteration has not moved it at all; otherwise on ``_settled``'s estimate."""
    if carried:
        return end == 0.0
    return _settled(end, last_end, theta_b6, _RADAU_ROUND_OFF, noise)


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_iterate(ks, t0, y, comp, F0, b, g, dt, p, w_floor, inside_tol, carried, cost, ys,
                   dy, dg):
    """Predictor–corrector iteration of the step of length dt from (t0, y): the expansion
    ``b`` (with its divided differences ``g``) is corrected in place until it is settled.
    Returns (converged, iterations, contraction ρ of b₆ measured above round-off); ``dy`` ends
    as f at the last node; ``ys`` and ``dg`` (7, N_Q + 2) are scratch; ``cost`` counts
    evaluations and iterations.

    ``carried``: the run carries on from the step's end (a step of the run, not a side
    step). Its iteration goes on until the change of b₆ is at round-off (IAS15's test) or
    no longer falls (converged only if that change is below 1e-13, as before: a step
    stagnating above it is redone shorter), or until an iteration changes nothing at the
    end; the estimates below do not end it. Stopping on an estimate of what is still owed,
    however small, leaves a remainder of one sign along an orbit, and the energy error of
    long runs then drifts like N instead of the √N of round-off (Brouwer's law: ``mechsim
    bench --brouwer``); so does accepting a stagnating iteration as noise.

    Settled otherwise (side steps; ``_settled``, from the second iteration on, the contraction
    θ measured on the last two changes and on b₆): what the iteration still owes to the state
    at the step's end is below ``_RADAU_ROUND_OFF`` of the state's scale (the
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
    scale_q, scale_v = _radau_state_scales(y, F0, dt, n)
    for it in range(_RADAU_MAX_ITERATIONS):
        # f at the seven non-zero nodes of the current expansion, each node's divided
        # difference corrected and its change applied to b at once
        _copy(ys, y)
        for node in range(1, 8):
            h = _RADAU_NODES[node]
            _radau_state_at(h, n, y, F0, b, dt, comp, ys)
            ks.rhs(t0 + h * dt, yp, pp, dyp)
            _radau_correct(node, n, dy, F0, b, g, dg)
        cost[0] += 7
        cost[1] += 1
        pc = _radau_b6_change(dg, dy, n)
        if _RADAU_RHO_FLOOR < previous < math.inf:
            rho = max(rho, pc / previous)
        iterations = it + 1
        end, inside = _radau_owed(y, F0, dg, dt, n, scale_q, scale_v, w_floor, inside_wanted)
        theta_b6 = pc / previous if previous > 0.0 else 1.0
        noise = it >= 2 and pc >= previous  # stagnating: the changes are noise
        settled = (it >= 1 and _end_settled(carried, end, last_end, theta_b6, noise)
                   and _settled(inside, last_inside, theta_b6, inside_tol, noise))
        last_end = end
        last_inside = inside
        if settled or pc < 1e-16 or (it >= 2 and pc >= previous):
            converged = settled or pc < 1e-13  # settled, at round-off, or stagnating there
            break
        previous = pc
    return converged, iterations, rho


@njit(inline="always")
def _radau_state_scales(y, F0, dt, n):
    """The state's scale for the iteration's changes: the largest |q| and |q̇|, or their
    changes over the step where those are larger."""
    scale_q = 0.0
    scale_v = 0.0
    for j in range(n):
        scale_q = max(scale_q, abs(y[j]), dt * abs(y[n + j]))
        scale_v = max(scale_v, abs(y[n + j]), dt * abs(F0[j]))
    return scale_q, scale_v


@njit(inline="always")
def _radau_correct(node, n, dy, F0, b, g, dg):
    """The divided difference g of ``node`` from f there (``dy``), its change into ``dg`` and
    applied to b at once (b = Cᵀ g)."""
    h = _RADAU_NODES[node]
    for j in range(n + 2):
        r = (dy[n + j] - F0[j]) / h
        for jj in range(1, node):
            r = (r - g[jj - 1, j]) / (h - _RADAU_NODES[jj])
        delta = r - g[node - 1, j]
        g[node - 1, j] = r
        dg[node - 1, j] = delta  # this iteration's change of g (b = Cᵀ g)
        for kk in range(node):
            b[kk, j] += _RADAU_C[node - 1, kk] * delta


@njit(inline="always")
def _radau_b6_change(dg, dy, n):
    """This iteration's change of b₆ of the accelerations relative to them (the work rates do
    not act back on the motion: theirs settles with it, and may be round-off of cancelling
    terms amplified)."""
    change = 0.0
    scale = 0.0
    for j in range(n):
        change = max(change, abs(_RADAU_C[6, 6] * dg[6, j]))
        scale = max(scale, abs(dy[n + j]))
    return change / scale if scale > 0.0 else 0.0


@njit(inline="always")
def _radau_owed(y, F0, dg, dt, n, scale_q, scale_v, w_floor, inside_wanted):
    """This iteration's change of the state, relative to the state's scale: at the step's end,
    and (``inside_wanted``) its bound anywhere inside the step."""
    end = 0.0
    inside = 0.0
    for j in range(n + 2):
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
    return end, inside


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
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
                                     math.inf, False, cost, inc, dy, np.empty((7, m)))
    _radau_increments(n, y0, F0, bs, frac * dt, inc)
    c = comp0.copy()
    out[:] = y0
    for i in range(2 * n + 2):
        _kahan(out, c, i, inc[i])
    return converged


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_derivatives(s_, rhs, t, y, inc, pp, dy, n, out):
    """``out`` ← the second derivatives of q and the work rates at (t, y) (one evaluation,
    counted; ``inc`` and ``dy`` are scratch)."""
    for i in range(y.size):
        inc[i] = y[i]
    rhs(t, inc.ctypes, pp, dy.ctypes)
    s_.n_evaluations += 1
    for j in range(out.size):
        out[j] = dy[n + j]
