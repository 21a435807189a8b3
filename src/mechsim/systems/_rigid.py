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
   q̇ ← q̇ − (q·q̇) q. No Euler angles are integrated, so there is no gimbal singularity.
   Torque: a constant body-frame torque N₀ (its work ∫ω·N₀ dt is W_ext) plus uniform gravity
   acting at the centre of mass c (body components, relative to the fixed point), which enters
   through V = M g (R c)·ẑ. The inertia and torque data are not parameters but derived from
   them: subclasses return them from ``rigid_data`` and they ride at the start of the
   parameter vector (fixed indices RB_*, then up to RB_N_EXTRA numbers of the subclass's own;
   its numeric parameters follow from RB_SIZE on), so the kernel is compiled once for every
   body and the same constants hold in Python and in the kernel module.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from mechsim.systems._rotation import (
    ROTATION_KERNELS,
    quat_mul,
    quat_product,
    rotate,
    rotate_inverse,
)
from mechsim.systems.base import Quantity, Structure
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
    out[0] = 0.5 * (p[RB_I1] * w[0] ** 2 + p[RB_I2] * w[1] ** 2 + p[RB_I3] * w[2] ** 2)
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


@dataclass(frozen=True)
class RigidData:
    """Principal moments, constant body torque N₀, CM position c (body, from the pivot), M g,
    and any further derived numbers a subclass's kernels read as p[RB_EXTRA + k]."""

    moments: tuple[float, float, float]
    torque: tuple[float, float, float] = (0.0, 0.0, 0.0)
    center_of_mass: tuple[float, float, float] = (0.0, 0.0, 0.0)
    weight: float = 0.0
    extra: tuple[float, ...] = ()


class QuaternionRigidBody(DirectModel):
    """Base for rigid bodies integrated as quaternions; see the module docstring.

    Subclasses give ``rigid_data`` and ``initial_attitude`` (quaternion, body ω), and list their
    own ``invariants``/``observables``/``frames`` kernels after ``RIGID_KERNELS``.
    """

    QUATERNION = ("x", "y", "z", "w")

    def rigid_data(self) -> RigidData:
        raise NotImplementedError

    def initial_attitude(self) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    @property
    def coordinates(self) -> tuple[Quantity, ...]:
        return tuple(Quantity(f"quaternion_{c}", "", f"attitude quaternion {c} (world_R_body)")
                     for c in self.QUATERNION)

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
