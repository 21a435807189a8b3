"""Benchmark problems: initial-value problems of mechsim's systems, each with a reference solution.

Each :class:`Problem` holds what every contestant needs: the mechsim system id and parameters
(the mechsim model is built from them), the horizon and sample times, a right-hand side
written here by hand from the same physics, as a user of scipy or numba would write it (not
through mechsim's kernels), the conserved quantity used for the invariant error, and the
reference solution at the sample times.

The right-hand side is ``deriv(t, y, p, dy)``: it writes dy/dt into ``dy`` from the state
``y`` and the parameter vector ``p``, with scalar ``math`` only, so that the same function
runs as plain Python (scipy's ``rhs``, a thin wrapper) and compiles with numba (the
hand-written fixed-step peers). Where q̈ does not depend on q̇ the problem also gives
``accel(t, q, p, a)`` (for the hand-written Yoshida-4); a linear problem gives its matrix
(for the matrix-exponential peer).

States and errors. Each problem has its own state (what its ``deriv`` integrates); errors are
measured on *compared* states, the problem state mapped by ``compare`` (identity except for
attitudes): ``[q, ω/Ω]`` for the rigid body and the top, q the unit quaternion world_R_body
(x, y, z, w; q and −q are the same attitude, so each row is compared with the sign that
matches the reference) and ω the body angular velocity over its initial magnitude Ω, so that
attitude and rate errors weigh alike. mechsim's output is mapped to the same compared states
(``from_mechsim``: its state rows where they are the problem's state, else its published
frames and observables, which do not depend on how mechsim integrates). The end-point error is
‖C − C_ref‖ at the last sample over the largest ‖C_ref‖ of the run (relative to the state
scale); the max error is the same over all samples.

References, each by a method independent of mechsim and of the contestants:

- closed forms: ``pendulum`` released from rest (Jacobi sn, cn), ``kepler`` (Kepler's
  equation), ``driven_oscillator`` (transient + steady state), ``harmonic_oscillator``,
  ``charged_particle_*`` (helix / cycloid with the E×B drift), ``coupled_oscillators_*``
  (normal modes u_r,j ∝ cos((j − ½)rπ/N), ω_r² = (κ + 4κ₁₂ sin²(rπ/2N))/m);
- ``rigid_body_*`` (torque-free, Euler's equations): ω(t) from Jacobi's elliptic functions,
  the attitude from the Euler angles about the fixed L (θ, ψ algebraic in ω, φ the quadrature
  of φ̇ = |L|(I₁ω₁² + I₂ω₂²)/(I₁²ω₁² + I₂²ω₂²); Landau & Lifshitz §37);
- ``heavy_top`` (Lagrange's top): u = cos θ = u₁ + (u₂ − u₁) sn²(κt + c | m) from the roots
  of the cubic f(u) = (1 − u²)(α − βu) − (b − au)², φ and ψ the quadratures of
  φ̇ = (b − au)/(1 − u²) and ψ̇ = I₁a/I₃ − uφ̇ (Goldstein §5.7);
- ``double_pendulum``, ``cr3bp`` and ``spring_pendulum`` (no closed form): a fixed-step run
  of the DOP853 tableau in extended precision (``np.longdouble``, 80-bit on x86: ε ≈ 1.1e-19),
  for the CR3BP in the co-rotating frame (autonomous) and for the spring pendulum in
  Cartesian coordinates (each a formulation other than the contestants'), converted back.
  For the double pendulum (chaotic, λ ≈ 1.9 /s, so a short horizon of 5 s) steps of 1.25 ms
  and of 0.31 ms agree to 4e-15 at the end point and 1.2e-14 over the run, relative to the
  state scale; double precision cannot do this well: scipy Radau and DOP853 at rtol = atol =
  1e-14 agree with each other to 1e-12 at the end point but are 2.7e-12 and 1.7e-12 away from
  the extended-precision run, i.e. round-off amplified by the chaos. Where ``longdouble`` is
  plain double, these references fall back to Radau at 1e-14 (and say so in
  ``reference_kind``).

The tests check every reference against a tight scipy run of the problem's own right-hand
side, and mechsim's trajectory at a tight tolerance against the reference (evidence that the
problem is set up as the mechsim system it names).
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.special import ellipj, ellipk

from mechsim.bench.problem import (
    _FALLBACK,
    EXTENDED,
    Array,
    Problem,
    _fixed_dop853_longdouble,
    _radau_tight,
)
from mechsim.bench.problems_coupled import coupled_oscillators_2, coupled_oscillators_12
from mechsim.bench.problems_rigid import (
    heavy_top,
    rigid_body_generic,
    rigid_body_intermediate,
)


# --- pendulum ---------------------------------------------------------------------------------
def _pendulum_deriv(t: float, y: Array, p: Array, dy: Array) -> None:  # p = [g/R]
    dy[0] = y[1]
    dy[1] = -p[0] * math.sin(y[0])


def _pendulum_accel(t: float, q: Array, p: Array, a: Array) -> None:
    a[0] = -p[0] * math.sin(q[0])


def pendulum(t_end: float = 100.0, n_samples: int = 200, angle: float = 1.0) -> Problem:
    m, R, g = 1.0, 1.0, 9.81
    w0 = math.sqrt(g / R)
    k = math.sin(angle / 2)
    K = float(ellipk(k * k))

    def reference(t: Array) -> Array:
        # Released from rest at φ₀: sin(φ/2) = k sn(K − ω₀t | k²), φ̇ = −2kω₀ cn(K − ω₀t | k²).
        u = np.mod(K - w0 * t, 4 * K)
        sn, cn, _, _ = ellipj(u, k * k)
        return np.stack([2 * np.arcsin(k * sn), -2 * k * w0 * cn], axis=1)

    def energy(t: Array, Y: Array) -> Array:
        return 0.5 * m * R**2 * Y[:, 1] ** 2 + m * g * R * (1 - np.cos(Y[:, 0]))

    e0 = m * g * R * (1 - math.cos(angle))
    return Problem("pendulum", "pendulum", {"formulation": "reduced", "initial.angle": angle},
                   t_end, n_samples, f"simple pendulum released from rest at φ₀ = {angle} rad, "
                   f"g = {g}, R = {R}; {t_end:g} s ≈ {t_end * w0 / (4 * K):.0f} periods",
                   _pendulum_deriv, np.array([g / R]), np.array([angle, 0.0]), reference,
                   "closed form (Jacobi sn, cn)", 4 * K / w0, energy, "energy",
                   peers=("scipy", "handwritten", "mujoco", "drake"), accel=_pendulum_accel,
                   extra={"conserved_scale": e0, "m": m, "R": R, "g": g})


# --- kepler -----------------------------------------------------------------------------------
def _kepler_deriv(t: float, y: Array, p: Array, dy: Array) -> None:  # p = [GM]
    r2 = y[0] * y[0] + y[1] * y[1]
    c = p[0] / (r2 * math.sqrt(r2))
    dy[0] = y[2]
    dy[1] = y[3]
    dy[2] = -c * y[0]
    dy[3] = -c * y[1]


def _kepler_accel(t: float, q: Array, p: Array, a: Array) -> None:
    r2 = q[0] * q[0] + q[1] * q[1]
    c = p[0] / (r2 * math.sqrt(r2))
    a[0] = -c * q[0]
    a[1] = -c * q[1]


def kepler(orbits: float = 100.0, n_samples: int = 200, e: float = 0.5) -> Problem:
    GM, a = 1.0, 1.0
    period = 2 * math.pi * math.sqrt(a**3 / GM)
    n_mean = 2 * math.pi / period
    rp = a * (1 - e)

    def reference(t: Array) -> Array:
        M = np.mod(n_mean * np.asarray(t, dtype=float), 2 * math.pi)
        E = M + e * np.sin(M)
        for _ in range(60):
            dE = (E - e * np.sin(E) - M) / (1 - e * np.cos(E))
            E = E - dE
            if np.max(np.abs(dE)) < 1e-16:
                break
        b = a * math.sqrt(1 - e * e)
        Edot = n_mean / (1 - e * np.cos(E))
        return np.stack([a * (np.cos(E) - e), b * np.sin(E), -a * np.sin(E) * Edot,
                         b * np.cos(E) * Edot], axis=1)

    def energy(t: Array, Y: Array) -> Array:
        r = np.hypot(Y[:, 0], Y[:, 1])
        return 0.5 * (Y[:, 2] ** 2 + Y[:, 3] ** 2) - GM / r

    y0 = np.array([rp, 0.0, 0.0, math.sqrt(GM * (1 + e) / rp)])
    return Problem("kepler", "kepler", {"eccentricity": e}, orbits * period, n_samples,
                   f"Kepler orbit e = {e}, a = 1, GM = 1, from pericentre; {orbits:g} orbits",
                   _kepler_deriv, np.array([GM]), y0, reference,
                   "closed form (Kepler's equation)", period, energy, "energy",
                   peers=("scipy", "handwritten", "rebound"), accel=_kepler_accel,
                   extra={"conserved_scale": GM / (2 * a),
                          "rebound": {"G": GM, "bodies": [(1.0, 0.0, 0.0, 0.0, 0.0)],
                                      "origin": 0, "period": period}})


# --- driven_oscillator ----------------------------------------------------------------------
def _driven_deriv(t: float, y: Array, p: Array, dy: Array) -> None:  # p = [m, k, b, F0, w]
    dy[0] = y[1]
    dy[1] = (p[3] * math.cos(p[4] * t) - p[2] * y[1] - p[1] * y[0]) / p[0]


def driven_oscillator(t_end: float = 100.0, n_samples: int = 200) -> Problem:
    m, k, b, F0, w = 1.0, 4.0, 0.4, 1.0, 1.8
    w0 = math.sqrt(k / m)
    beta = b / (2 * m)
    A = F0 / m
    D = A / math.sqrt((w0**2 - w**2) ** 2 + 4 * w**2 * beta**2)
    delta = math.atan2(2 * w * beta, w0**2 - w**2)
    w1 = math.sqrt(w0**2 - beta**2)
    x0, v0 = 0.0, 0.0
    C = x0 - D * math.cos(delta)
    E = (v0 - D * w * math.sin(delta) + beta * C) / w1

    def reference(t: Array) -> Array:
        ex = np.exp(-beta * t)
        c1, s1 = np.cos(w1 * t), np.sin(w1 * t)
        x = D * np.cos(w * t - delta) + ex * (C * c1 + E * s1)
        v = (-D * w * np.sin(w * t - delta)
             + ex * ((-beta * C + w1 * E) * c1 + (-beta * E - w1 * C) * s1))
        return np.stack([x, v], axis=1)

    return Problem("driven_oscillator", "driven_oscillator", {}, t_end, n_samples,
                   f"m = {m}, k = {k}, b = {b}, F₀ = {F0}, ω = {w}, from rest; {t_end:g} s",
                   _driven_deriv, np.array([m, k, b, F0, w]), np.array([x0, v0]), reference,
                   "closed form (transient + steady state)", 2 * math.pi / w0)


# --- harmonic_oscillator --------------------------------------------------------------------
def _harmonic_deriv(t: float, y: Array, p: Array, dy: Array) -> None:  # p = [k/m]
    dy[0] = y[1]
    dy[1] = -p[0] * y[0]


def _harmonic_accel(t: float, q: Array, p: Array, a: Array) -> None:
    a[0] = -p[0] * q[0]


def harmonic_oscillator(t_end: float = 100.0, n_samples: int = 200) -> Problem:
    m, k, x0, v0 = 1.0, 4.0, 0.5, 0.0
    w0 = math.sqrt(k / m)

    def reference(t: Array) -> Array:
        c, s = np.cos(w0 * t), np.sin(w0 * t)
        return np.stack([x0 * c + v0 / w0 * s, -x0 * w0 * s + v0 * c], axis=1)

    def energy(t: Array, Y: Array) -> Array:
        return 0.5 * m * Y[:, 1] ** 2 + 0.5 * k * Y[:, 0] ** 2

    return Problem("harmonic_oscillator", "harmonic_oscillator", {}, t_end, n_samples,
                   f"m = {m}, k = {k}, x₀ = {x0}; {t_end:g} s ≈ {t_end * w0 / 2 / math.pi:.0f} "
                   "periods", _harmonic_deriv, np.array([k / m]), np.array([x0, v0]),
                   reference, "closed form", 2 * math.pi / w0, energy, "energy",
                   peers=("scipy", "handwritten", "expm"), accel=_harmonic_accel,
                   linear=np.array([[0.0, 1.0], [-k / m, 0.0]]),
                   extra={"conserved_scale": 0.5 * k * x0**2})


# --- double_pendulum --------------------------------------------------------------------------
def _double_pendulum_deriv(t: float, y: Array, p: Array, dy: Array) -> None:
    # p = [m1, m2, l1, l2, g]. Euler–Lagrange equations of L = T − V (derived independently
    # with sympy from the Cartesian bob positions): M(θ) θ̈ = f(θ, θ̇), M 2×2 by Cramer's rule.
    m1, m2, l1, l2, g = p[0], p[1], p[2], p[3], p[4]
    t1, t2, w1, w2 = y[0], y[1], y[2], y[3]
    c, s = math.cos(t1 - t2), math.sin(t1 - t2)
    m11, m12, m22 = (m1 + m2) * l1 * l1, m2 * l1 * l2 * c, m2 * l2 * l2
    f1 = -m2 * l1 * l2 * w2 * w2 * s - (m1 + m2) * g * l1 * math.sin(t1)
    f2 = m2 * l1 * l2 * w1 * w1 * s - m2 * g * l2 * math.sin(t2)
    det = m11 * m22 - m12 * m12
    dy[0] = w1
    dy[1] = w2
    dy[2] = (m22 * f1 - m12 * f2) / det
    dy[3] = (m11 * f2 - m12 * f1) / det


def double_pendulum(t_end: float = 5.0, n_samples: int = 200) -> Problem:
    # Defaults of load_system("double_pendulum") (angles form): absolute angles θ₁, θ₂ from
    # straight down, point masses on massless rods.
    m1, m2, l1, l2, g = 1.0, 1.0, 1.0, 1.0, 9.81
    th1, th2 = 2.0, 2.5
    p = np.array([m1, m2, l1, l2, g])

    def rhs_ext(y: Array) -> Array:  # the same equations in numpy, keeping np.longdouble
        t1, t2, w1, w2 = y
        c, s = np.cos(t1 - t2), np.sin(t1 - t2)
        m11, m12, m22 = (m1 + m2) * l1 * l1, m2 * l1 * l2 * c, m2 * l2 * l2
        f1 = -m2 * l1 * l2 * w2 * w2 * s - (m1 + m2) * g * l1 * np.sin(t1)
        f2 = m2 * l1 * l2 * w1 * w1 * s - m2 * g * l2 * np.sin(t2)
        det = m11 * m22 - m12 * m12
        return np.array([w1, w2, (m22 * f1 - m12 * f2) / det, (m11 * f2 - m12 * f1) / det],
                        dtype=y.dtype)

    y0 = np.array([th1, th2, 0.0, 0.0])
    pb: Problem

    def reference(t: Array) -> Array:
        t = np.asarray(t, dtype=float)
        if EXTENDED:
            return _fixed_dop853_longdouble(rhs_ext, y0, t, 1.25e-3).astype(float)
        return _radau_tight(pb.rhs, y0, t)

    def energy(t: Array, Y: Array) -> Array:
        t1, t2, w1, w2 = Y.T
        T = 0.5 * m1 * l1**2 * w1**2 + 0.5 * m2 * (l1**2 * w1**2 + l2**2 * w2**2 + 2 * l1 * l2
                                                   * w1 * w2 * np.cos(t1 - t2))
        V = (m1 * g * (l1 + l2 - l1 * np.cos(t1))
             + m2 * g * (l1 + l2 - l1 * np.cos(t1) - l2 * np.cos(t2)))
        return T + V

    pb = Problem("double_pendulum", "double_pendulum", {}, t_end, n_samples,
                 f"double pendulum, m₁ = m₂ = {m1}, l₁ = l₂ = {l1}, g = {g}, from rest at "
                 f"θ₁ = {th1}, θ₂ = {th2} rad (chaotic, λ ≈ 1.9 /s); {t_end:g} s",
                 _double_pendulum_deriv, p, y0, reference,
                 "DOP853 tableau, fixed step 1.25 ms, long double (error ~1e-14)" if EXTENDED
                 else _FALLBACK, 2 * math.pi * math.sqrt(l1 / g), energy, "energy",
                 peers=("scipy", "handwritten", "mujoco", "drake"),
                 extra={"m1": m1, "m2": m2, "l1": l1, "l2": l2, "g": g})
    return pb


# --- cr3bp (planar, inertial frame) -----------------------------------------------------------
def _cr3bp_accel(t: float, q: Array, p: Array, a: Array) -> None:
    # p = [G m1, G m2, a1, a2, ω]: primaries at a_k (cos ωt, sin ωt).
    c, s = math.cos(p[4] * t), math.sin(p[4] * t)
    dx1, dy1 = q[0] - p[2] * c, q[1] - p[2] * s
    dx2, dy2 = q[0] - p[3] * c, q[1] - p[3] * s
    r1 = dx1 * dx1 + dy1 * dy1
    r2 = dx2 * dx2 + dy2 * dy2
    k1 = p[0] / (r1 * math.sqrt(r1))
    k2 = p[1] / (r2 * math.sqrt(r2))
    a[0] = -k1 * dx1 - k2 * dx2
    a[1] = -k1 * dy1 - k2 * dy2


def _cr3bp_deriv(t: float, y: Array, p: Array, dy: Array) -> None:
    c, s = math.cos(p[4] * t), math.sin(p[4] * t)
    dx1, dy1 = y[0] - p[2] * c, y[1] - p[2] * s
    dx2, dy2 = y[0] - p[3] * c, y[1] - p[3] * s
    r1 = dx1 * dx1 + dy1 * dy1
    r2 = dx2 * dx2 + dy2 * dy2
    k1 = p[0] / (r1 * math.sqrt(r1))
    k2 = p[1] / (r2 * math.sqrt(r2))
    dy[0] = y[2]
    dy[1] = y[3]
    dy[2] = -k1 * dx1 - k2 * dx2
    dy[3] = -k1 * dy1 - k2 * dy2


def cr3bp(orbits: float = 20.0, n_samples: int = 200, r0: float = 1.8) -> Problem:
    G, m1, m2, L = 1.0, 0.9, 0.1, 1.0
    M = m1 + m2
    w = math.sqrt(G * M / L**3)
    a1, a2 = m2 / M * L, -m1 / M * L
    p = np.array([G * m1, G * m2, a1, a2, w])
    y0 = np.array([r0, 0.0, 0.0, math.sqrt(G * M / r0)])  # circular about the barycentre
    period = 2 * math.pi / w
    pb: Problem

    def synodic_ext(z: Array) -> Array:  # co-rotating frame: autonomous
        xi, eta, dxi, deta = z
        r1 = ((xi - a1) ** 2 + eta**2) ** 1.5
        r2 = ((xi - a2) ** 2 + eta**2) ** 1.5
        return np.array([dxi, deta,
                         2 * w * deta + w * w * xi - G * m1 * (xi - a1) / r1
                         - G * m2 * (xi - a2) / r2,
                         -2 * w * dxi + w * w * eta - G * m1 * eta / r1 - G * m2 * eta / r2],
                        dtype=z.dtype)

    def reference(t: Array) -> Array:
        t = np.asarray(t, dtype=float)
        if not EXTENDED:
            return _radau_tight(pb.rhs, y0, t)
        Ld = np.longdouble
        x, y, vx, vy = (Ld(v) for v in y0)
        z0 = np.array([x, y, vx + Ld(w) * y, vy - Ld(w) * x], dtype=Ld)
        Z = _fixed_dop853_longdouble(synodic_ext, z0, t, 0.01)
        ang = Ld(w) * t.astype(Ld)
        c, s = np.cos(ang), np.sin(ang)
        ux, uy = Z[:, 2] - Ld(w) * Z[:, 1], Z[:, 3] + Ld(w) * Z[:, 0]
        return np.stack([c * Z[:, 0] - s * Z[:, 1], s * Z[:, 0] + c * Z[:, 1],
                         c * ux - s * uy, s * ux + c * uy], axis=1).astype(float)

    def jacobi(t: Array, Y: Array) -> Array:
        c, s = np.cos(w * t), np.sin(w * t)
        r1 = np.hypot(Y[:, 0] - a1 * c, Y[:, 1] - a1 * s)
        r2 = np.hypot(Y[:, 0] - a2 * c, Y[:, 1] - a2 * s)
        E = 0.5 * (Y[:, 2] ** 2 + Y[:, 3] ** 2) - G * m1 / r1 - G * m2 / r2
        return E - w * (Y[:, 0] * Y[:, 3] - Y[:, 1] * Y[:, 2])

    params = {"formulation": "inertial", "gravitational_constant": G, "primary_mass": m1,
              "secondary_mass": m2, "separation": L, "initial.x": float(y0[0]),
              "initial.y": float(y0[1]), "initial_rate.x": float(y0[2]),
              "initial_rate.y": float(y0[3])}
    pb = Problem("cr3bp", "cr3bp", params, orbits * period, n_samples,
                 f"planar CR3BP, m₁ = {m1}, m₂ = {m2}, L = {L}, G = {G}: test particle on a "
                 f"near-circular orbit about both primaries from r = {r0} (inertial frame); "
                 f"{orbits:g} orbits of the primaries",
                 _cr3bp_deriv, p, y0, reference,
                 "DOP853 tableau in the co-rotating frame, fixed step 0.01, long double"
                 if EXTENDED else _FALLBACK, period, jacobi, "Jacobi integral",
                 peers=("scipy", "handwritten", "rebound"), accel=_cr3bp_accel,
                 extra={"rebound": {"G": G, "origin": None, "period": period, "bodies": [
                     (m1, a1, 0.0, 0.0, a1 * w), (m2, a2, 0.0, 0.0, a2 * w)]}})
    return pb


# --- charged_particle (uniform B along z, uniform E) ------------------------------------------
def _charged_deriv(t: float, y: Array, p: Array, dy: Array) -> None:
    # p = [q/m, Ex, Ey, Ez, Bx, By, Bz]: v̇ = (q/m)(E + v × B).
    k = p[0]
    vx, vy, vz = y[3], y[4], y[5]
    dy[0] = vx
    dy[1] = vy
    dy[2] = vz
    dy[3] = k * (p[1] + vy * p[6] - vz * p[5])
    dy[4] = k * (p[2] + vz * p[4] - vx * p[6])
    dy[5] = k * (p[3] + vx * p[5] - vy * p[4])


def charged_particle_reference(qm: float, E: Array, B: float, y0: Array, t: Array) -> Array:
    """Uniform B ẑ and E: u = v⊥ − v_d (v_d = E × B/B²) turns at ω_c = (q/m)B (clockwise for
    ω_c > 0), z accelerates at (q/m)E_z."""
    t = np.asarray(t, dtype=float)
    wc = qm * B
    vdx, vdy = E[1] / B, -E[0] / B
    ux, uy = y0[3] - vdx, y0[4] - vdy
    c, s = np.cos(wc * t), np.sin(wc * t)
    x = y0[0] + vdx * t + (ux * s + uy * (1 - c)) / wc
    y = y0[1] + vdy * t + (ux * (c - 1) + uy * s) / wc
    z = y0[2] + y0[5] * t + 0.5 * qm * E[2] * t * t
    return np.stack([x, y, z, vdx + ux * c + uy * s, vdy - ux * s + uy * c,
                     y0[5] + qm * E[2] * t], axis=1)


def _charged_particle(name: str, E: tuple[float, float, float], t_end: float, n_samples: int
                      ) -> Problem:
    m, q, B = 1.0, 1.0, 2.0
    Ev = np.array(E, dtype=float)
    y0 = np.array([1.0, 0.0, 0.0, 0.0, -1.5, 0.2])  # mechsim's default initial state

    def reference(t: Array) -> Array:
        return charged_particle_reference(q / m, Ev, B, y0, t)

    def energy(t: Array, Y: Array) -> Array:
        return 0.5 * m * np.sum(Y[:, 3:6] ** 2, axis=1) - q * (Y[:, 0:3] @ Ev)

    params = {"formulation": "symmetric", "mass": m, "charge": q, "magnetic_field": B,
              **{f"electric_field.{a}": float(Ev[i]) for i, a in enumerate("xyz")},
              **{f"initial.{a}": float(y0[i]) for i, a in enumerate("xyz")},
              **{f"initial_rate.{a}": float(y0[3 + i]) for i, a in enumerate("xyz")}}
    wc = abs(q * B / m)
    field_text = f"B = {B} T along z" + (f", E = {E} V/m" if any(E) else "")
    return Problem(name, "charged_particle", params, t_end, n_samples,
                   f"charged particle q = {q} C, m = {m} kg, {field_text}, from r₀ = (1, 0, 0), "
                   f"v₀ = (0, −1.5, 0.2); {t_end:g} s ≈ {t_end * wc / (2 * math.pi):.0f} "
                   "gyrations; Cartesian (mechsim's symmetric gauge)",
                   _charged_deriv, np.array([q / m, *Ev, 0.0, 0.0, B]), y0, reference,
                   "closed form (gyration + E×B drift)", 2 * math.pi / wc, energy, "energy",
                   extra={"conserved_scale": 0.5 * m * float(y0[3:] @ y0[3:]),
                          "boris": {"q_over_m": q / m, "E": tuple(Ev), "B": (0.0, 0.0, B)}})


def charged_particle_b(t_end: float = 60.0, n_samples: int = 200) -> Problem:
    return _charged_particle("charged_particle_b", (0.0, 0.0, 0.0), t_end, n_samples)


def charged_particle_exb(t_end: float = 60.0, n_samples: int = 200) -> Problem:
    return _charged_particle("charged_particle_exb", (0.5, 0.0, 0.0), t_end, n_samples)


# --- spring_pendulum (polar: extension x, angle θ) --------------------------------------------
def _spring_pendulum_deriv(t: float, y: Array, p: Array, dy: Array) -> None:
    # p = [l, k/m, g]; bob at (l + x)(sin θ, −cos θ).
    r = p[0] + y[0]
    dy[0] = y[2]
    dy[1] = y[3]
    dy[2] = r * y[3] * y[3] + p[2] * math.cos(y[1]) - p[1] * y[0]
    dy[3] = -(p[2] * math.sin(y[1]) + 2.0 * y[2] * y[3]) / r


def spring_pendulum(t_end: float = 20.0, n_samples: int = 200) -> Problem:
    m, l, k, g = 1.0, 1.0, 40.0, 9.81
    y0 = np.array([0.3, 0.8, 0.0, 0.0])  # mechsim's defaults: extension, angle, rates
    pb: Problem

    def cartesian_ext(z: Array) -> Array:  # bob (y, z), z up: independent formulation
        yy, zz, vy, vz = z
        rho = np.sqrt(yy * yy + zz * zz)
        f = k / m * (rho - l) / rho
        return np.array([vy, vz, -f * yy, -g - f * zz], dtype=z.dtype)

    def reference(t: Array) -> Array:
        t = np.asarray(t, dtype=float)
        if not EXTENDED:
            return _radau_tight(pb.rhs, y0, t)
        Ld = np.longdouble
        x, th, dx, dth = (Ld(v) for v in y0)
        r, s, c = Ld(l) + x, np.sin(th), np.cos(th)
        z0 = np.array([r * s, -r * c, dx * s + r * dth * c, -dx * c + r * dth * s], dtype=Ld)
        Z = _fixed_dop853_longdouble(cartesian_ext, z0, t, 2e-3)
        yy, zz, vy, vz = Z.T
        rho = np.sqrt(yy * yy + zz * zz)
        return np.stack([rho - Ld(l), np.arctan2(yy, -zz), (yy * vy + zz * vz) / rho,
                         (-zz * vy + yy * vz) / (rho * rho)], axis=1).astype(float)

    def energy(t: Array, Y: Array) -> Array:
        x, th, dx, dth = Y.T
        r = l + x
        return 0.5 * m * (dx**2 + r**2 * dth**2) - m * g * r * np.cos(th) + 0.5 * k * x**2

    params = {"formulation": "polar", "mass": m, "length": l, "spring_constant": k,
              "gravity": g, "initial.extension": float(y0[0]), "initial.angle": float(y0[1]),
              "initial_rate.extension": float(y0[2]), "initial_rate.angle": float(y0[3])}
    pb = Problem("spring_pendulum", "spring_pendulum", params, t_end, n_samples,
                 f"spring pendulum m = {m}, l = {l}, k = {k}, g = {g}, released at extension "
                 f"{y0[0]} m, angle {y0[1]} rad (polar coordinates); {t_end:g} s",
                 _spring_pendulum_deriv, np.array([l, k / m, g]), y0, reference,
                 "DOP853 tableau in Cartesian coordinates, fixed step 2 ms, long double"
                 if EXTENDED else _FALLBACK, 2 * math.pi * math.sqrt(m / k), energy, "energy",
                 extra={"conserved_scale": 0.5 * k * y0[0] ** 2})
    return pb


BUILDERS: dict[str, Callable[..., Problem]] = {
    "pendulum": pendulum,
    "kepler": kepler,
    "driven_oscillator": driven_oscillator,
    "harmonic_oscillator": harmonic_oscillator,
    "double_pendulum": double_pendulum,
    "rigid_body_intermediate": rigid_body_intermediate,
    "rigid_body_generic": rigid_body_generic,
    "heavy_top": heavy_top,
    "cr3bp": cr3bp,
    "charged_particle_b": charged_particle_b,
    "charged_particle_exb": charged_particle_exb,
    "spring_pendulum": spring_pendulum,
    "coupled_oscillators_2": coupled_oscillators_2,
    "coupled_oscillators_12": coupled_oscillators_12,
}

#: The short problems: one period of these, sampled ``SHORT_SAMPLES`` times, where a call's
#: fixed cost weighs most (a power of two: the sample times end exactly on the period).
SHORT_OF = ("pendulum", "kepler", "rigid_body_generic", "spring_pendulum",
            "charged_particle_b", "charged_particle_exb")
SHORT_SAMPLES = 64


def short(name: str) -> Problem:
    """Problem ``name`` over one of its periods, sampled ``SHORT_SAMPLES`` times."""
    pb = BUILDERS[name]()
    return dataclasses.replace(
        pb, name=f"{name}_short", t_end=pb.period, n_samples=SHORT_SAMPLES,
        description=f"{pb.description.split(';')[0]}; one period ({pb.period:.4g} s), "
        f"{SHORT_SAMPLES} samples", _ref_cache=None)


BUILDERS.update({f"{name}_short": functools.partial(short, name) for name in SHORT_OF})

# The mechsim system each problem runs on (without building the problem).
SYSTEM_OF: dict[str, str] = {
    "rigid_body_intermediate": "rigid_body", "rigid_body_generic": "rigid_body",
    "heavy_top": "symmetric_top", "charged_particle_b": "charged_particle",
    "charged_particle_exb": "charged_particle", "coupled_oscillators_2": "coupled_oscillators",
    "coupled_oscillators_12": "coupled_oscillators",
}
SYSTEM_OF.update({f"{name}_short": SYSTEM_OF.get(name, name) for name in SHORT_OF})

# Horizons of --quick (CI): a few periods.
QUICK: dict[str, dict[str, Any]] = {
    "pendulum": {"t_end": 5.0, "n_samples": 20},
    "kepler": {"orbits": 2.0, "n_samples": 20},
    "driven_oscillator": {"t_end": 5.0, "n_samples": 20},
    "harmonic_oscillator": {"t_end": 5.0, "n_samples": 20},
    "double_pendulum": {"t_end": 2.0, "n_samples": 20},
    "rigid_body_intermediate": {"t_end": 10.0, "n_samples": 20},
    "rigid_body_generic": {"t_end": 5.0, "n_samples": 20},
    "heavy_top": {"t_end": 1.0, "n_samples": 20},
    "cr3bp": {"orbits": 2.0, "n_samples": 20},
    "charged_particle_b": {"t_end": 5.0, "n_samples": 20},
    "charged_particle_exb": {"t_end": 5.0, "n_samples": 20},
    "spring_pendulum": {"t_end": 3.0, "n_samples": 20},
    "coupled_oscillators_2": {"t_end": 10.0, "n_samples": 20},
    "coupled_oscillators_12": {"t_end": 10.0, "n_samples": 20},
}
QUICK.update({f"{name}_short": {} for name in SHORT_OF})  # short already


def system_of(name: str) -> str:
    return SYSTEM_OF.get(name, name)


def problem(name: str, quick: bool = False) -> Problem:
    return BUILDERS[name](**(QUICK.get(name, {}) if quick else {}))
