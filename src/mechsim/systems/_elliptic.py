"""Jacobi's elliptic functions and the elliptic integrals of the first and third kinds, for
the closed forms of the torque-free rigid body (``_rigid``) and the simple pendulum. Not a
system (leading underscore).

Every function takes the parameter m together with its complement m1 = 1 − m, each accurate on
its own: near a separatrix m1 is small, and 1 − m computed from m would keep few of its digits
(scipy's ``ellipj`` and ``ellipkinc`` take m alone). The integrals use Carlson's symmetric forms
R_F and R_J (DLMF 19.16, 19.36), compiled for the per-sample loops of the closed forms.

Conventions (Abramowitz & Stegun 16–17): u = F(φ | m) = ∫₀^φ dθ/√(1 − m sin²θ), am u = φ,
sn u = sin φ, cn u = cos φ, dn u = √(1 − m sn²u); Π(n; φ | m) = ∫₀^φ dθ/((1 − n sin²θ)
√(1 − m sin²θ)).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def agm_ratios(m: float, m1: float) -> tuple[np.ndarray, float]:
    """The ratios c_k/a_k of the arithmetic–geometric mean from a₀ = 1, b₀ = √m1, c₀ = √m
    (Abramowitz & Stegun 16.4) and 2^N a_N, which start the descending recursion for am u."""
    a, b, c = 1.0, math.sqrt(m1), math.sqrt(m)
    ratios = np.empty(_AGM_MAX)
    n = 0
    # c_{k+1} ≈ c_k²/4a: once below 1e-15 a, the next ratio would change am by less than
    # round-off (a − b can stall at an ulp instead of reaching 0)
    while c > 1e-15 * a and n < _AGM_MAX:
        a, b, c = 0.5 * (a + b), math.sqrt(a * b), 0.5 * (a - b)
        ratios[n] = c / a
        n += 1
    return ratios[:n][::-1].copy(), (2.0 ** n) * a


#: The most AGM steps ``agm_ratios`` takes.
_AGM_MAX = 60


@njit(cache=True)
def am_dn(u: float, ratios: np.ndarray, scale: float, m1: float) -> tuple[float, float]:
    """am u and dn u (``jacobi_amplitude``) from ``agm_ratios`` (ratios last-first)."""
    if m1 == 0.0:
        return 2.0 * math.atan(math.tanh(0.5 * u)), 1.0 / math.cosh(u)
    phi = scale * u
    for r in ratios:
        phi = 0.5 * (phi + math.asin(r * math.sin(phi)))
    c = math.cos(phi)
    return phi, math.sqrt(m1 + (1.0 - m1) * c * c)


@njit(cache=True)
def sn_cn_dn(u: float, ratios: np.ndarray, a_n: float, m1: float) -> tuple[float, float, float]:
    """sn u, cn u and dn u from ``agm_ratios`` (ratios last-first; ``a_n`` = a_N, its scale
    divided by 2^N) by the descending Landen transformation (A&S 16.12.2–4): with
    √μ = c_k/a_k, sn(u | m) = (1 + √μ) sn(v | μ) / (1 + √μ sn²(v | μ)), cn(u | m) =
    cn(v | μ) dn(v | μ) / (1 + √μ sn²), dn(v | μ) likewise with 1 − √μ sn², from
    sn = sin(a_N u), cn = cos(a_N u), dn = 1 at the last parameter (below round-off); dn u at
    the top as √(m1 + m cn²), as ``am_dn``. One sine and one cosine a call, where ``am_dn``
    takes a sine and an arcsine at every level; the same values to a few ulps of 1. On the
    separatrix (m1 = 0) sn u = tanh u, cn u = dn u = sech u."""
    if m1 == 0.0:
        sech = 1.0 / math.cosh(u)
        return math.tanh(u), sech, sech
    v = a_n * u
    s, c, d = math.sin(v), math.cos(v), 1.0
    for r in ratios:
        s2 = s * s
        inv = 1.0 / (1.0 + r * s2)
        s, c, d = (1.0 + r) * s * inv, c * d * inv, (1.0 - r * s2) * inv
    return s, c, math.sqrt(m1 + (1.0 - m1) * c * c)


@njit(cache=True)
def _amplitudes(u: np.ndarray, ratios: np.ndarray, scale: float, m1: float,
                am: np.ndarray, dn: np.ndarray) -> None:
    for k in range(u.size):
        am[k], dn[k] = am_dn(u[k], ratios, scale, m1)


def jacobi_amplitude(u: np.ndarray, m: float, m1: float) -> tuple[np.ndarray, np.ndarray]:
    """The amplitude φ = am(u | m) (continuous, increasing in u) and dn(u | m), for the
    parameter m given with its complement m1 = 1 − m, each accurate on its own (near the
    separatrix m1 is small and 1 − m would keep few of its digits; scipy's ``ellipj`` takes m
    alone): the descending recursion φ_{k−1} = ½(φ_k + asin((c_k/a_k) sin φ_k)) from
    φ_N = 2^N a_N u (A&S 16.4), and dn = √(m1 + m cn²), a sum of two positive terms (A&S's
    cos φ / cos(φ₁ − φ) is 0/0 at u = K); on the separatrix (m1 = 0) am u = gd u,
    dn u = sech u."""
    u = np.ascontiguousarray(u, dtype=float)
    ratios, scale = agm_ratios(m, m1)
    am, dn = np.empty_like(u), np.empty_like(u)
    _amplitudes(u.ravel(), ratios, scale, m1, am.ravel(), dn.ravel())
    return am, dn


def jacobi_elliptic(u: np.ndarray, m: float, m1: float) -> tuple[np.ndarray, ...]:
    """sn, cn, dn of u from m and m1 = 1 − m (``jacobi_amplitude``)."""
    phi, dn = jacobi_amplitude(u, m, m1)
    return np.sin(phi), np.cos(phi), dn


#: Carlson's duplication stops once the arguments agree to this (relative): the series then
#: leaves an error of its sixth power, below round-off.
_CARLSON_SPREAD = 1e-3


@njit(cache=True)
def carlson_rf(x: float, y: float, z: float) -> float:
    """R_F(x, y, z) = ½∫₀^∞ dt/√((t+x)(t+y)(t+z)), x, y, z ≥ 0, at most one zero: duplication
    x ← (x + λ)/4 (λ = √x√y + √y√z + √z√x), then the series in X = 1 − x/A, … (A the mean):
    (1 − E₂/10 + E₃/14 + E₂²/24 − 3E₂E₃/44)/√A, E₂ = XY − Z², E₃ = XYZ (Carlson 1995;
    DLMF 19.36.1)."""
    for _ in range(200):
        A = (x + y + z) / 3.0
        X, Y = 1.0 - x / A, 1.0 - y / A
        Z = -(X + Y)
        if max(abs(X), abs(Y), abs(Z)) < _CARLSON_SPREAD:
            break
        sx, sy, sz = math.sqrt(x), math.sqrt(y), math.sqrt(z)
        lam = sx * sy + sy * sz + sz * sx
        x, y, z = 0.25 * (x + lam), 0.25 * (y + lam), 0.25 * (z + lam)
    E2, E3 = X * Y - Z * Z, X * Y * Z
    return (1.0 - E2 / 10.0 + E3 / 14.0 + E2 * E2 / 24.0 - 3.0 * E2 * E3 / 44.0) / math.sqrt(A)


@njit(cache=True)
def carlson_rf_rj(x: float, y: float, z: float, p: float) -> tuple[float, float]:
    """R_F(x, y, z) and R_J(x, y, z, p) = (3/2)∫₀^∞ dt/((t+p)√((t+x)(t+y)(t+z))), for
    p ≥ max(x, y, z) (the case of ``elliptic_pi`` with n ≤ 0; then every R_C below is an
    arctangent), from one duplication of x, y, z and p (R_F is invariant under it, so its
    series is taken at the last x, y, z). R_J: each step adds 6·4^{−k} R_C(1, 1 + e_k)/d_k,
    d_k = (√p+√x)(√p+√y)(√p+√z), e_k = 4^{−3k}δ/d_k², δ = (p−x)(p−y)(p−z); then the series
    4^{−K} A_K^{−3/2}(1 − 3E₂/14 + E₃/6 + 9E₂²/88 − 3E₄/22 − 9E₂E₃/52 + 3E₅/26) in
    X = (A₀ − x)/(4^K A_K), …, P = −(X + Y + Z)/2 (Carlson 1995; DLMF 19.36.2)."""
    A0 = (x + y + z + 2.0 * p) / 5.0
    delta = (p - x) * (p - y) * (p - z)
    A, fac, total = A0, 1.0, 0.0
    x0, y0, z0 = x, y, z
    for _ in range(200):
        X, Y, Z = (A0 - x0) * fac / A, (A0 - y0) * fac / A, (A0 - z0) * fac / A
        if max(abs(X), abs(Y), abs(Z), abs(0.5 * (X + Y + Z))) < _CARLSON_SPREAD:
            break
        sx, sy, sz, sp = math.sqrt(x), math.sqrt(y), math.sqrt(z), math.sqrt(p)
        lam = sx * sy + sy * sz + sz * sx
        d = (sp + sx) * (sp + sy) * (sp + sz)
        e = delta * fac * fac * fac / (d * d)
        rc = 1.0 - e / 3.0 + e * e / 5.0 if e < 1e-6 else math.atan(math.sqrt(e)) / math.sqrt(e)
        total += fac * rc / d
        fac *= 0.25
        x, y, z, p = 0.25 * (x + lam), 0.25 * (y + lam), 0.25 * (z + lam), 0.25 * (p + lam)
        A = 0.25 * (A + lam)
    P = -0.5 * (X + Y + Z)
    E2 = X * Y + X * Z + Y * Z - 3.0 * P * P
    E3 = X * Y * Z + 2.0 * E2 * P + 4.0 * P * P * P
    E4 = (2.0 * X * Y * Z + E2 * P + 3.0 * P * P * P) * P
    E5 = X * Y * Z * P * P
    series = (1.0 - 3.0 * E2 / 14.0 + E3 / 6.0 + 9.0 * E2 * E2 / 88.0 - 3.0 * E4 / 22.0
              - 9.0 * E2 * E3 / 52.0 + 3.0 * E5 / 26.0)
    return carlson_rf(x, y, z), fac * series / (A * math.sqrt(A)) + 6.0 * total


@njit(cache=True)
def third_kind(n: float, phi: float, m1: float, whole: float) -> float:
    """Π(n; φ | m) (``elliptic_pi``), ``whole`` = Π(n | m) (read only when |φ| > π/2)."""
    k = np.round(phi / math.pi)
    r = phi - k * math.pi
    s, c = math.sin(r), math.cos(r)
    c2, s2 = c * c, s * s
    y = c2 + m1 * s2
    rf, rj = carlson_rf_rj(c2, y, 1.0, 1.0 - n * s2)
    part = s * rf + (n / 3.0) * s * s2 * rj
    return part + 2.0 * k * whole if k != 0.0 else part


def elliptic_pi(n: float, phi: np.ndarray, m1: float) -> np.ndarray:
    """The incomplete integral of the third kind Π(n; φ | m) = ∫₀^φ dθ / ((1 − n sin²θ)
    √(1 − m sin²θ)) (A&S 17.2.15) for n ≤ 0 and any real φ, from m1 = 1 − m: for
    |φ| ≤ π/2, s R_F(c², c² + m1 s², 1) + (n/3) s³ R_J(c², c² + m1 s², 1, 1 − n s²)
    (s = sin φ, c = cos φ; DLMF 19.25.14), and Π(n; φ + kπ) = Π(n; φ) + 2k Π(n | m)."""
    phi = np.asarray(phi, dtype=float)
    whole = complete_third_kind(n, m1) if np.any(np.abs(phi) > 0.5 * math.pi) else 0.0
    return np.array([third_kind(n, float(f), m1, whole) for f in phi.ravel()]).reshape(
        phi.shape)


def complete_third_kind(n: float, m1: float) -> float:
    """Π(n | m) = R_F(0, m1, 1) + (n/3) R_J(0, m1, 1, 1 − n) (∞ on the separatrix)."""
    if m1 == 0.0:
        return math.inf
    rf, rj = carlson_rf_rj(0.0, m1, 1.0, 1.0 - n)
    return float(rf + (n / 3.0) * rj)


@njit(cache=True)
def elliptic_f(phi: float, m1: float) -> float:
    """The incomplete integral F(φ | m) for φ ∈ [−π, π] from m1 = 1 − m: sin φ R_F(cos²φ,
    cos²φ + m1 sin²φ, 1) (Carlson), and F(φ) = 2K − F(π − φ) beyond π/2."""
    if abs(phi) > 0.5 * math.pi:
        whole = 2.0 * carlson_rf(0.0, m1, 1.0)
        rest = math.pi - abs(phi)
        s, c = math.sin(rest), math.cos(rest)
        return math.copysign(whole - s * carlson_rf(c * c, c * c + m1 * s * s, 1.0), phi)
    s, c = math.sin(phi), math.cos(phi)
    return s * carlson_rf(c * c, c * c + m1 * s * s, 1.0)  # type: ignore[no-any-return]
