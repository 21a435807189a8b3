"""The rigid body as a ``DirectModel`` with a quaternion attitude, shared by ``rigid_body`` and
``symmetric_top`` (not a system). The inertia tensors are in ``_inertia``, the torque-free
motion in closed form in ``_free_rotation``.

``QuaternionRigidBody``: a rigid body turning about its centre of mass or about a fixed point,
attitude integrated as a unit quaternion q (world_R_body, (x, y, z, w)) with Euler's equations
(PHYS0500 – Advanced Classical Mechanics, §7.7.2)

    I₁ω̇₁ − (I₂ − I₃)ω₂ω₃ = N₁,  I₂ω̇₂ − (I₃ − I₁)ω₃ω₁ = N₂,  I₃ω̇₃ − (I₁ − I₂)ω₁ω₂ = N₃

in principal axes. The state follows the engine's layout y = [q, q̇, W_ext, W_diss] with the
four quaternion components as coordinates and their rates as velocities: ω = 2 q* ⊗ q̇ and
q̈ = ½ q̇ ⊗ ω + ½ q ⊗ ω̇. The unit norm is a constraint (|q| − 1, published as
``constraint_unit_norm``), restored after every step by projection: q ← q/|q|,
q̇ ← q̇/|q| − (q·q̇) q, which leaves ω unchanged. No Euler angles are integrated, so there is no
gimbal singularity. The kernel functions make no arrays (helpers return tuples).
Torque: a constant body-frame torque N₀ (its work ∫ω·N₀ dt is W_ext) plus uniform gravity
acting at the centre of mass c (body components, relative to the fixed point), which enters
through V = M g (R c)·ẑ. The inertia and torque data are not parameters but derived from them:
subclasses return them from ``rigid_data`` and they ride at the start of the parameter vector
(fixed indices RB_*, then up to RB_N_EXTRA numbers of the subclass's own; its numeric
parameters follow from RB_SIZE on), so the kernel is compiled once for every body and the same
constants hold in Python and in the kernel module. Whenever no torque acts, ``propagate`` (method
``exact``) is the closed form of ``_free_rotation``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from mechsim.systems._free_rotation import (
    _NONE,
    FreeMotion,
    UniformSpin,
    _torque_free_motion,
    free_motion,
    free_rotation_at,
    pack,
    packed_motion_rows,
)
from mechsim.systems._rotation import (
    ROTATION_KERNELS,
    quat_mul,
    quat_product,
    rotate,
    rotate_inverse,
)
from mechsim.systems.base import Attitude, Quantity, Structure
from mechsim.systems.direct import DirectModel

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

    @cached_property
    def rigid(self) -> RigidData:
        """``rigid_data()``, computed once (a model's parameters never change)."""
        return self.rigid_data()

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
        d = self.rigid
        return Structure(separable=False, n_constraints=1, driven=any(d.torque))

    @property
    def invariants(self) -> tuple[Quantity, ...]:
        return (Quantity("constraint_unit_norm", "", "|q| − 1"),)

    def _make_parameter_vector(self) -> np.ndarray:
        d = self.rigid
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
        d = self.rigid
        return not any(d.torque) and not (d.weight and any(d.center_of_mass))

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray,
                  work_terms: bool = True) -> np.ndarray | None:
        """The torque-free motion in closed form (``free_rotation``): rows [q, q̇ = ½ q ⊗ ω,
        work terms of y0]; None when a torque acts."""
        if not self.torque_free():
            return None
        t = np.ascontiguousarray(t, dtype=float)
        y0 = np.ascontiguousarray(y0, dtype=float)
        motion = self._free_motion(y0)
        rows = np.empty((t.size, y0.size))
        if isinstance(motion, UniformSpin):
            rows[:, :8], _ = free_rotation_at(motion, t - t0)
            rows[:, 8:] = y0[8:]
        else:  # the work terms too, in the same pass
            _torque_free_motion(t, float(t0), *motion, y0, rows, _NONE)
        return rows

    def closed_form_kernel(self, y0: np.ndarray) -> tuple[Any, np.ndarray] | None:
        """``packed_motion_rows`` with the motion's constants from y0 (``motion_constants``)
        off the principal axes; else None (``propagate``)."""
        if not self.torque_free():
            return None
        motion = self._free_motion(np.ascontiguousarray(y0, dtype=float))
        return None if isinstance(motion, UniformSpin) else (packed_motion_rows, pack(motion))

    #: Initial states whose closed-form constants are kept (``propagate``), per model.
    MOTION_CACHE_SIZE = 8

    def motion_constants(self, y0: np.ndarray, make: Callable[[], Any]) -> Any:
        """``make()``, the constants of a closed form from the state y0 (None: no closed form
        from there), computed once per state and parameter values: they depend on nothing
        else, and t₀ only shifts the times."""
        key = (y0.tobytes(), tuple(self.values.items()))
        cache = self.__dict__.setdefault("_motion_cache", {})
        if key not in cache:
            if len(cache) >= self.MOTION_CACHE_SIZE:
                cache.clear()
            cache[key] = make()
        return cache[key]

    def _free_motion(self, y0: np.ndarray) -> FreeMotion:
        """``free_motion`` from the state y0 (``motion_constants``)."""
        return self.motion_constants(y0, lambda: free_motion(
            self.rigid.moments, y0[:4], np.array(rb_omega(y0))))
