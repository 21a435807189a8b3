"""Rigid-body math shared by ``rigid_body`` and ``symmetric_top`` (not a system).

Two parts:

1. Inertia tensors (plain numpy, seed 003 §7.2–7.5): standard solids about their centroid,
   point masses, the general parallel-axis theorem J_ij = I_ij + M(a² δ_ij − a_i a_j) (line
   1686; the document's 1674/1676 index typos corrected), composition of parts, principal axes.

2. ``QuaternionRigidBody``: a DirectModel base for a rigid body turning about its centre of mass
   or about a fixed point, attitude integrated as a unit quaternion q (world_R_body, (x, y, z, w))
   with Euler's equations (seed 003 §7.7.2, line 1783)

       I₁ω̇₁ − (I₂ − I₃)ω₂ω₃ = N₁,  I₂ω̇₂ − (I₃ − I₁)ω₃ω₁ = N₂,  I₃ω̇₃ − (I₁ − I₂)ω₁ω₂ = N₃

   in principal axes. The state follows the engine's layout y = [q, q̇, W_ext, W_diss] with the
   four quaternion components as coordinates and their rates as velocities: ω = 2 q* ⊗ q̇ and
   q̈ = ½ q̇ ⊗ ω + ½ q ⊗ ω̇. The unit norm is a constraint (|q| − 1, published as
   ``constraint_unit_norm``), restored after every step by projection: q ← q/|q|,
   q̇ ← q̇/|q| − (q·q̇) q, which leaves ω unchanged. No Euler angles are integrated, so there
   is no gimbal singularity. The kernel functions make no arrays (helpers return tuples).
   Torque: a constant body-frame torque N₀ (its work ∫ω·N₀ dt is W_ext) plus uniform gravity
   acting at the centre of mass c (body components, relative to the fixed point), which enters
   through V = M g (R c)·ẑ. The inertia and torque data are not parameters but derived from
   them: subclasses return them from ``rigid_data`` and they ride at the start of the
   parameter vector (fixed indices RB_*, then up to RB_N_EXTRA numbers of the subclass's own;
   its numeric parameters follow from RB_SIZE on), so the kernel is compiled once for every
   body and the same constants hold in Python and in the kernel module.

3. The torque-free motion in closed form (``free_rotation``: Jacobi elliptic functions for ω,
   the precession angle about the fixed L for the attitude), which ``QuaternionRigidBody``
   offers as ``propagate`` (method ``exact``) whenever no torque acts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from mechsim.systems._rotation import (
    ROTATION_KERNELS,
    quat_from_rows,
    quat_mul,
    quat_product,
    rotate,
    rotate_inverse,
)
from mechsim.systems.base import Attitude, Quantity, Structure
from mechsim.systems.direct import DirectModel

# --- inertia ----------------------------------------------------------------------------------


def box_inertia(mass: float, size: tuple[float, float, float]) -> np.ndarray:
    """Solid box with edge lengths (a, b, c) along x, y, z, about its centre:
    (M/12) diag(b² + c², a² + c², a² + b²)."""
    a, b, c = size
    return mass / 12.0 * np.diag([b * b + c * c, a * a + c * c, a * a + b * b])


def cylinder_inertia(mass: float, radius: float, length: float) -> np.ndarray:
    """Solid circular cylinder along z about its centre: diag(M(3r² + L²)/12, same, Mr²/2)."""
    t = mass * (3 * radius**2 + length**2) / 12.0
    return np.diag([t, t, 0.5 * mass * radius**2])


def sphere_inertia(mass: float, radius: float) -> np.ndarray:
    """Solid sphere about its centre: (2/5) M r² 1."""
    return 0.4 * mass * radius**2 * np.eye(3)


def point_mass_inertia(mass: float, position: np.ndarray) -> np.ndarray:
    """A point mass at ``position``, about the origin: m (r² 1 − r rᵀ) (eq. 7.1)."""
    r = np.asarray(position, dtype=float)
    return mass * (r @ r * np.eye(3) - np.outer(r, r))


def parallel_axis(inertia_cm: np.ndarray, mass: float, offset: np.ndarray) -> np.ndarray:
    """Tensor about a point Q from the one about the centre of mass, ``offset`` = a = CM − Q:
    J = I + M (a² 1 − a aᵀ) (seed 003 §7.5, line 1686)."""
    return np.asarray(inertia_cm, dtype=float) + point_mass_inertia(mass, offset)


@dataclass(frozen=True)
class Part:
    """A solid of mass ``mass`` with tensor ``inertia`` about its own centre, placed at
    ``position`` with orientation ``rotation`` (its axes in the body frame, as columns)."""

    mass: float
    inertia: np.ndarray
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: np.ndarray | None = None


def composite(parts: list[Part]) -> tuple[float, np.ndarray, np.ndarray]:
    """Total mass, centre of mass and inertia tensor about the centre of mass of ``parts``."""
    total = sum(p.mass for p in parts)
    cm = sum(p.mass * np.asarray(p.position, dtype=float) for p in parts) / total
    inertia = np.zeros((3, 3))
    for p in parts:
        R = np.eye(3) if p.rotation is None else np.asarray(p.rotation, dtype=float)
        inertia += parallel_axis(R @ p.inertia @ R.T, p.mass, np.asarray(p.position) - cm)
    return total, cm, inertia


def principal_axes(inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments and axes: I = Q diag(moments) Qᵀ, det Q = +1 (seed 003 §7.4).

    The axes are matched to the body axes they lie closest to (so a tensor that is already
    diagonal keeps its axes and their order) and point along their positive directions.
    """
    inertia = np.asarray(inertia, dtype=float)
    scale = float(np.trace(inertia)) or 1.0
    off = inertia - np.diag(np.diag(inertia))
    if np.max(np.abs(off)) <= 1e-14 * scale:
        return np.diag(inertia).copy(), np.eye(3)
    moments, Q = np.linalg.eigh(inertia)
    order = [-1, -1, -1]
    free = [0, 1, 2]
    # greedy: the eigenvector most aligned with a body axis takes that axis first
    pairs = sorted(((abs(Q[axis, k]), axis, k) for axis in range(3) for k in range(3)),
                   reverse=True)
    taken: set[int] = set()
    for _, axis, k in pairs:
        if order[axis] < 0 and k not in taken:
            order[axis] = k
            taken.add(k)
            free.remove(axis)
    Q = Q[:, order]
    moments = moments[order]
    for axis in range(3):
        if Q[axis, axis] < 0:
            Q[:, axis] = -Q[:, axis]
    if np.linalg.det(Q) < 0:
        Q[:, 2] = -Q[:, 2]
    return moments, Q


# --- quaternion rigid-body kernel (pasted into kernel modules) --------------------------------
# Where the derived data sit in p: principal moments, constant body torque, centre of mass,
# M g, then RB_N_EXTRA slots for a subclass's own numbers; numeric parameters from RB_SIZE on.
RIGID_BLOCK = ("RB_I1", "RB_I2", "RB_I3", "RB_N1", "RB_N2", "RB_N3",
               "RB_C1", "RB_C2", "RB_C3", "RB_MG", "RB_EXTRA")
RB_I1, RB_I2, RB_I3, RB_N1, RB_N2, RB_N3, RB_C1, RB_C2, RB_C3, RB_MG, RB_EXTRA = range(11)
RB_N_EXTRA = 10
RB_SIZE = RB_EXTRA + RB_N_EXTRA


def rb_omega(y):
    """Body angular velocity ω = 2 q* ⊗ q̇ / |q|² (vector part), as a tuple."""
    x, yy, z, s = y[0], y[1], y[2], y[3]
    dx, dy, dz, ds = y[4], y[5], y[6], y[7]
    f = 2.0 / (x * x + yy * yy + z * z + s * s)
    return (f * (s * dx - x * ds - yy * dz + z * dy),
            f * (s * dy - yy * ds - z * dx + x * dz),
            f * (s * dz - z * ds - x * dy + yy * dx))


def rb_unit(y):
    """The attitude q/|q| as a tuple."""
    n = math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3])
    return (y[0] / n, y[1] / n, y[2] / n, y[3] / n)


def rb_torque(q, p):
    """Body torque: constant N₀ plus gravity at the CM, c × (Rᵀ (0, 0, −M g))."""
    g = rotate_inverse(q, (0.0, 0.0, -p[RB_MG]))
    c1, c2, c3 = p[RB_C1], p[RB_C2], p[RB_C3]
    return (p[RB_N1] + c2 * g[2] - c3 * g[1],
            p[RB_N2] + c3 * g[0] - c1 * g[2],
            p[RB_N3] + c1 * g[1] - c2 * g[0])


def rhs(t, y, p, dy):
    w = rb_omega(y)
    tq = rb_torque(rb_unit(y), p)
    i1, i2, i3 = p[RB_I1], p[RB_I2], p[RB_I3]
    wd = (((i2 - i3) * w[1] * w[2] + tq[0]) / i1,
          ((i3 - i1) * w[2] * w[0] + tq[1]) / i2,
          ((i1 - i2) * w[0] * w[1] + tq[2]) / i3, 0.0)
    a = quat_product((y[4], y[5], y[6], y[7]), (w[0], w[1], w[2], 0.0))
    b = quat_product((y[0], y[1], y[2], y[3]), wd)
    for i in range(4):
        dy[i] = y[4 + i]
        dy[4 + i] = 0.5 * (a[i] + b[i])
    dy[8] = w[0] * p[RB_N1] + w[1] * p[RB_N2] + w[2] * p[RB_N3]
    dy[9] = 0.0


def project(t, y, p):
    """q ← q/|q|, q̇ ← q̇/|q| − (q·q̇) q: onto |q| = 1, q·q̇ = 0 with ω = 2 q* ⊗ q̇ / |q|²
    unchanged (scaling q alone would scale ω, and with it the energy, by |q|)."""
    n = math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3])
    for i in range(8):
        y[i] /= n
    d = y[0] * y[4] + y[1] * y[5] + y[2] * y[6] + y[3] * y[7]
    for i in range(4):
        y[4 + i] -= d * y[i]


def energy(t, y, p, out):
    w = rb_omega(y)
    cw = rotate(rb_unit(y), (p[RB_C1], p[RB_C2], p[RB_C3]))
    out[0] = 0.5 * (p[RB_I1] * (w[0] * w[0]) + p[RB_I2] * (w[1] * w[1])
                    + p[RB_I3] * (w[2] * w[2]))
    out[1] = p[RB_MG] * cw[2]
    out[2] = out[0] + out[1]


def rb_momentum(y, p):
    """Angular momentum L = I ω (about the CM or the fixed point): body components, then
    world components, as one tuple of six."""
    w = rb_omega(y)
    body = (p[RB_I1] * w[0], p[RB_I2] * w[1], p[RB_I3] * w[2])
    world = rotate(rb_unit(y), body)
    return (body[0], body[1], body[2], world[0], world[1], world[2])


#: The shared kernel functions (no arrays are made in any: every helper returns a tuple).
RIGID_KERNELS = (*ROTATION_KERNELS, rb_omega, rb_unit, rb_torque, rhs, project, energy,
                 rb_momentum)


# --- the torque-free motion in closed form ----------------------------------------------------


def _quat_z(angle: np.ndarray) -> tuple[np.ndarray, ...]:
    """Quaternions (x, y, z, w) of rotations by ``angle`` about z, as four arrays."""
    zero = np.zeros_like(angle)
    return (zero, zero, np.sin(0.5 * angle), np.cos(0.5 * angle))


def _quat_x(angle: np.ndarray) -> tuple[np.ndarray, ...]:
    zero = np.zeros_like(angle)
    return (np.sin(0.5 * angle), zero, zero, np.cos(0.5 * angle))


def _conjugate(q: tuple | np.ndarray) -> tuple:
    return (-q[0], -q[1], -q[2], q[3])


def jacobi_elliptic(u: np.ndarray, m: float, m1: float) -> tuple[np.ndarray, ...]:
    """sn, cn, dn of u for the parameter m given with its complement m1 = 1 − m, each accurate
    on its own (near the separatrix m1 is small and 1 − m would keep few of its digits; scipy's
    ``ellipj`` takes m alone). Arithmetic–geometric mean and descending recursion for the
    amplitude (Abramowitz & Stegun 16.4), with b₀ = √m1."""
    u = np.asarray(u, dtype=float)
    if m1 == 0.0:  # on the separatrix: the limit m = 1
        return np.tanh(u), 1.0 / np.cosh(u), 1.0 / np.cosh(u)
    a, b, c = 1.0, math.sqrt(m1), math.sqrt(m)
    ratios = []
    while abs(c) > 1e-17 * a and len(ratios) < 60:
        a, b, c = 0.5 * (a + b), math.sqrt(a * b), 0.5 * (a - b)
        ratios.append(c / a)
    phi = (2.0 ** len(ratios)) * a * u
    prev = phi
    for r in reversed(ratios):
        prev = phi
        phi = 0.5 * (phi + np.arcsin(r * np.sin(phi)))
    sn, cn = np.sin(phi), np.cos(phi)
    dn = cn / np.cos(prev - phi) if ratios else np.ones_like(u)
    return sn, cn, dn


def elliptic_f(phi: float, m1: float) -> float:
    """The incomplete integral F(φ | m) for φ ∈ [−π, π] from m1 = 1 − m: sin φ R_F(cos²φ,
    cos²φ + m1 sin²φ, 1) (Carlson), and F(φ) = 2K − F(π − φ) beyond π/2."""
    from scipy.special import elliprf

    if abs(phi) > 0.5 * math.pi:
        whole = 2.0 * float(elliprf(0.0, m1, 1.0))
        return math.copysign(whole - elliptic_f(math.pi - abs(phi), m1), phi)
    s, c = math.sin(phi), math.cos(phi)
    return s * float(elliprf(c * c, c * c + m1 * s * s, 1.0))


def free_rotation(moments: tuple[float, float, float], q0: np.ndarray, w0: np.ndarray,
                  t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Attitude q(t) (rows (x, y, z, w), world_R_body) and body ω(t) (rows) of a torque-free
    rigid body with principal moments ``moments`` from q(0) = q0, ω(0) = w0; ``t`` increasing,
    ≥ 0.

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
    about axis a; the denominator I_b²ω_b² + I_c²ω_c² stays away from zero), integrated by
    Gauss–Legendre quadrature on pieces of a tenth of 1/ν (round-off for this smooth integrand).
    """
    from mechsim.systems._oscillator import cumulative_integral

    t = np.asarray(t, dtype=float)
    I = np.asarray(moments, dtype=float)
    w0 = np.asarray(w0, dtype=float)
    q0 = np.asarray(q0, dtype=float) / np.linalg.norm(q0)
    Lb = I * w0
    lam = float(np.linalg.norm(Lb))
    w_dot = np.cross(Lb, w0) / I
    if lam == 0.0 or not np.any(w_dot):
        # at rest, or spinning about a principal axis: ω constant, q(t) = q0 ⊗ exp(ω t / 2)
        speed = float(np.linalg.norm(w0))
        axis = w0 / speed if speed > 0 else np.array([0.0, 0.0, 1.0])
        half = 0.5 * speed * t
        turn = (axis[0] * np.sin(half), axis[1] * np.sin(half), axis[2] * np.sin(half),
                np.cos(half))
        Q = np.stack(quat_product(tuple(q0), turn), axis=1)
        return Q, np.repeat(w0[None, :], t.size, axis=0)
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
    u0 = elliptic_f(math.atan2(s_b * y0, x0), m1)

    def omega(s: np.ndarray) -> np.ndarray:
        sn, cn, dn = jacobi_elliptic(nu * s + u0, m, m1)
        w = np.empty((3,) + np.shape(s))
        w[a], w[b], w[c] = amp_a * cn, s_b * amp_b * sn, s_c * amp_c * dn
        return w

    def precession_rate(s: np.ndarray) -> np.ndarray:
        w = omega(s)
        j, k = (a + 1) % 3, (a + 2) % 3
        num = I[j] * w[j] ** 2 + I[k] * w[k] ** 2
        den = (I[j] * w[j]) ** 2 + (I[k] * w[k]) ** 2
        return lam * num / den

    W = omega(t)
    phi = cumulative_integral(precession_rate, 0.0, t, 0.1 / nu)

    def attitude(w: np.ndarray, phi_: np.ndarray) -> tuple:
        """Quaternions of L-frame_R_body from the Euler angles about axis a."""
        i, j = (a + 1) % 3, (a + 2) % 3
        n = I[:, None] * w.reshape(3, -1) / lam
        theta = np.arctan2(np.hypot(n[i], n[j]), n[a])
        # L_c keeps its sign: flip both arguments when c = j and L_c < 0, so that ψ never
        # meets the branch cut of atan2
        flip = -1.0 if (c == j and n[c][0] < 0.0) else 1.0
        psi = np.arctan2(flip * n[i], flip * n[j]) + (math.pi if flip < 0 else 0.0)
        perm = np.zeros((3, 3))
        perm[0, i] = perm[1, j] = perm[2, a] = 1.0  # v_(i, j, a) = P v
        p = np.empty(4)
        quat_from_rows(perm, p)  # the quaternion of Pᵀ
        q = quat_product(quat_product(_quat_z(phi_), _quat_x(theta)), _quat_z(psi))
        return quat_product(q, _conjugate(p))

    start = attitude(w0[:, None].copy(), np.zeros(1))
    g = quat_product(tuple(q0), _conjugate(tuple(x[0] for x in start)))
    Q = np.stack(quat_product(g, attitude(W, phi)), axis=1)
    return Q, W.T.copy()


@dataclass(frozen=True)
class RigidData:
    """Principal moments, constant body torque N₀, CM position c (body, from the pivot), M g,
    and any further derived numbers a subclass's kernels read as p[RB_EXTRA + k]."""

    moments: tuple[float, float, float]
    torque: tuple[float, float, float] = (0.0, 0.0, 0.0)
    center_of_mass: tuple[float, float, float] = (0.0, 0.0, 0.0)
    weight: float = 0.0
    extra: tuple[float, ...] = ()


def body_angular_velocity(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """ω in body axes (``rb_omega``) for quaternions q and rates v = q̇ of shape (..., 4)."""
    y = np.concatenate([np.moveaxis(np.asarray(q, dtype=float), -1, 0),
                        np.moveaxis(np.asarray(v, dtype=float), -1, 0)])
    return np.stack(rb_omega(y), axis=-1)


class QuaternionRigidBody(DirectModel):
    """Base for rigid bodies integrated as quaternions; see the module docstring.

    Subclasses give ``rigid_data`` and ``initial_attitude`` (quaternion, body ω), and list their
    own ``invariants``/``observables``/``frames`` kernels after ``RIGID_KERNELS``.
    """

    QUATERNION = ("x", "y", "z", "w")
    #: The frame (a child of "world", at its origin) whose orientation q is.
    ATTITUDE_FRAME = "body"

    def rigid_data(self) -> RigidData:
        raise NotImplementedError

    def initial_attitude(self) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    @property
    def coordinates(self) -> tuple[Quantity, ...]:
        return tuple(Quantity(f"quaternion_{c}", "", f"attitude quaternion {c} (world_R_body)")
                     for c in self.QUATERNION)

    @property
    def attitude(self) -> Attitude:
        """q is world_R_body of ``ATTITUDE_FRAME``; ω = 2 q* ⊗ q̇ in body axes (``rb_omega``)."""
        return Attitude(self.ATTITUDE_FRAME, (0, 1, 2, 3), body_angular_velocity)

    @cached_property
    def structure(self) -> Structure:
        d = self.rigid_data()
        return Structure(separable=False, n_constraints=1, driven=any(d.torque))

    @property
    def invariants(self) -> tuple[Quantity, ...]:
        return (Quantity("constraint_unit_norm", "", "|q| − 1"),)

    def _make_parameter_vector(self) -> np.ndarray:
        d = self.rigid_data()
        if len(d.extra) > RB_N_EXTRA:
            raise ValueError(f"{type(self).__name__}: at most {RB_N_EXTRA} extra numbers")
        block = np.zeros(RB_SIZE)
        block[:RB_EXTRA] = [*d.moments, *d.torque, *d.center_of_mass, d.weight]
        block[RB_EXTRA:RB_EXTRA + len(d.extra)] = d.extra
        return np.concatenate([block, super()._make_parameter_vector()])

    def parameter_offset(self) -> int:
        return RB_SIZE

    def kernel_constants(self) -> dict[str, int | float]:
        return {name: i for i, name in enumerate(RIGID_BLOCK)}

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        q, w = self.initial_attitude()
        wq = np.array([w[0], w[1], w[2], 0.0])
        qd = np.empty(4)
        quat_mul(q, wq, qd)
        return np.asarray(q, dtype=float), 0.5 * qd

    def torque_free(self) -> bool:
        """No constant torque and no weight acting off the pivot."""
        d = self.rigid_data()
        return not any(d.torque) and not (d.weight and any(d.center_of_mass))

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray) -> np.ndarray | None:
        """The torque-free motion in closed form (``free_rotation``): rows [q, q̇ = ½ q ⊗ ω,
        work terms of y0]; None when a torque acts."""
        if not self.torque_free():
            return None
        t = np.asarray(t, dtype=float)
        Q, W = free_rotation(self.rigid_data().moments, y0[:4], np.array(rb_omega(y0)),
                             t - t0)
        Qd = 0.5 * np.stack(quat_product(Q.T, (W[:, 0], W[:, 1], W[:, 2], 0.0 * W[:, 0])),
                            axis=1)
        rows = np.repeat(np.asarray(y0, dtype=float)[None, :], t.size, axis=0)
        rows[:, :4], rows[:, 4:8] = Q, Qd
        return rows
