"""The rigid-body benchmark problems (``mechsim.bench.problems``): the torque-free body
(Euler's equations; references from Jacobi's elliptic functions, Landau & Lifshitz §37) and
Lagrange's heavy top (Goldstein §5.7), and the attitudes they compare."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.special import ellipj, ellipk, ellipkinc

from mechsim.bench.problem import Array, Problem


# --- attitudes --------------------------------------------------------------------------------
def _quat_from_matrices(R: Array) -> Array:
    """Unit quaternions (x, y, z, w) of rotation matrices (m, 3, 3)."""
    from scipy.spatial.transform import Rotation

    return np.asarray(Rotation.from_matrix(R).as_quat())


def _euler_zxz_matrices(phi: Array, theta: Array, psi: Array) -> Array:
    """R_z(φ) R_x(θ) R_z(ψ) for arrays of angles: shape (m, 3, 3)."""
    from scipy.spatial.transform import Rotation

    return np.asarray(Rotation.from_euler("ZXZ", np.stack([phi, theta, psi], axis=1))
                      .as_matrix())


def _attitude_compare(omega_scale: float) -> Callable[[Array], Array]:
    """Compared state [q, ω/Ω] of a (q, ω) rigid-body state (the quaternion normalised)."""
    def compare(Y: Array) -> Array:
        q = Y[:, :4] / np.linalg.norm(Y[:, :4], axis=1)[:, None]
        return np.concatenate([q, Y[:, 4:7] / omega_scale], axis=1)
    return compare


def _mechsim_attitude(frame: str, omega_scale: float) -> Callable[[Any, Array, Array], Array]:
    """Compared state [q, ω/Ω] from mechsim's published frame ``frame`` (world_R_body) and its
    observables ``omega_1..3`` (body angular velocity), whatever its state layout."""
    def convert(model: Any, t: Array, rows: Array) -> Array:
        from mechsim.simulate import evaluate

        out = evaluate(model, np.ascontiguousarray(t), np.ascontiguousarray(rows),
                       model.parameter_vector(), ("observables", "frames"))
        assert out.frames is not None
        k = [f.child for f in model.frames].index(frame)
        q = out.frames[:, k, 3:7]
        w = np.stack([out.observables[f"omega_{i}"] for i in (1, 2, 3)], axis=1)
        return np.concatenate([q, w / omega_scale], axis=1)
    return convert


# --- rigid_body (torque-free, Euler's equations) ----------------------------------------------
def _rigid_body_deriv(t: float, y: Array, p: Array, dy: Array) -> None:
    # p = [I1, I2, I3]; y = [q (x, y, z, w), ω (body)]: q̇ = ½ q ⊗ (ω, 0), Euler's equations.
    x, yy, z, w = y[0], y[1], y[2], y[3]
    w1, w2, w3 = y[4], y[5], y[6]
    dy[0] = 0.5 * (w * w1 + yy * w3 - z * w2)
    dy[1] = 0.5 * (w * w2 + z * w1 - x * w3)
    dy[2] = 0.5 * (w * w3 + x * w2 - yy * w1)
    dy[3] = -0.5 * (x * w1 + yy * w2 + z * w3)
    dy[4] = (p[1] - p[2]) * w2 * w3 / p[0]
    dy[5] = (p[2] - p[0]) * w3 * w1 / p[1]
    dy[6] = (p[0] - p[1]) * w1 * w2 / p[2]


def jacobi_elliptic_longdouble(u: Array, m1: Any) -> tuple[Array, Array, Array]:
    """sn, cn, dn (``np.longdouble``) of u for the parameter m = 1 − m1, by the arithmetic-
    geometric mean (Abramowitz & Stegun 16.4), with the complementary parameter m1 given
    directly: near m = 1 (near a separatrix) it carries the precision that m = 1 − m1 would
    lose in rounding. Accurate to ~|u| × 1e-19."""
    L = np.longdouble
    m1 = L(m1)
    a, b, c = [L(1)], np.sqrt(m1), [np.sqrt(L(1) - m1)]
    while abs(c[-1]) > L(1e-19) * a[-1] and len(a) < 40:
        an, bn, cn = (a[-1] + b) / 2, np.sqrt(a[-1] * b), (a[-1] - b) / 2
        a.append(an)
        c.append(cn)
        b = bn
    n = len(a) - 1
    phi = L(2) ** n * a[n] * np.asarray(u, dtype=L)
    prev = phi
    for k in range(n, 0, -1):
        prev = phi
        phi = (phi + np.arcsin(c[k] / a[k] * np.sin(phi))) / 2
    return np.sin(phi), np.cos(phi), np.cos(phi) / np.cos(prev - phi)


def free_rigid_body_omega(inertia: Array, w0: Array) -> Callable[[Array], Array]:
    """ω(t) (m, 3; ``np.longdouble``) of the torque-free body, I₁ < I₂ < I₃, from Jacobi's
    elliptic functions (Landau & Lifshitz §37). For |L|² > 2E I₂ (rotation about axis 3):
    ω = (A₁ cn u, s A₂ sn u, s A₃ dn u), u = λt + u₀, s = sign ω₃; for |L|² < 2E I₂ the same
    with axes 1 and 3 exchanged and ω reversed (which keeps Euler's equations, with the phase
    running backwards). The constants come from mpmath at 40 digits (near the separatrix
    1 − m ∝ |L|² − 2E I₂ cancels), the functions from :func:`jacobi_elliptic_longdouble`."""
    import mpmath

    I = [float(v) for v in inertia]
    w = [float(v) for v in w0]
    if not (I[0] < I[1] < I[2]):
        raise ValueError("principal moments must be ascending and distinct")
    with mpmath.workdps(40):
        Im, wm = [mpmath.mpf(v) for v in I], [mpmath.mpf(v) for v in w]
        M2 = sum((i * x) ** 2 for i, x in zip(Im, wm, strict=True))
        E2 = sum(i * x * x for i, x in zip(Im, wm, strict=True))
        flip = M2 < E2 * Im[1]
        if flip:
            Im, wm = Im[::-1], [-x for x in wm[::-1]]
        I1, I2, I3 = Im
        A1 = mpmath.sqrt((E2 * I3 - M2) / (I1 * (I3 - I1)))
        A2 = mpmath.sqrt((E2 * I3 - M2) / (I2 * (I3 - I2)))
        A3 = mpmath.sqrt((M2 - E2 * I1) / (I3 * (I3 - I1)))
        lam = mpmath.sqrt((I3 - I2) * (M2 - E2 * I1) / (I1 * I2 * I3))
        den = (I3 - I2) * (M2 - E2 * I1)
        m = (I2 - I1) * (E2 * I3 - M2) / den
        m1 = (I3 - I1) * (M2 - E2 * I2) / den
        s = 1 if wm[2] >= 0 else -1
        u0 = mpmath.ellipf(mpmath.atan2(s * wm[1] / A2, wm[0] / A1), m)
        L = np.longdouble
        c = [L(mpmath.nstr(v, 30)) for v in (A1, A2, A3, lam, u0, m1)]
    sign = L(-1) if flip else L(1)

    def omega(t: Array) -> Array:
        u = c[4] + sign * c[3] * np.asarray(t, dtype=L)
        sn, cn, dn = jacobi_elliptic_longdouble(u, c[5])
        W = np.stack([c[0] * cn, s * c[1] * sn, s * c[2] * dn], axis=-1)
        return -W[..., ::-1] if flip else W
    return omega


def free_rigid_body_period(inertia: Array, w0: Array) -> float:
    """Period of ω(t) of the torque-free body: 4K(m)/λ (K of 1 − m, accurate near m = 1)."""
    from scipy.special import ellipkm1

    I = [float(v) for v in inertia]
    M2 = sum((i * float(x)) ** 2 for i, x in zip(I, w0, strict=True))
    E2 = sum(i * float(x) ** 2 for i, x in zip(I, w0, strict=True))
    if M2 < E2 * I[1]:
        I = I[::-1]
    I1, I2, I3 = I
    den = (I3 - I2) * (M2 - E2 * I1)
    lam = math.sqrt(den / (I1 * I2 * I3))
    return 4 * float(ellipkm1((I3 - I1) * (M2 - E2 * I2) / den)) / lam


def _cumulative_quadrature(f: Callable[[Array], Array], t: Array, h_max: float) -> Array:
    """∫₀^t f at each sample time (f vectorised; nodes, weights and sums in ``np.longdouble``):
    20-point Gauss–Legendre on pieces of at most ``h_max`` between samples (f smooth: exact
    to round-off for pieces well under its time scale)."""
    L = np.longdouble
    x, wts = (v.astype(L) for v in np.polynomial.legendre.leggauss(20))
    out = np.zeros(t.size, dtype=L)
    for i in range(1, t.size):
        k = max(1, math.ceil((t[i] - t[i - 1]) / h_max))
        edges = L(t[i - 1]) + (L(t[i]) - L(t[i - 1])) * np.arange(k + 1, dtype=L) / k
        mid, half = (edges[1:] + edges[:-1]) / 2, np.diff(edges) / 2
        nodes = (mid[:, None] + half[:, None] * x[None, :]).ravel()
        out[i] = out[i - 1] + np.sum((half[:, None] * wts[None, :]).ravel() * f(nodes))
    return out


def free_rigid_body_attitude(inertia: Array, w0: Array, R0: Array, t: Array,
                             h_max: float = 0.01) -> tuple[Array, Array]:
    """(world_R_body matrices (m, 3, 3), ω (m, 3)) of the torque-free body. In a frame A with
    z along the fixed L, world_R_body = R_A R_z(φ) R_x(θ) R_z(ψ) with cos θ = I₃ω₃/|L|,
    tan ψ = I₁ω₁/(I₂ω₂) and φ̇ = |L|(I₁ω₁² + I₂ω₂²)/(I₁²ω₁² + I₂²ω₂²), integrated by
    Gauss–Legendre quadrature (Landau & Lifshitz §37)."""
    L = np.longdouble
    I = np.asarray(inertia, dtype=float)
    t = np.asarray(t, dtype=float)
    omega = free_rigid_body_omega(I, w0)
    W = omega(t)
    Lb0 = I * np.asarray(w0, dtype=float)
    z = R0 @ Lb0 / np.linalg.norm(Lb0)
    e = np.eye(3)[int(np.argmin(np.abs(z)))]
    x = np.cross(e, z)
    x /= np.linalg.norm(x)
    RA = np.stack([x, np.cross(z, x), z], axis=1)
    RAB0 = RA.T @ R0
    phi0 = math.atan2(RAB0[0, 2], -RAB0[1, 2])
    IL = I.astype(L)
    M = np.sqrt(np.sum((IL * np.asarray(w0, dtype=L)) ** 2))

    def phidot(tau: Array) -> Array:
        w = omega(tau)
        a, b = IL[0] * w[:, 0] ** 2, IL[1] * w[:, 1] ** 2
        return M * (a + b) / (IL[0] * a + IL[1] * b)

    two_pi = L(2) * L("3.14159265358979323846264338327950288")
    phi = np.mod(L(phi0) + _cumulative_quadrature(phidot, t, h_max), two_pi).astype(float)
    Lb = (IL * W).astype(float)
    theta = np.arctan2(np.hypot(Lb[:, 0], Lb[:, 1]), Lb[:, 2])
    psi = np.arctan2(Lb[:, 0], Lb[:, 1])
    return RA[None, :, :] @ _euler_zxz_matrices(phi, theta, psi), W.astype(float)


def _rigid_body(name: str, omega: tuple[float, float, float], t_end: float, n_samples: int,
                what: str) -> Problem:
    mass, size = 1.0, (0.3, 0.2, 0.1)  # mechsim's default box; its principal axes are x, y, z
    a, b, c = size
    I = mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    angles = (0.3, 0.7, -0.4)  # initial attitude, z-x-z Euler angles
    R0 = _euler_zxz_matrices(*(np.array([v]) for v in angles))[0]
    q0 = _quat_from_matrices(R0[None])[0]
    w0 = np.array(omega, dtype=float)
    scale = float(np.linalg.norm(w0))

    def reference(t: Array) -> Array:
        R, W = free_rigid_body_attitude(I, w0, R0, t)
        return np.concatenate([_quat_from_matrices(R), W], axis=1)

    def twice_kinetic(t: Array, C: Array) -> Array:
        return np.sum(I * (C[:, 4:7] * scale) ** 2, axis=1)

    params = {"shape": "box", "mass": mass, "size.x": a, "size.y": b, "size.z": c,
              "initial.phi": angles[0], "initial.theta": angles[1], "initial.psi": angles[2],
              **{f"initial.omega_{i + 1}": float(w0[i]) for i in range(3)}}
    M2, E2 = float(np.sum((I * w0) ** 2)), float(np.sum(I * w0 * w0))
    return Problem(name, "rigid_body", params, t_end, n_samples,
                   f"torque-free box {a}×{b}×{c} m, {mass} kg (I = {I[0]:.4g}, {I[1]:.4g}, "
                   f"{I[2]:.4g} kg m²), ω₀ = {omega} rad/s {what}, |L|²/(2E I₂) = "
                   f"{M2 / (E2 * I[1]):.6f}, period of ω {free_rigid_body_period(I, w0):.4g} s; "
                   f"{t_end:g} s",
                   _rigid_body_deriv, I.copy(), np.concatenate([q0, w0]), reference,
                   "closed form (ω: Jacobi sn, cn, dn; attitude: Euler angles about L, φ by "
                   "Gauss–Legendre quadrature)", 2 * math.pi / scale, twice_kinetic,
                   "kinetic energy", compare=_attitude_compare(scale),
                   from_mechsim=_mechsim_attitude("principal", scale), sign_free=slice(0, 4),
                   extra={"omega_scale": scale})


def rigid_body_intermediate(t_end: float = 50.0, n_samples: int = 200) -> Problem:
    return _rigid_body("rigid_body_intermediate", (0.02, 4.0, 0.02), t_end, n_samples,
                       "near the intermediate axis (it flips over every half period)")


def rigid_body_generic(t_end: float = 50.0, n_samples: int = 200) -> Problem:
    return _rigid_body("rigid_body_generic", (3.0, 1.0, 2.0), t_end, n_samples,
                       "(tumbling about axis 1)")


# --- heavy_top (Lagrange's top, Euler angles z-x-z) -------------------------------------------
def _heavy_top_deriv(t: float, y: Array, p: Array, dy: Array) -> None:
    # p = [I1, I3, MgR]; y = [φ, θ, ψ, φ̇, θ̇, ψ̇]; θ from the upward vertical, V = MgR cos θ.
    # L = ½I₁(θ̇² + φ̇² sin²θ) + ½I₃ω₃² − MgR cos θ, ω₃ = ψ̇ + φ̇ cos θ (constant).
    I1, I3, mgr = p[0], p[1], p[2]
    th, dphi, dth, dpsi = y[1], y[3], y[4], y[5]
    s, c = math.sin(th), math.cos(th)
    w3 = dpsi + dphi * c
    ddphi = dth * (I3 * w3 - 2.0 * I1 * c * dphi) / (I1 * s)
    dy[0] = dphi
    dy[1] = dth
    dy[2] = dpsi
    dy[3] = ddphi
    dy[4] = (I1 * dphi * dphi * s * c - I3 * w3 * dphi * s + mgr * s) / I1
    dy[5] = -ddphi * c + dphi * s * dth


def heavy_top_reference(I1: float, I3: float, mgr: float, init: Array, t: Array) -> Array:
    """[φ, θ, ψ, φ̇, θ̇, ψ̇] of Lagrange's top at ``t`` (see the module docstring)."""
    phi0, th0, psi0, dphi0, dth0, dpsi0 = (float(v) for v in init)
    u0 = math.cos(th0)
    w3 = dpsi0 + dphi0 * u0
    a = I3 * w3 / I1
    b = (I1 * math.sin(th0) ** 2 * dphi0 + I3 * w3 * u0) / I1
    beta = 2 * mgr / I1
    alpha = dth0**2 + dphi0**2 * math.sin(th0) ** 2 + beta * u0
    coeffs = [beta, -(alpha + a * a), 2 * a * b - beta, alpha - b * b]
    roots = np.sort(np.roots(coeffs).real)
    dcoeffs = np.polyder(coeffs)
    for _ in range(3):  # polish with Newton
        roots = roots - np.polyval(coeffs, roots) / np.polyval(dcoeffs, roots)
    u1, u2, u3 = (float(r) for r in roots)
    m = (u2 - u1) / (u3 - u1)
    kappa = math.sqrt(beta * (u3 - u1)) / 2
    s0 = min(max((u0 - u1) / (u2 - u1), 0.0), 1.0)
    c = float(ellipkinc(math.asin(math.sqrt(s0)), m))
    if -math.sin(th0) * dth0 < 0:  # u̇(0) < 0
        c = -c

    def u_of(tt: Array) -> tuple[Array, Array]:
        sn, cn, dn, _ = ellipj(kappa * np.asarray(tt, dtype=float) + c, m)
        return u1 + (u2 - u1) * sn * sn, 2 * (u2 - u1) * kappa * sn * cn * dn

    def phidot(uu: Array) -> Array:
        return (b - a * uu) / (1 - uu * uu)

    def u_phidot(tt: Array) -> Array:
        uu = u_of(tt)[0]
        return uu * phidot(uu)

    t = np.asarray(t, dtype=float)
    h = 2 * float(ellipk(m)) / kappa / 40  # 40 pieces per nutation period
    phi = phi0 + _cumulative_quadrature(lambda tt: phidot(u_of(tt)[0]), t, h)
    slip = _cumulative_quadrature(u_phidot, t, h)  # ∫ u φ̇ dt
    u, du = u_of(t)
    th = np.arccos(u)
    dphi = phidot(u)
    return np.stack([phi, th, psi0 + w3 * t - slip, dphi, -du / np.sin(th),
                     w3 - u * dphi], axis=1).astype(float)


def heavy_top(t_end: float = 10.0, n_samples: int = 200) -> Problem:
    # mechsim's default top (symmetric_top, quaternion formulation), released with φ̇ = θ̇ = 0:
    # it nutates in cusps.
    M, g, R, I1, I3 = 1.0, 9.81, 0.1, 0.02, 0.01
    mgr = M * g * R
    init = np.array([0.0, 0.6, 0.0, 0.0, 0.0, 40.0])  # φ, θ, ψ, φ̇, θ̇, ψ̇
    phi, th, psi, dphi, dth, dpsi = init
    w0 = np.array([dphi * math.sin(th) * math.sin(psi) + dth * math.cos(psi),
                   dphi * math.sin(th) * math.cos(psi) - dth * math.sin(psi),
                   dphi * math.cos(th) + dpsi])
    scale = float(np.linalg.norm(w0))

    def compare(Y: Array) -> Array:
        phi, th, psi, dphi, dth, dpsi = Y.T
        q = _quat_from_matrices(_euler_zxz_matrices(phi, th, psi))
        w = np.stack([dphi * np.sin(th) * np.sin(psi) + dth * np.cos(psi),
                      dphi * np.sin(th) * np.cos(psi) - dth * np.sin(psi),
                      dphi * np.cos(th) + dpsi], axis=1)
        return np.concatenate([q, w / scale], axis=1)

    def energy(t: Array, C: Array) -> Array:
        q = C[:, :4]
        up = (q[:, 3] ** 2 + q[:, 2] ** 2 - q[:, 0] ** 2 - q[:, 1] ** 2) / np.sum(q * q, axis=1)
        w = C[:, 4:7] * scale
        return 0.5 * (I1 * (w[:, 0] ** 2 + w[:, 1] ** 2) + I3 * w[:, 2] ** 2) + mgr * up

    def reference(t: Array) -> Array:
        return heavy_top_reference(I1, I3, mgr, init, t)

    params = {"formulation": "quaternion", "mass": M, "gravity": g, "cm_distance": R,
              "transverse_inertia": I1, "axial_inertia": I3, "initial.phi": phi,
              "initial.theta": th, "initial.psi": psi, "initial_rate.phi": dphi,
              "initial_rate.theta": dth, "initial_rate.psi": dpsi}
    return Problem("heavy_top", "symmetric_top", params, t_end, n_samples,
                   f"heavy symmetric top (Lagrange), M = {M}, g = {g}, R = {R}, I₁ = {I1}, "
                   f"I₃ = {I3}, released at θ₀ = {th} rad with ψ̇₀ = {dpsi} rad/s, φ̇₀ = θ̇₀ = 0 "
                   f"(nutation in cusps); {t_end:g} s; state: Euler angles z-x-z",
                   _heavy_top_deriv, np.array([I1, I3, mgr]), init.copy(), reference,
                   "closed form (cos θ: Jacobi sn²; φ, ψ by Gauss–Legendre quadrature)",
                   2 * math.pi * I1 / (I3 * w0[2]),  # fast top: nutation at I₃ω₃/I₁
                   energy, "energy", compare=compare,
                   from_mechsim=_mechsim_attitude("body", scale), sign_free=slice(0, 4),
                   extra={"omega_scale": scale, "conserved_scale": mgr})
