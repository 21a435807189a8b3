"""radau15: the adaptive 15th-order Gauss–Radau predictor–corrector (``radau15_advance``)."""

import math

import numpy as np
from numba import njit

from mechsim.integrators.compiled.common import (
    _any_crossed,
    _borrowed,
    _copy,
    _copy_matrix,
    _copy_row,
    _crossed,
    _finite_row,
    _kahan,
    _zero,
    _zero_matrix,
)
from mechsim.integrators.compiled.events import (
    DENSE_RADAU,
    DENSE_RADAU_STEP,
    _locate_event,
    _state_in_step,
)
from mechsim.integrators.compiled.radau_basis import (
    _RADAU_X,
    _radau_dense_expansion,
    _radau_increments,
    _radau_interpolant_error,
    _radau_predict,
    _radau_rescale,
)
from mechsim.integrators.compiled.radau_iteration import (
    _RADAU_CONTRACTION,
    _RADAU_ROUND_OFF,
    _RADAU_SLOW,
    _radau_derivatives,
    _radau_iterate,
)
from mechsim.integrators.state import Status

# A step that would end short of the last requested time by less than this fraction of its
# length is stretched to land on it: otherwise the next step is the remainder, a few ulps
# when the planned step ends a few ulps before that time, and the run stops with a step-size
# underflow.
_LANDING_STRETCH = 0.01
# An output inside a step comes from the step's (corrected) expansion when the estimate of
# the error of its own expansion is within this share of the tolerance, else from a side step
# of its own. The corrected expansion is off by at most that error plus the correction, each
# about the estimate (checked against side steps, the state landing there would give, on the
# systems of tests/test_radau15.py). A thousandth (as DOP853's local tolerance): outputs then
# stay near the integration's own error, not just within the tolerance (a larger share shows
# in the sampled energy error of long runs), at the cost of side steps for a few per cent of
# the outputs of a chaotic or constrained system.
_RADAU_DENSE_SHARE = 0.001
# ... or within this much of the state scale (64 units of round-off, what a run's own
# round-off soon exceeds), up to half the tolerance: at tolerances near round-off a thousandth
# would have side steps take nearly every output.
_RADAU_DENSE_FLOOR = 2.0**-47
# ... and what the iteration still owes inside the step within this share of the tolerance.
_RADAU_INSIDE_SHARE = 1e-4


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
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
    written).

    The steps are taken by ``_radau15_steps``, on the arrays borrowed (see ``common``)."""
    n = ks.n_q
    m = n + 2  # accelerations and the two work rates
    work = (np.empty(y.size), np.empty((7, m)), np.empty(m), np.empty(y.size), np.empty(y.size),
            np.empty((8, m)), np.empty((7, m)), np.empty(max(ks.n_ev, 1)))
    return _radau15_steps(ks, state, y, p, t_out, Y_out, eps, max_steps, comp, b, g, e, F0, dy,
                          g_old, ev_dir, a_floor, w_floor, dense_tol, work,
                          np.zeros(3, dtype=np.int64))


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau15_steps(ks, state, y, p, t_out, Y_out, eps, max_steps, comp, b, g, e, F0, dy,
                   g_old, ev_dir, a_floor, w_floor, dense_tol, work, cost):
    """``radau15_advance``'s steps; ``work``: scratch (the increments, the prediction a step
    started from, f at its end, its end state and compensation, the dense output's
    expansion, the changes of g, the event functions at its end); ``cost``: a side step's
    evaluations, iterations and side steps."""
    y, p, t_out, Y_out, comp, b, g, e, F0, dy, g_old, ev_dir = (
        _borrowed(y), _borrowed(p), _borrowed(t_out), _borrowed(Y_out), _borrowed(comp),
        _borrowed(b), _borrowed(g), _borrowed(e), _borrowed(F0), _borrowed(dy),
        _borrowed(g_old), _borrowed(ev_dir))
    inc, F1, y_new, comp_new, g_new, cost = (
        _borrowed(work[0]), _borrowed(work[2]), _borrowed(work[3]), _borrowed(work[4]),
        _borrowed(work[7]), _borrowed(cost))
    b_start, b8, dg = _borrowed(work[1]), _borrowed(work[5]), _borrowed(work[6])
    s_ = state[0]
    n = ks.n_q
    rhs = ks.rhs
    pp = p.ctypes
    dense_limit, dense_inside = _radau_dense_limits(dense_tol)
    n_out = t_out.size
    k = _radau_outputs_now(s_, y, t_out, Y_out)
    steps = 0
    t_last = t_out[n_out - 1] if n_out > 0 else s_.t
    t_target = t_last  # the time to land on (an earlier output where a side step failed)
    while k < n_out:
        if steps >= max_steps:
            return Status.MAX_STEPS, k
        t0 = s_.t
        tc0 = s_.t_comp
        dt, landing = _radau_plan(s_, b, g, e, t_target)
        if dt <= 10.0 * abs(np.nextafter(t0, np.inf) - t0):
            return Status.STEP_UNDERFLOW, k
        if s_.f0_ready == 0:  # F₀ at the start of the step
            _radau_derivatives(s_, rhs, t0, y, inc, pp, dy, n, F0)
            s_.f0_ready = 1
        _copy_matrix(b_start, b)
        dt_first = dt  # the step b_start predicts
        again = True
        while again:  # until the controller accepts the step (or it is not finite)
            _zero(cost)
            converged, iterations, rho = _radau_iterate(
                ks, t0, y, comp, F0, b, g, dt, p, w_floor,
                _inside_tolerance(dense_inside, t_out[k] - t0, dt), True, cost, inc, dy, dg)
            status, again, dt, dt_new = _radau_control(s_, b, g, e, b_start, dy, cost, converged,
                                                      a_floor, eps, dt, dt_first, n)
        if status != Status.OK:
            return status, k
        landing = landing and dt == dt_first  # (a step redone is shorter: it does not land)
        # the step's end, not committed yet (a side step to an output inside the step that
        # does not converge has the step redone, landing on that output)
        finite, local, scale = _radau_end_state(n, y, comp, F0, b, dt, inc, y_new, comp_new)
        if not finite:
            return Status.NOT_FINITE, k
        t_new, tc_new = _radau_end_time(landing, t0, tc0, dt, t_target)
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
        _zero(cost)
        redo = -1
        if ks.n_ev > 0:
            ks.event(t_new, y_new, p, g_new)
            if _any_crossed(g_old, g_new, ev_dir):
                status, k, redo = _radau_event(ks, s_, mode, t_out, Y_out, k, b8, F0, y, comp,
                                               t0, tc0, dt, p, w_floor, cost, t_new, y_new,
                                               g_old, g_new, ev_dir)
                if status != Status.OK:
                    return status, k
        if redo < 0:
            k, redo = _outputs_written(_radau_outputs(
                ks, mode, t_out, Y_out, k, t_new, y_new, True, b8, F0, y, comp, t0, tc0, dt, p,
                w_floor, cost), k)
        _count_cost(s_, cost)
        if redo >= 0:
            # outputs before t_out[redo] are written; the step is redone, landing there
            k = redo
            t_target = t_out[redo]
            s_.n_rejected += 1
            _copy_matrix(b, b_start)
            _radau_rescale(b, g, e, s_.h / dt_first)
            continue
        t_target = t_last
        _radau_commit(ks, s_, y, comp, y_new, comp_new, t_new, tc_new, g_old, g_new, F0, F1,
                      local / scale, dt)
        steps += 1
        _radau_next_step(s_, b, g, e, dt, dt_new, iterations, rho, landing)
    return Status.OK, k


@njit(inline="always")
def _radau_dense_limits(dense_tol):
    """What the outputs inside a step may be off by, and what they read of its iteration
    (nothing when they all take side steps; never better than round-off)."""
    limit = max(_RADAU_DENSE_SHARE * dense_tol, min(0.5 * dense_tol, _RADAU_DENSE_FLOOR))
    inside = (max(_RADAU_INSIDE_SHARE * dense_tol, _RADAU_ROUND_OFF) if dense_tol > 0.0
              else math.inf)
    return limit, inside


@njit(inline="always")
def _inside_tolerance(dense_inside, gap, dt):
    """The inside of the step matters only where an output falls in it (``gap`` ahead)."""
    return dense_inside if gap < dt else math.inf


@njit(inline="always")
def _radau_outputs_now(s_, y, t_out, Y_out):
    """Write the outputs at the current time, or a few ulps after it, closer than a step can
    go (an event located that close before the output time the step landed on); returns how
    many."""
    near = 10.0 * abs(np.nextafter(s_.t, np.inf) - s_.t)
    k = 0
    while k < t_out.size and t_out[k] - s_.t <= near:
        _copy_row(Y_out, k, y)
        k += 1
    return k


@njit(inline="always")
def _radau_plan(s_, b, g, e, t_target):
    """The next step's length, and whether it lands on ``t_target``: a step within
    ``_LANDING_STRETCH`` of it is cut (or stretched) to end there, from the compensated time
    t₀ + t_comp (t_target − t₀ is exact once t₀ ≥ t_target/2, Sterbenz: the state is
    integrated over exactly the span the clock advances, leaving no time shift at a landing),
    its prediction rescaled for that length."""
    dt = s_.h
    landing = s_.t + dt * (1.0 + _LANDING_STRETCH) >= t_target
    if landing:
        dt = (t_target - s_.t) - s_.t_comp
        _radau_rescale(b, g, e, dt / s_.h)  # the prediction, for this step's length
    return dt, landing


@njit(inline="always")
def _radau_control(s_, b, g, e, b_start, dy, cost, converged, a_floor, eps, dt, dt_first, n):
    """After the iteration of the step of dt: its cost counted and the controller's proposal
    for the next step. A step whose iteration did not converge, or whose proposal is below a
    quarter of it, is rejected: it is to be iterated again with the proposal, from the
    prediction it started from (``b_start``, for length ``dt_first``). Returns (NOT_FINITE
    where the expansion is not finite, else OK; whether to iterate again; the step to take
    or iterate; the proposal)."""
    s_.n_evaluations += cost[0]
    s_.n_iterations += cost[1]
    status = Status.OK
    again = False
    dt_new = dt
    if not _finite_row(b, 6, n + 2):
        status = Status.NOT_FINITE
    else:
        dt_new = _radau_proposal(b, dy, a_floor, eps, dt, n)
        if not converged:
            dt_new = min(dt_new, 0.25 * dt)
        if dt_new < 0.25 * dt or not converged:
            # rejected: the prediction the step started from, for the shorter step
            s_.n_rejected += 1
            _copy_matrix(b, b_start)
            _radau_rescale(b, g, e, dt_new / dt_first)
            again = True
            dt = dt_new
    return status, again, dt, dt_new


@njit(inline="always")
def _radau_proposal(b, dy, a_floor, eps, dt, n):
    """The next step the controller proposes, from the accelerations' last coefficient (the
    work rates do not act back on the motion, and may be round-off around zero)."""
    big_b6 = 0.0
    big_a = a_floor
    for j in range(n):
        big_b6 = max(big_b6, abs(b[6, j]))
        big_a = max(big_a, abs(dy[n + j]))
    err = big_b6 / big_a if big_a > 0.0 else 0.0
    return dt * (eps / err) ** (1.0 / 7.0) if err > 0.0 else 4.0 * dt


@njit(inline="always")
def _radau_end_state(n, y, comp, F0, b, dt, inc, y_new, comp_new):
    """The state at the step's end (with its compensation), not committed. Returns (whether
    it is finite, the local error estimate, the state's scale)."""
    _radau_increments(n, y, F0, b, dt, inc)
    _copy(y_new, y)
    _copy(comp_new, comp)
    local = 0.0
    scale = 1.0
    for j in range(n):
        local = max(local, abs(b[6, j]) * _RADAU_X[6] * dt * dt)
    for i in range(2 * n + 2):
        _kahan(y_new, comp_new, i, inc[i])
    finite = True
    for i in range(2 * n):
        finite = finite and math.isfinite(y_new[i])
        scale = max(scale, abs(y_new[i]))
    return finite, local, scale


@njit(inline="always")
def _radau_end_time(landing, t0, tc0, dt, t_target):
    """The time at the step's end, compensated too (or exactly the output time landed on)."""
    dtc = dt + tc0
    t_new = t0 + dtc
    if landing:
        return t_target, 0.0
    return t_new, dtc - (t_new - t0)


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _radau_event(ks, s_, mode, t_out, Y_out, k, b8, F0, y, comp, t0, tc0, dt, p, w_floor,
                 cost, t_new, y_new, g_old, g_new, ev_dir):
    """The earliest event in the step just taken (event functions ``g_old`` at its start,
    ``g_new`` at its end, a sign change among them), located on the step's interior: the
    outputs before it written, the state left at it (status EVENT, the cost counted).
    Returns (status, next output index, the output to redo the step to, landing there, where
    a side step did not converge, or -1); NOT_CONVERGED where a side step of the search did
    not converge."""
    first = -1
    t_ev = t_new
    for i in range(ks.n_ev):
        if _crossed(g_old[i], g_new[i], ev_dir[i]):
            ti = _locate_event(ks, mode, b8, F0, y, comp, t0, tc0, dt, p, w_floor, cost, i, t0,
                               g_old[i], t_new, g_new[i])
            if math.isnan(ti):  # a side step of the search did not converge
                return Status.NOT_CONVERGED, k, -1
            if first < 0 or ti < t_ev:
                first = i
                t_ev = ti
    k2 = _radau_outputs(ks, mode, t_out, Y_out, k, t_ev, y_new, False, b8, F0, y, comp, t0, tc0,
                        dt, p, w_floor, cost)
    if k2 < 0:
        return Status.OK, k, -k2 - 1
    if t_ev < t_new:
        if not _state_in_step(ks, mode, t_ev, b8, F0, y, comp, t0, tc0, dt, p, w_floor, cost,
                              y_new):
            return Status.NOT_CONVERGED, k2, -1
        if ks.n_c > 0:
            ks.project(t_ev, y_new, p)
    _count_cost(s_, cost)
    y[:] = y_new
    comp[:] = 0.0
    s_.t = t_ev
    s_.t_comp = 0.0
    s_.f0_ready = 0
    s_.n_steps += 1
    s_.last_event = first
    s_.n_events += 1
    return Status.EVENT, k2, -1


@njit(inline="always")
def _outputs_written(k2, k):
    """(next output index, output to redo the step to or -1) from ``_radau_outputs``'s
    answer: the next index, or −(index + 1) where a side step did not converge."""
    return (k2, -1) if k2 >= 0 else (k, -k2 - 1)


@njit(inline="always")
def _count_cost(s_, cost):
    s_.n_evaluations += cost[0]
    s_.n_iterations += cost[1]
    s_.n_side += cost[2]


@njit(inline="always")
def _radau_commit(ks, s_, y, comp, y_new, comp_new, t_new, tc_new, g_old, g_new, F0, F1, error,
                  dt):
    """Take the step: its end becomes the state, f there the next step's F₀."""
    _copy(y, y_new)
    _copy(comp, comp_new)
    s_.t = t_new
    s_.t_comp = tc_new
    if ks.n_ev > 0:
        _copy(g_old, g_new)
    _copy(F0, F1)
    s_.f0_ready = 1
    s_.error_estimate += error
    s_.n_steps += 1
    s_.h_old = dt


@njit(inline="always")
def _radau_next_step(s_, b, g, e, dt, dt_new, iterations, rho, landing):
    """The next step: the controller's proposal, at most four times this one, shorter where
    the iteration converged slowly (forces depending strongly on velocities, or stiff ones: a
    longer step would not converge within the iteration budget); a step shortened to land
    keeps the controller's plan. The expansion moved to it as its prediction (from F = F₀
    where it is too far to extrapolate)."""
    planned = s_.h
    dt_new = min(dt_new, 4.0 * dt)
    if iterations > _RADAU_SLOW and rho > _RADAU_CONTRACTION:
        dt_new = min(dt_new, dt * _RADAU_CONTRACTION / rho)
    if landing:
        dt_new = max(dt_new, planned)
    q = dt_new / dt
    if q <= 4.0:
        _radau_predict(b, g, e, q)
    else:
        _zero_matrix(b)
        _zero_matrix(g)
        _zero_matrix(e)
    s_.h = dt_new


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
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
            _copy_row(Y_out, k, y_end)
        else:
            if not _state_in_step(ks, mode, t, b, F0, y0, comp0, t0, tc, dt, p, w_floor, cost,
                                  Y_out[k]):
                return -(k + 1)
            if ks.n_c > 0:
                ks.project(t, Y_out[k], p)
        k += 1
    return k
