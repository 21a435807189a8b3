"""Free rigid body: inertia tensor, principal axes, Euler's equations, quaternion attitude.

Source: PHYS0500 §7.2–7.7 (ch. 7 "Dynamics of Rigid Bodies": inertia tensor eq. 7.1,
principal axes §7.4, parallel-axis theorem §7.5, Euler's equations §7.7.1 force-free and §7.7.2
with torque, line 1783). The body is a solid ``shape`` (box, cylinder along z, sphere) of mass
``mass`` plus an optional point mass ``tip_mass`` at ``tip_position`` (both in the shape's own
frame, whose origin is the shape's centre); its tensor about the common centre of mass comes
from the inertia module ``mechsim.systems._inertia`` (parallel-axis theorem) and is diagonalised
into principal axes Q (det Q = +1, axes matched to the nearest shape axes).

Conventions:
- The centre of mass stays at the world origin (free body, no force). The integrated attitude
  is the principal-axis frame ``principal`` (quaternion world_R_principal, (x, y, z, w));
  ``body`` is the shape's frame, fixed in ``principal`` (a static frame). Attitude and the
  initial attitude angles: z-x-z Euler angles (φ, θ, ψ), world_R_body = R_z(φ)R_x(θ)R_z(ψ), the
  transpose of the document's passive λ = λ_ψλ_θλ_φ (§7.6).
- ω and the constant ``torque`` are given by components along the principal axes 1, 2, 3.
  Euler's equations in the document's form I₁ω̇₁ − (I₂ − I₃)ω₂ω₃ = N₁ (cyclic). The torque's
  work ∫ω·N dt is the external work of the energy balance.
- Attitude: a unit quaternion with its rates as velocities, renormalised by projection after
  every step (see ``_rigid``); no Euler angles are integrated, so nothing is singular.
- Without a torque the motion has a closed form (method ``exact``): ω from Jacobi's elliptic
  functions, the attitude from the precession about the fixed L (``_free_rotation.free_rotation``).

Document typos corrected (catalog 003 §7.2–7.7): m_α missing in Σ m_α r_α = 0 (1537) and in the
(3,2) entry of the explicit tensor (1580); a_j a_i for α_j α_i and I_ij for I_ii in the
parallel-axis derivation (1674, 1676); I₁ω₁ω₂ for Iω₁ω₂ and ω₃ for ω₂ in the ψ-derivation
(1748–1752); "I₁ = I₂ = I₂" for the spherical top (1654). Eq. (6.3), the transport theorem
(dQ/dt)_fixed = (dQ/dt)_rot + ω × Q that §7.7.2 relies on, is missing from the document.
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, nonnegative, number, positive
from mechsim.systems._inertia import (
    Part,
    box_inertia,
    composite,
    cylinder_inertia,
    principal_axes,
    sphere_inertia,
)
from mechsim.systems._rigid import (
    RB_EXTRA,
    RIGID_KERNELS,
    QuaternionRigidBody,
    RigidData,
    rb_momentum,
    rb_omega,
    rb_unit,
)
from mechsim.systems._rotation import quat_from_euler_zxz, quat_from_rows, rotate
from mechsim.systems.base import FrameSpec, Quantity, Visual

# --- kernel functions -------------------------------------------------------------------------


def invariants(t, y, p, out):
    """[L_world (3), L·ω/|L|, |q| − 1] without a torque, [|q| − 1] with one (``out.size``)."""
    n = math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3])
    out[out.size - 1] = n - 1.0
    if out.size > 1:
        L = rb_momentum(y, p)
        w = rb_omega(y)
        out[0] = L[3]
        out[1] = L[4]
        out[2] = L[5]
        size = math.sqrt(L[0] * L[0] + L[1] * L[1] + L[2] * L[2])
        out[3] = (w[0] * L[0] + w[1] * L[1] + w[2] * L[2]) / size if size > 0 else 0.0


def observables(t, y, p, out):
    w = rb_omega(y)
    L = rb_momentum(y, p)
    ws = rotate(rb_unit(y), w)
    for i in range(3):
        out[i] = w[i]
        out[3 + i] = L[i]
        out[6 + i] = ws[i]
    out[9] = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    out[10] = math.sqrt(L[0] * L[0] + L[1] * L[1] + L[2] * L[2])


def frames(t, y, p, out):
    q = rb_unit(y)
    for k in range(3):
        out[0, k] = 0.0
    for k in range(4):
        out[0, 3 + k] = q[k]
    # body (shape) frame in the principal frame, and the marker in the body frame: constants
    for k in range(7):
        out[1, k] = p[RB_EXTRA + k]
    for k in range(3):
        out[2, k] = p[RB_EXTRA + 7 + k]
    out[2, 3] = 0.0
    out[2, 4] = 0.0
    out[2, 5] = 0.0
    out[2, 6] = 1.0


# --- the model --------------------------------------------------------------------------------

SHAPES = ("box", "cylinder", "sphere")


class RigidBody(QuaternionRigidBody):
    id = "rigid_body"
    ATTITUDE_FRAME = "principal"  # q poses the principal axes (see ``frames``)
    title = "Free rigid body (Euler's equations, quaternion attitude)"
    source = ("PHYS0500 – Advanced Classical Mechanics, §7.2–7.7 (inertia tensor, principal axes, "
              "Euler's equations)")
    oracles = ("box/cylinder/sphere tensors and parallel axis; spin stability about the "
               "extreme axes at ω₀√((I_k−I_i)(I_k−I_j)/(I_iI_j)), intermediate-axis flip; "
               "L (space) and 2T = ω·L conserved; agrees with a rotation-matrix integration")
    parameters = (
        Parameter("shape", "box", "", "solid: box (edges size.x/y/z), cylinder (radius, "
                  "length along z) or sphere (radius)", choices=SHAPES),
        positive("mass", 1.0, "kg", "mass of the solid"),
        positive("size.x", 0.3, "m", "box edge along x"),
        positive("size.y", 0.2, "m", "box edge along y"),
        positive("size.z", 0.1, "m", "box edge along z"),
        positive("radius", 0.05, "m", "cylinder or sphere radius"),
        positive("length", 0.3, "m", "cylinder length (along z)"),
        nonnegative("tip_mass", 0.0, "kg", "extra point mass fixed to the solid"),
        number("tip_position.x", 0.15, "m", "point mass position x in the shape's frame"),
        number("tip_position.y", 0.0, "m", "point mass position y in the shape's frame"),
        number("tip_position.z", 0.0, "m", "point mass position z in the shape's frame"),
        number("torque.x", 0.0, "N m", "constant torque along principal axis 1"),
        number("torque.y", 0.0, "N m", "constant torque along principal axis 2"),
        number("torque.z", 0.0, "N m", "constant torque along principal axis 3"),
        number("initial.phi", 0.0, "rad", "initial attitude: z-x-z Euler angle φ"),
        number("initial.theta", 0.0, "rad", "initial attitude: z-x-z Euler angle θ"),
        number("initial.psi", 0.0, "rad", "initial attitude: z-x-z Euler angle ψ"),
        number("initial.omega_1", 0.02, "rad/s", "initial ω along principal axis 1"),
        number("initial.omega_2", 4.0, "rad/s", "initial ω along principal axis 2 "
               "(the intermediate axis of the default box: it flips)"),
        number("initial.omega_3", 0.02, "rad/s", "initial ω along principal axis 3"),
    )
    kernel_functions = (*RIGID_KERNELS, invariants, observables, frames)

    # --- the body ------------------------------------------------------------------------
    def parts(self) -> list[Part]:
        m = self.value("mass")
        shape = str(self.values["shape"])
        if shape == "box":
            solid = box_inertia(m, (self.value("size.x"), self.value("size.y"),
                                    self.value("size.z")))
        elif shape == "cylinder":
            solid = cylinder_inertia(m, self.value("radius"), self.value("length"))
        else:
            solid = sphere_inertia(m, self.value("radius"))
        parts = [Part(m, solid)]
        if self.value("tip_mass") > 0:
            parts.append(Part(self.value("tip_mass"), np.zeros((3, 3)), self.tip_position()))
        return parts

    def tip_position(self) -> tuple[float, float, float]:
        return (self.value("tip_position.x"), self.value("tip_position.y"),
                self.value("tip_position.z"))

    def inertia(self) -> tuple[float, np.ndarray, np.ndarray]:
        """Total mass, centre of mass (shape frame) and tensor about the CM (shape axes)."""
        return composite(self.parts())

    def principal(self) -> tuple[np.ndarray, np.ndarray]:
        """Principal moments (I₁, I₂, I₃) and axes Q (columns, in shape axes)."""
        return principal_axes(self.inertia()[2])

    def marker(self) -> tuple[float, float, float]:
        """A point of the body to trace: the tip mass, else the shape's +x end."""
        if self.value("tip_mass") > 0:
            return self.tip_position()
        shape = str(self.values["shape"])
        reach = self.value("size.x") / 2 if shape == "box" else self.value("radius")
        return (reach, 0.0, 0.0)

    def rigid_data(self) -> RigidData:
        _, cm, _ = self.inertia()
        moments, Q = self.principal()
        qb = np.empty(4)
        quat_from_rows(Q.copy(), qb)  # rows of Q = shape axes in principal components
        origin = -Q.T @ cm
        extra = (*origin, *qb, *self.marker())
        return RigidData(moments=tuple(moments),  # type: ignore[arg-type]
                         torque=(self.value("torque.x"), self.value("torque.y"),
                                 self.value("torque.z")),
                         extra=tuple(float(x) for x in extra))

    def check(self) -> None:
        moments, _ = self.principal()
        if min(moments) <= 1e-12 * max(moments):
            raise ParameterError("shape", "the body has a vanishing principal moment")
        if self.value("tip_mass") > 0 and np.allclose(self.tip_position(), 0.0):
            raise ParameterError("tip_position.x", "a tip mass at the centre changes nothing: "
                                 "move it away from the shape's centre")

    def initial_attitude(self) -> tuple[np.ndarray, np.ndarray]:
        q = np.empty(4)
        quat_from_euler_zxz(self.value("initial.phi"), self.value("initial.theta"),
                            self.value("initial.psi"), q)
        return q, np.array([self.value(f"initial.omega_{i}") for i in (1, 2, 3)])

    # --- outputs -------------------------------------------------------------------------
    @property
    def invariants(self) -> tuple[Quantity, ...]:
        out: tuple[Quantity, ...] = ()
        if self.torque_free():
            out = (Quantity("angular_momentum_x", "kg m^2/s", "L along world x (fixed)"),
                   Quantity("angular_momentum_y", "kg m^2/s", "L along world y (fixed)"),
                   Quantity("angular_momentum_z", "kg m^2/s", "L along world z (fixed)"),
                   Quantity("omega_along_momentum", "rad/s",
                            "ω·L/|L| = 2T/|L| (Poinsot: ω's tip stays on the invariable plane)"))
        return out + super().invariants

    @property
    def observables(self) -> tuple[Quantity, ...]:
        return (*(Quantity(f"omega_{i}", "rad/s", f"ω along principal axis {i}")
                  for i in (1, 2, 3)),
                *(Quantity(f"angular_momentum_{i}", "kg m^2/s", f"L along principal axis {i}")
                  for i in (1, 2, 3)),
                *(Quantity(f"space_omega_{a}", "rad/s", f"ω along world {a}") for a in "xyz"),
                Quantity("angular_speed", "rad/s", "|ω|"),
                Quantity("angular_momentum", "kg m^2/s", "|L|"))

    @property
    def frames(self) -> tuple[FrameSpec, ...]:
        return (FrameSpec("principal", "world"), FrameSpec("body", "principal", static=True),
                FrameSpec("marker", "body", static=True))

    def visuals(self) -> tuple[Visual, ...]:
        shape = str(self.values["shape"])
        color = (200, 160, 90)
        if shape == "box":
            solid = Visual("box", "body", size=(self.value("size.x") / 2,
                                                self.value("size.y") / 2,
                                                self.value("size.z") / 2), color=color)
        elif shape == "cylinder":
            r, h = self.value("radius"), self.value("length") / 2
            ring = [(r * math.cos(a), r * math.sin(a)) for a in np.linspace(0, 2 * math.pi, 33)]
            pts = [(x, y, -h) for x, y in ring] + [(x, y, h) for x, y in ring]
            solid = Visual("polyline", "body", points=tuple(pts), radius=0.005, color=color)
        else:
            solid = Visual("sphere", "body", radius=self.value("radius"), color=color)
        out = [solid, Visual("axes", "principal", radius=0.25),
               Visual("sphere", "marker", radius=0.015, color=(240, 80, 80)),
               Visual("trail", "marker", color=(240, 120, 120))]
        return tuple(out)

    def time_scale(self) -> float:
        w = math.sqrt(sum(self.value(f"initial.omega_{i}") ** 2 for i in (1, 2, 3)))
        return 2 * math.pi / w if w > 0 else 1.0

    # --- analytic oracles ----------------------------------------------------------------
    def spin_stability(self, axis: int) -> float:
        """Ω² for a steady spin ω₀ (the initial |ω|) about principal axis ``axis`` (1..3):
        a small perturbation oscillates at √Ω² if Ω² > 0 (largest or smallest moment) and
        grows as exp(√(−Ω²) t) if Ω² < 0 (intermediate axis), Ω² = ω₀²(I_k − I_i)(I_k −
        I_j)/(I_i I_j) (linearised Euler equations; catalog 003 §7.7 [SUPPLEMENT])."""
        moments, _ = self.principal()
        k = axis - 1
        i, j = (k + 1) % 3, (k + 2) % 3
        w0 = math.sqrt(sum(self.value(f"initial.omega_{n}") ** 2 for n in (1, 2, 3)))
        Ik, Ii, Ij = moments[k], moments[i], moments[j]
        return w0 * w0 * (Ik - Ii) * (Ik - Ij) / (Ii * Ij)


MODEL = RigidBody
