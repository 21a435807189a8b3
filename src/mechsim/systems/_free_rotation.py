"""The torque-free motion of a rigid body in closed form (``free_rotation``): Jacobi elliptic
functions for the body angular velocity ω, the precession angle about the fixed angular momentum
L for the attitude, evaluated by compiled loops that vectorize (Fourier series of one period
where they converge fast, term by term otherwise). ``_rigid.QuaternionRigidBody`` offers it as
``propagate`` (method ``exact``) whenever no torque acts; ``symmetric_top`` uses its building
blocks for the heavy top's closed form. Source: PHYS0500 – Advanced Classical Mechanics,
§7.7–7.8 (Euler's equations, force-free motion), with Landau & Lifshitz, Mechanics §37."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numba import njit

from mechsim.codegen.contract import CLOSED_FORM_SIGNATURE
from mechsim.systems._elliptic import (
    _amplitudes,
    agm_ratios,
    am_dn,
    carlson_rf,
    complete_third_kind,
    elliptic_f,
    third_kind,
)
from mechsim.systems._rotation import quat_from_rows, quat_product


@njit(cache=True, inline="always")
def _qmul(ax: float, ay: float, az: float, aw: float, bx: float, by: float, bz: float,
          bw: float) -> tuple[float, float, float, float]:
    """a ⊗ b on components (``quat_product`` unrolled for the loop below)."""
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


@njit(cache=True, inline="always", error_model="numpy")
def _half_angle(y: float, x: float, r: float) -> tuple[float, float]:
    """cos and sin of ½ atan2(y, x), r = √(x² + y²), without trigonometry: with
    h = √(2r(r + |x|)), for x ≥ 0 the cosine (r + x)/h and the sine y/h, else the sine
    ±(r − x)/h (the sign of y, −0 included) and the cosine |y|/h (so that no difference
    cancels); at the origin atan2's 0 (x = +0) or ±π (x = −0), as at (±1, ±0). Selections
    only, no calls: it vectorizes in ``_attitude_rows``."""
    if r == 0.0:
        x, r = math.copysign(1.0, x), 1.0
    big = r + abs(x)
    h = math.sqrt(2.0 * r * big)
    if x >= 0.0:
        return big / h, y / h
    return abs(y) / h, math.copysign(big / h, y)


@njit(cache=True, inline="always", error_model="numpy")
def _euler_frame(na: float, ni: float, nj: float, cf: float, sf: float, flip: float
                 ) -> tuple[float, float, float, float]:
    """q_z(φ) ⊗ q_x(θ) ⊗ q_z(ψ), θ and ψ from L/|L| = (n_i, n_j, n_a) in body axes (i, j, a)
    (``free_rotation``), cf, sf = cos, sin φ/2: (sin θ/2 cos(φ−ψ)/2, sin θ/2 sin(φ−ψ)/2,
    cos θ/2 sin(φ+ψ)/2, cos θ/2 cos(φ+ψ)/2), with θ = atan2(|L_⊥|, L_a) and
    ψ = atan2(flip L_i, flip L_j) (+ π when flipped); the half angles of θ and ψ algebraically
    (``_half_angle``), those of φ ± ψ by the addition theorems."""
    perp = math.sqrt(ni * ni + nj * nj)
    ch, sh = _half_angle(perp, na, math.sqrt(na * na + perp * perp))
    cp, sp = _half_angle(flip * ni, flip * nj, perp)
    if flip < 0.0:  # ψ/2 + π/2
        cp, sp = -sp, cp
    cd, sd = cf * cp + sf * sp, sf * cp - cf * sp  # (φ − ψ)/2
    cs, ss = cf * cp - sf * sp, sf * cp + cf * sp  # (φ + ψ)/2
    return sh * cd, sh * sd, ch * ss, ch * cs


@njit(cache=True, inline="always")
def _dot4(f: tuple[float, float, float, float], e: tuple[float, float, float, float]) -> float:
    """f · e of two 4-tuples."""
    return f[0] * e[0] + f[1] * e[1] + f[2] * e[2] + f[3] * e[3]


#: Cody and Waite's reduction by π/2 = P1 + P2 + P3 (+ 8.5e-32), P1 and P2 short enough
#: (31, 32 significant bits) that n P1 and n P2 are exact for |n| < 2²¹, and the minimax
#: polynomials of sin and cos on [−π/4, π/4] (fdlibm's e_rem_pio2.c, k_sin.c, k_cos.c).
_TWO_OVER_PI = 6.36619772367581382433e-01
_PIO2 = (1.57079632673412561417e+00, 6.07710050630396597660e-11, 2.02226624871116645580e-21)
_SIN = (-1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04,
        2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10)
_COS = (4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05,
        -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11)
#: Adding and subtracting 1.5 · 2⁵² rounds a double below 2⁵¹ to the nearest integer.
_ROUND = 6755399441055744.0
#: ``_cos_sin`` reduces arguments up to this (|n| ≤ 2¹⁹) itself, larger ones by ``math``.
_REDUCED = 2.0 ** 19


@njit(cache=True, fastmath={"contract"})
def _cos_sin(x: np.ndarray, c: np.ndarray, s: np.ndarray) -> None:
    """c = cos x, s = sin x, elementwise, within an ulp of ``math.cos``, ``math.sin`` (which
    they call for |x| > ``_REDUCED`` and non-finite x): x = nπ/2 + r, |r| ≤ π/4, then sin r
    and cos r by polynomials and the quadrant n mod 4 by selections, so that the loop has no
    calls and vectorizes (``math.sin`` and ``math.cos`` in a loop cost 15 ns a pair)."""
    for k in range(x.size):
        v = x[k]
        n = (v * _TWO_OVER_PI + _ROUND) - _ROUND
        r = ((v - n * _PIO2[0]) - n * _PIO2[1]) - n * _PIO2[2]
        z = r * r
        sr = r + (r * z) * (_SIN[0] + z * (_SIN[1] + z * (_SIN[2] + z * (
            _SIN[3] + z * (_SIN[4] + z * _SIN[5])))))
        hz = 0.5 * z
        w = 1.0 - hz  # 1 − z/2 + the polynomial, its rounding error carried (k_cos.c)
        cr = w + (((1.0 - w) - hz) + z * z * (_COS[0] + z * (_COS[1] + z * (_COS[2] + z * (
            _COS[3] + z * (_COS[4] + z * _COS[5]))))))
        q = np.int64(n) & 3
        sa, ca = (cr, sr) if q & 1 else (sr, cr)
        s[k] = -sa if q & 2 else sa
        c[k] = -ca if (q + 1) & 2 else ca
    for k in range(x.size):
        if not abs(x[k]) <= _REDUCED:
            c[k], s[k] = math.cos(x[k]), math.sin(x[k])


#: Samples evaluated together by ``_torque_free_motion`` (its scratch rows stay in cache).
_BLOCK = 256
#: The rows of ``_torque_free_motion``'s scratch: times after t₀, u, dn u, am u, Π(−N; am u),
#: φ/2, their cosines and sines, then q, q̇ and ω (``_attitude_rows``).
_TAU, _U, _DN, _AM, _TURN, _HALF, _COS_AM, _SIN_AM, _COS_HALF, _SIN_HALF = range(10)
_Q, _QDOT, _OMEGA = 10, 14, 18
_ROWS = 21


@njit(cache=True, fastmath={"contract"})  # fused multiply-adds: one rounding less per step
def _clenshaw(coef: np.ndarray, n: int, x: np.ndarray, b1: np.ndarray, b2: np.ndarray
              ) -> None:
    """b1 = b₀, b2 = b₁ of Clenshaw's recurrence b_k = (c_k − b_{k+2}) + x b_{k+1} over the
    first n coefficients c_k, at every x (= 2 cos θ; the sums Σ c_k cos (k+1)θ = b₀ cos θ − b₁
    and Σ c_k sin (k+1)θ = b₀ sin θ): the samples in the inner loop, independent of each other
    so that it vectorizes, two steps per pass so that neither needs a swap."""
    m = x.size
    for j in range(m):
        b1[j] = 0.0
        b2[j] = 0.0
    k = n - 1
    while k >= 1:  # b1 holds b_{k+1}, b2 b_{k+2}
        ck, ck1 = coef[k], coef[k - 1]
        for j in range(m):
            b2[j] = (ck - b2[j]) + x[j] * b1[j]
            b1[j] = (ck1 - b1[j]) + x[j] * b2[j]
        k -= 2
    if k == 0:
        c0 = coef[0]
        for j in range(m):
            b = (c0 - b2[j]) + x[j] * b1[j]
            b2[j] = b1[j]
            b1[j] = b


@njit(cache=True, fastmath={"contract"})
def _series_sums(rates: np.ndarray, coefs: np.ndarray, terms: np.ndarray, u: np.ndarray,
                 dn: np.ndarray, am: np.ndarray, turn: np.ndarray) -> None:
    """dn u, am u and Π(−N; am u) at each u from ``_period_series`` (``_clenshaw`` for each
    sum, over its own number of terms)."""
    m = u.size
    work = np.empty((5, m))
    c, s, x, b1, b2 = work[0], work[1], work[2], work[3], work[4]
    for k in range(m):
        x[k] = rates[0] * u[k]  # θ
    _cos_sin(x, c, s)
    for k in range(m):
        x[k] = 2.0 * c[k]
    for r in range(3):  # one call of ``_clenshaw``: compiled once
        _clenshaw(coefs[r], terms[r], x, b1, b2)
        if r == 0:
            for k in range(m):
                dn[k] = rates[1] + (b1[k] * c[k] - b2[k])
        else:
            out, rate = (am, rates[1]) if r == 1 else (turn, rates[2])
            for k in range(m):
                out[k] = rate * u[k] + b1[k] * s[k]


@njit(cache=True, inline="always")
def _pick(axis: int, a: int, b: int, va: float, vb: float, vc: float) -> float:
    """The component along body axis ``axis`` of a vector given along a, b and the third."""
    return va if axis == a else (vb if axis == b else vc)


@njit(cache=True, error_model="numpy")
def _attitude_rows(work: np.ndarray, m: int, c: np.ndarray, axes: np.ndarray, Iw: np.ndarray,
                   frame: np.ndarray) -> None:
    """ω, q = F e (F = ``frame``, e the Euler frame) and q̇ = ½ q ⊗ (ω, 0) into the rows
    _OMEGA, _Q, _QDOT of ``work`` from cos am, sin am, dn and cos, sin φ/2 in its rows
    (``_torque_free_motion``), for its first m samples. Selections only, no calls, no
    branches on the samples and no exceptions (numpy's error model): the loop vectorizes."""
    # read once: ``work`` could alias them for all the compiler knows
    amp_a, amp_b, amp_c, flip = c[9], c[10], c[11], c[12]
    a, b, cc = axes[0], axes[1], axes[2]
    i_is_b = axes[3] == b
    Ia, Ib, Ic = Iw[a], Iw[b], Iw[cc]
    F0 = (frame[0, 0], frame[0, 1], frame[0, 2], frame[0, 3])
    F1 = (frame[1, 0], frame[1, 1], frame[1, 2], frame[1, 3])
    F2 = (frame[2, 0], frame[2, 1], frame[2, 2], frame[2, 3])
    F3 = (frame[3, 0], frame[3, 1], frame[3, 2], frame[3, 3])
    for k in range(m):
        wa = amp_a * work[_COS_AM, k]
        wb = amp_b * work[_SIN_AM, k]
        wc = amp_c * work[_DN, k]
        na, nb, nc = Ia * wa, Ib * wb, Ic * wc
        e = _euler_frame(na, nb if i_is_b else nc, nc if i_is_b else nb, work[_COS_HALF, k],
                         work[_SIN_HALF, k], flip)
        q = (_dot4(F0, e), _dot4(F1, e), _dot4(F2, e), _dot4(F3, e))
        w = (_pick(0, a, b, wa, wb, wc), _pick(1, a, b, wa, wb, wc), _pick(2, a, b, wa, wb, wc))
        qd = _qmul(q[0], q[1], q[2], q[3], w[0], w[1], w[2], 0.0)
        for r in range(4):
            work[_Q + r, k] = q[r]
            work[_QDOT + r, k] = 0.5 * qd[r]
        for r in range(3):
            work[_OMEGA + r, k] = w[r]


@njit(cache=True, error_model="numpy")
def _torque_free_motion(t: np.ndarray, t0: float, c: np.ndarray, ratios: np.ndarray,
                        axes: np.ndarray, Iw: np.ndarray, frame: np.ndarray, rates: np.ndarray,
                        coefs: np.ndarray, terms: np.ndarray, y0: np.ndarray, rows: np.ndarray,
                        W: np.ndarray) -> None:
    """Rows [q, q̇ = ½ q ⊗ (ω, 0), y0[8:]] (as many columns as ``rows`` has) and ω (unless W
    has no rows) of ``free_rotation`` at each time t − t₀ (see there), the arguments between
    t₀ and y0 those of ``EllipticMotion``: φ = (λ/I_a) t − λ(I_c − I_a)/(I_a I_c ν)
    (Π(−N; am u) − Π(−N; am u₀)), q = F e (``frame``), e the Euler frame. am u, dn u and
    Π(−N; am u) from the Fourier series ``rates``, ``coefs`` (``_period_series``) where it has
    terms, else by ``am_dn`` and ``third_kind``. Block by block of samples, each step over a
    whole block at once (the loops vectorize; only the rows are written sample by sample)."""
    nu, u0, scale, m1, N, whole, turn0 = c[0], c[1], c[2], c[3], c[4], c[5], c[6]
    precession, wobble = c[7], c[8]
    series = coefs.shape[1] > 0
    n = t.size
    work = np.empty((_ROWS, min(n, _BLOCK)))
    tau, u, am, dn, turn, half = (work[_TAU], work[_U], work[_AM], work[_DN], work[_TURN],
                                  work[_HALF])
    for start in range(0, n, _BLOCK):
        m = min(n - start, _BLOCK)
        for k in range(m):
            tau[k] = t[start + k] - t0
            u[k] = nu * tau[k] + u0
        if series:
            _series_sums(rates, coefs, terms, u[:m], dn, am, turn)
        else:
            for k in range(m):
                am[k], dn[k] = am_dn(u[k], ratios, scale, m1)
                turn[k] = third_kind(-N, am[k], m1, whole)
        for k in range(m):
            half[k] = 0.5 * (precession * tau[k] - wobble * (turn[k] - turn0))  # φ/2
        for r in range(2):  # one call of ``_cos_sin``: compiled once
            angle = am if r == 0 else half
            _cos_sin(angle[:m], work[_COS_AM + 2 * r], work[_SIN_AM + 2 * r])
        _attitude_rows(work, m, c, axes, Iw, frame)
        for k in range(m):
            row = start + k
            for r in range(8):
                rows[row, r] = work[_Q + r, k]
            for r in range(8, rows.shape[1]):
                rows[row, r] = y0[r]
            if W.shape[0]:
                for r in range(3):
                    W[row, r] = work[_OMEGA + r, k]


@njit(CLOSED_FORM_SIGNATURE, cache=True)
def packed_motion_rows(t0: float, y0: np.ndarray, t: np.ndarray, c: np.ndarray,
                       rows: np.ndarray) -> bool:
    """``_torque_free_motion`` from the ``EllipticMotion`` ``pack`` laid out in ``c``: its
    arrays as views of c (the integer ones as copies), of the types the tuple's own have."""
    o = np.empty(9, np.int64)
    o[0] = 8
    for k in range(8):
        o[k + 1] = o[k] + int(c[k])
    coefs = c[o[6]:o[7]]
    _torque_free_motion(t, t0, c[o[0]:o[1]], c[o[1]:o[2]], c[o[2]:o[3]].astype(np.int64),
                        c[o[3]:o[4]], c[o[4]:o[5]].reshape((4, 4)), c[o[5]:o[6]],
                        coefs.reshape((3, coefs.size // 3)), c[o[7]:o[8]].astype(np.int64),
                        y0, rows, np.empty((0, 3)))
    return True


def pack(motion: EllipticMotion) -> np.ndarray:
    """``motion``'s arrays as one, for ``packed_motion_rows``: their sizes, then each flat."""
    parts = [np.ravel(a).astype(np.float64) for a in motion]
    return np.concatenate([np.array([p.size for p in parts], np.float64), *parts])


def free_rotation(moments: tuple[float, float, float], q0: np.ndarray, w0: np.ndarray,
                  t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows [q, q̇] of the attitude q(t) ((x, y, z, w), world_R_body) and its rate
    q̇ = ½ q ⊗ (ω, 0), and rows of the body ω(t), of a torque-free rigid body with principal
    moments ``moments`` from q(0) = q0, ω(0) = w0 (any times; compiled, block by block of
    samples, ``_torque_free_motion``): ``free_rotation_at(free_motion(moments, q0, w0), t)``.

    ω(t) (Landau & Lifshitz, Mechanics §37; catalog 003 §7.7 [SUPPLEMENT]): with the moments
    relabelled so that the polhode circles axis c (the largest moment if |L|² > 2E I_mid, else
    the smallest), b the intermediate and a the other extreme axis,
    ω_a = A_a cn u, ω_b = ±A_b sn u, ω_c = ±A_c dn u, u = ν t + u₀ (``jacobi_elliptic``), with
    A_a² = (2E I_c − L²)/(I_a(I_c − I_a)), A_b² = (2E I_c − L²)/(I_b(I_c − I_b)),
    A_c² = (L² − 2E I_a)/(I_c(I_c − I_a)), ν² = (I_c − I_b)(L² − 2E I_a)/(I_a I_b I_c),
    m = (I_b − I_a)(2E I_c − L²)/((I_c − I_b)(L² − 2E I_a)). The differences 2E I_c − L² and
    L² − 2E I_a, which vanish near steady spins and decide the side of the separatrix, are
    summed from same-signed terms (no cancellation); the sign of ω_b follows the sense in which
    Euler's equations turn (ω_a, ω_b), u₀ = F(am₀ | m); m and 1 − m are each computed from
    the ω components, so that both stay accurate near the separatrix. A body of revolution is
    the case m = 0 (uniform precession of ω about the symmetry axis); a spin about a principal
    axis (ω̇ = 0) is uniform rotation.

    Attitude: L is fixed in space; in a frame with L along z the body's z-x-z Euler angles
    taken about body axis a are θ = ∠(L, a), ψ = atan2(L_i, L_j) (i, j, a cyclic), continuous
    because L_c keeps its sign, and φ̇ = |L|(2E − I_a ω_a²)/(|L|² − I_a² ω_a²) (L&L eq. 37.14
    about axis a; the denominator I_b²ω_b² + I_c²ω_c² stays away from zero), integrated in
    closed form with the elliptic integral of the third kind (``elliptic_pi``; L&L §37 give
    the same angle through theta functions).
    """
    return free_rotation_at(free_motion(moments, q0, w0), t)


#: Passed to ``_torque_free_motion`` for "no ω rows".
_NONE = np.empty((0, 3))


def free_rotation_at(motion: FreeMotion, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``free_rotation`` from its constants ``motion`` (``free_motion``) at the times t."""
    t = np.ascontiguousarray(t, dtype=float)
    if isinstance(motion, UniformSpin):
        q0, w0, speed, axis = motion
        half = 0.5 * speed * t
        turn = (axis[0] * np.sin(half), axis[1] * np.sin(half), axis[2] * np.sin(half),
                np.cos(half))
        Q = quat_product(tuple(q0), turn)
        Qd = quat_product(Q, (w0[0], w0[1], w0[2], 0.0))
        return (np.stack([*Q, *(0.5 * x for x in Qd)], axis=1),
                np.repeat(w0[None, :], t.size, axis=0))
    rows, W = np.empty((t.size, 8)), np.empty((t.size, 3))
    _torque_free_motion(t, 0.0, *motion, np.empty(0), rows, W)
    return rows, W


class UniformSpin(NamedTuple):
    """``free_motion`` at rest or spinning about a principal axis: ω = w0 constant,
    q(t) = q0 ⊗ exp(ω t / 2), ``speed`` = |ω|, ``axis`` = ω/|ω| (z at rest)."""

    q0: np.ndarray
    w0: np.ndarray
    speed: float
    axis: np.ndarray


class EllipticMotion(NamedTuple):
    """``free_motion`` off the principal axes: the arguments of ``_torque_free_motion``
    between t₀ and y0 (see ``free_motion`` for their meaning)."""

    #: (ν, u₀, 2^N a_N, m1, N, Π(−N | m), Π(−N; am u₀), λ/I_a, λ(I_c − I_a)/(I_a I_c ν), A_a,
    #: ±A_b, ±A_c, flip)
    consts: np.ndarray
    #: ``agm_ratios`` (for ``am_dn``)
    ratios: np.ndarray
    #: body axes (a, b, c, i, j), i, j, a cyclic
    axes: np.ndarray
    #: I/|L|
    Iw: np.ndarray
    #: 4 × 4: the Euler frame e ↦ q = g ⊗ e ⊗ p*
    frame: np.ndarray
    #: ``_period_series``: π/K, π/2K, Π(−N | m)/K
    rates: np.ndarray
    #: ``_period_series``: (3, n) coefficients of dn, am, Π(−N; am)
    coefs: np.ndarray
    #: the number of coefficients each of the three series uses (none: term by term)
    terms: np.ndarray


#: What ``free_motion`` returns.
FreeMotion = EllipticMotion | UniformSpin


def free_motion(moments: tuple[float, float, float], q0: np.ndarray, w0: np.ndarray
                ) -> FreeMotion:
    """The constants of ``free_rotation`` from q(0) = q0, ω(0) = w0 (see there)."""
    I = np.asarray(moments, dtype=float)
    w0 = np.asarray(w0, dtype=float)
    q0 = np.asarray(q0, dtype=float)
    q0 = q0 / math.sqrt(float(q0 @ q0))
    Lb = I * w0
    lam = math.sqrt(float(Lb @ Lb))
    # Euler's equations, torque-free: I ω̇ = L × ω
    w_dot = np.array([Lb[1] * w0[2] - Lb[2] * w0[1], Lb[2] * w0[0] - Lb[0] * w0[2],
                      Lb[0] * w0[1] - Lb[1] * w0[0]]) / I
    if lam == 0.0 or not np.any(w_dot):
        # at rest, or spinning about a principal axis: ω constant, q(t) = q0 ⊗ exp(ω t / 2)
        speed = float(np.linalg.norm(w0))
        axis = w0 / speed if speed > 0 else np.array([0.0, 0.0, 1.0])
        return UniformSpin(q0, w0, speed, axis)
    order = np.argsort(I, kind="stable")
    mid = int(order[1])
    # which axis the polhode circles: sign of |L|² − 2E I_mid, summed without cancellation
    side = float(np.sum(I * w0 * w0 * (I - I[mid])))
    c, a = (int(order[2]), int(order[0])) if side >= 0.0 else (int(order[0]), int(order[2]))
    b = mid
    Ia, Ib, Ic = I[a], I[b], I[c]
    wa, wb, wc = w0[a], w0[b], w0[c]
    d_c = Ia * wa * wa * (Ic - Ia) + Ib * wb * wb * (Ic - Ib)  # 2E I_c − L²
    d_a = Ib * wb * wb * (Ib - Ia) + Ic * wc * wc * (Ic - Ia)  # L² − 2E I_a
    amp_a = math.sqrt(d_c / (Ia * (Ic - Ia)))
    amp_b = math.sqrt(d_c / (Ib * (Ic - Ib))) if Ic != Ib else 0.0
    amp_c = math.sqrt(d_a / (Ic * (Ic - Ia)))
    nu = math.sqrt((Ic - Ib) * d_a / (Ia * Ib * Ic))
    m = min(max((Ib - Ia) * d_c / ((Ic - Ib) * d_a), 0.0), 1.0) if Ic != Ib else 0.0
    # 1 − m = (I_c − I_a)(L² − 2E I_b)/((I_c − I_b)(L² − 2E I_a)), the separatrix distance
    # summed from the ω components (not 1 − m, which would lose its digits near m = 1)
    near = Ia * wa * wa * (Ia - Ib) + Ic * wc * wc * (Ic - Ib)
    m1 = min(max((Ic - Ia) * near / ((Ic - Ib) * d_a), 0.0), 1.0) if Ic != Ib else 1.0
    x0 = min(max(wa / amp_a, -1.0), 1.0) if amp_a > 0 else 1.0
    y0 = min(max(wb / amp_b, -1.0), 1.0) if amp_b > 0 else 0.0
    sense = x0 * (w_dot[b] / amp_b if amp_b > 0 else 0.0) - y0 * (w_dot[a] / amp_a)
    s_b = 1.0 if sense >= 0.0 else -1.0
    s_c = 1.0 if wc >= 0.0 else -1.0
    am0 = math.atan2(s_b * y0, x0)
    u0 = elliptic_f(am0, m1)  # so am(u0) = am0
    # φ = (λ/I_a) t − λ(I_c − I_a)/(I_a I_c ν) [Π(−N; am u) − Π(−N; am u₀)], N = I_a(2E I_c
    # − L²)/(I_c(L² − 2E I_a)): φ̇ = (λ/I_a)[1 − (L² − 2E I_a)/(L² − I_a²ω_a²)] with
    # L² − I_a²ω_a² = I_c²A_c²(1 + N sn²u), and ∫du/(1 + N sn²u) = Π(−N; am u | m).
    N = Ia * d_c / (Ic * d_a)
    ratios, scale = agm_ratios(m, m1)
    whole = complete_third_kind(-N, m1)
    turn0 = third_kind(-N, am0, m1, whole)
    i, j = (a + 1) % 3, (a + 2) % 3
    # L_c keeps its sign: flip both arguments of ψ's atan2 when c = j and L_c < 0, so that ψ
    # never meets the branch cut
    flip = -1.0 if (c == j and Lb[c] < 0.0) else 1.0
    perm = np.zeros((3, 3))
    perm[0, i] = perm[1, j] = perm[2, a] = 1.0  # v_(i, j, a) = P v
    p = np.empty(4)
    quat_from_rows(perm, p)  # the quaternion of Pᵀ
    consts = np.array([nu, u0, scale, m1, N, whole, turn0, lam / Ia,
                       lam * (Ic - Ia) / (Ia * Ic * nu), amp_a, s_b * amp_b, s_c * amp_c,
                       flip])
    rates, coefs, terms = _period_series(ratios, scale, m1, N, whole)
    if coefs.shape[1]:  # Π(−N; am u₀) from the same series
        sums = np.empty((3, 1))
        _series_sums(rates, coefs, terms, np.array([u0]), sums[0], sums[1], sums[2])
        consts[6] = sums[2, 0]
    motion = EllipticMotion(consts, ratios, np.array([a, b, c, i, j]), I / lam, np.eye(4),
                            rates, coefs, terms)
    # q = g ⊗ e ⊗ p*, e the Euler frame, g = q0 ⊗ p ⊗ e(0)*: ``frame`` the matrix of e ↦ q;
    # e(0) as every other sample's e (the identity frame gives it), so that q(0) = q0
    e0 = free_rotation_at(motion, np.zeros(1))[0][0]
    g = quat_product(quat_product(q0, p), (-e0[0], -e0[1], -e0[2], e0[3]))
    p_conj = (-p[0], -p[1], -p[2], p[3])
    frame = np.stack([quat_product(quat_product(g, e), p_conj) for e in np.eye(4)], axis=1)
    return motion._replace(frame=frame)


#: Fourier series of one period of dn u and 1/(1 + N sn²u) are kept up to the last
#: coefficient above this (relative to the function's mean): beyond, terms are below round-off
#: (the FFT's own round-off is about 1e-16); sampled densely enough once the upper half of the
#: spectrum is below ten times it.
SERIES_FLOOR = 1e-16
#: The most samples per period tried for the series; a motion needing more (close to the
#: separatrix, where the period 2K grows without bound) is evaluated term by term instead.
SERIES_MAX_SAMPLES = 2048


def period_spectra(sample: Callable[[int], np.ndarray],
                   size: Callable[[np.ndarray, np.ndarray], np.ndarray]
                   ) -> tuple[np.ndarray, list[int]] | None:
    """The cosine spectra (real parts of the FFT, times 2/M: f = c₀/2 + Σ cₙ cos nθ) of
    periodic functions even about the start of their period, from ``sample(M)``, their rows at
    M equispaced points of one period, M doubled from 64 until the upper half of each spectrum
    is below ten times ``SERIES_FLOOR`` × its ``size(f, spec)`` (their coefficients fall
    geometrically, the FFT's own round-off is about 1e-16); with how many coefficients each
    takes, up to its first at the floor (later ones are noise). None where that needs more
    than ``SERIES_MAX_SAMPLES`` samples."""
    M = 64
    while M <= SERIES_MAX_SAMPLES:
        f = sample(M)
        spec = np.fft.rfft(f, axis=1).real * (2.0 / M)
        floor = size(f, spec)
        if np.all(np.abs(spec[:, M // 4:]).max(axis=1) <= 10.0 * SERIES_FLOOR * floor):
            low = np.abs(spec[:, 1:]) <= SERIES_FLOOR * floor[:, None]
            return spec, [int(np.argmax(row)) if row.any() else row.size for row in low]
        M *= 2
    return None


def _period_series(ratios: np.ndarray, scale: float, m1: float, N: float, whole: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """dn u and Π(−N; am u) as Fourier series over the period 2K of u, for ``_torque_free_motion``
    to evaluate in a few operations per sample instead of the descending recursion and
    Carlson's R_F, R_J: with θ = πu/K, dn u = π/2K + Σ dₙ cos nθ, so am u = ∫dn =
    πu/2K + Σ dₙ (K/nπ) sin nθ, and likewise 1/(1 + N sn²u) = Π(−N | m)/K + Σ fₙ cos nθ gives
    Π(−N; am u) = (Π(−N | m)/K) u + Σ fₙ (K/nπ) sin nθ. The coefficients come from samples
    of one period (FFT), doubled until the upper half of the spectrum is below round-off
    (both functions are analytic, so the coefficients fall geometrically). Returns ``rates``
    (π/K, π/2K, Π(−N | m)/K), ``coefs`` (3, n): dₙ, then the sine coefficients of am and
    Π, and ``terms``, how many of them each sum takes (up to its first coefficient at
    round-off: the series of Π often falls more slowly than that of dn); no terms where the
    series would need more than ``SERIES_MAX_SAMPLES`` samples or the motion is on the
    separatrix."""
    none = np.empty(3), np.empty((3, 0)), np.zeros(3, dtype=np.int64)
    if m1 == 0.0 or not math.isfinite(whole):
        return none
    K = float(carlson_rf(0.0, m1, 1.0))
    rates = np.array([math.pi / K, 0.5 * math.pi / K, whole / K])

    def sample(M: int) -> np.ndarray:
        am, dn = np.empty(M), np.empty(M)
        _amplitudes(2.0 * K * np.arange(M) / M, ratios, scale, m1, am, dn)
        return np.stack([dn, 1.0 / (1.0 + N * np.sin(am) ** 2)])

    found = period_spectra(sample, lambda f, spec: np.abs(0.5 * spec[:, 0]))
    if found is None:
        return none
    spec, (n_dn, n_turn) = found
    n = max(n_dn, n_turn)
    k = np.arange(1, n + 1)
    d, fn = spec[0, 1:n + 1], spec[1, 1:n + 1]
    return (rates, np.stack([d, d * K / (k * math.pi), fn * K / (k * math.pi)]),
            np.array([n_dn, n_dn, n_turn]))
