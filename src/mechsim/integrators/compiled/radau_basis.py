"""The Gauss–Radau expansion of radau15 (the IAS15 scheme, Rein & Spiegel 2015, MNRAS 446,
1424): its nodes and the constants derived from them, and the algebra of the expansion of the
second derivatives within a step, F(s) = F₀ + Σ_k b_k s^(k+1), s = (t − t₀)/dt: the state it
integrates to, its divided differences g, its move to the next step, the step's increments,
the dense output's expansion and the bound of its error."""

import math

import numpy as np
from numba import njit

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


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
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


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
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


@njit(inline="always")
def _radau_g_from_b(b, g):
    """The divided differences g of the expansion b (g = (Cᵀ)⁻¹ b, upper triangular)."""
    m = b.shape[1]
    for j in range(m):
        for k in range(7):
            acc = 0.0
            for i in range(k, 7):
                acc += _RADAU_D[k, i] * b[i, j]
            g[k, j] = acc


@njit(inline="always")
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


@njit(inline="always")
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


@njit(inline="always")
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


@njit(inline="always")
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


@njit(inline="always")
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
