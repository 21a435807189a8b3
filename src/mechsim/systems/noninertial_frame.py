"""A free particle seen from a frame whose rotation rate varies and whose origin accelerates: the
four fictitious forces of PHYS0500 – Advanced Classical Mechanics, §6.1, Euler's among them.

Source: PHYS0500 §6.1 (Centrifugal and Coriolis Forces), the effective force (eq. at line 1452)

    m a_r = F − m R̈_f − m ω̇ × r − m ω × (ω × r) − 2m ω × v_r,

with eqs. 6.1–6.4 (r′ = R + r, v_f = V + v_r + ω × r); Lecture 10: The Methods of Lagrange
Revisited, the linearly accelerated frame (eq. 10.24). The notes name the terms: the origin's
acceleration, the azimuthal term −m ω̇ × r (the Euler force; their wording is garbled), the
centrifugal and the Coriolis force.

Conventions: REP-103 axes, z up, SI. The ``moving`` frame turns about +z by
φ(t) = ω₀t + (Δω/Ω)(1 − cos Ωt), so ω(t) = ω₀ + Δω sin Ωt and ω̇ = Δω Ω cos Ωt, and its origin
oscillates along the world x axis, R(t) = A sin Ωt x̂ (R̈ = −AΩ² sin Ωt x̂). The particle moves
in the plane z = 0 and no real force acts on it (F = 0): in the world frame it moves uniformly,
so its inertial kinetic energy, momentum and angular momentum about the world origin are
conserved (``invariants``), while everything seen from the moving frame is driven by the
frame's motion (L depends on t: neither T + V of the moving coordinates nor h is conserved).

Formulations:
- ``moving``: coordinates (x, y) in the moving frame; L = ½ m |Ṙ + R_z(φ)(ṙ + ω ẑ × r)|²,
  from which the engine derives the equation above (no fictitious force is typed in).
- ``inertial``: coordinates (X, Y) in the world frame, L = ½ m (Ẋ² + Ẏ²); the moving-frame
  position r = R_z(−φ)(X − R) is computed for the frames and the force observables.
The observables ``translational_force_*``, ``euler_force_*``, ``centrifugal_force_*`` and
``coriolis_force_*`` are the four terms in moving-frame components (N); their sum is m a_r.
Initial conditions are given in the moving frame at t = 0 (where the frames coincide in
orientation and the origin is at the world origin).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.params import nonnegative, number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class NoninertialFrame(LagrangianModel):
    id = "noninertial_frame"
    title = ("Free particle seen from a frame with a varying rotation rate and an oscillating "
             "origin (Euler, centrifugal, Coriolis and translational forces)")
    source = ("PHYS0500 – Advanced Classical Mechanics, §6.1 (Centrifugal and Coriolis Forces, "
              "the effective force with the ω̇ × r and R̈ terms); Lecture 10: The Methods of "
              "Lagrange Revisited, linearly accelerated frame (eq. 10.24)")
    formulations = ("moving", "inertial")
    oracles = ("uniform inertial motion mapped into the frame; m × (finite-difference a_r) = "
               "sum of the four fictitious forces of §6.1, each against the document's formula; "
               "inertial energy, momentum and angular momentum conserved; forms agree")
    parameters = (
        positive("mass", 1.0, "kg", "particle mass m"),
        number("rotation_rate", 0.5, "rad/s", "mean rotation rate ω₀ of the frame about +z"),
        number("rate_swing", 0.4, "rad/s", "amplitude Δω of ω(t) = ω₀ + Δω sin Ωt"),
        nonnegative("swing_frequency", 0.8, "rad/s",
                    "angular frequency Ω of the rate swing and of the origin's oscillation"),
        number("origin_amplitude", 0.5, "m", "amplitude A of the origin's motion R = A sin Ωt x̂"),
        number("initial.x", 1.0, "m", "initial x in the moving frame"),
        number("initial.y", 0.0, "m", "initial y in the moving frame"),
        number("initial_rate.x", 0.0, "m/s", "initial ẋ relative to the moving frame"),
        number("initial_rate.y", 0.2, "m/s", "initial ẏ relative to the moving frame"),
    )

    def _motion(self, b: LagrangianBuilder) -> tuple[sp.Expr, ...]:
        """φ(t), ω(t), ω̇(t), R(t), Ṙ(t), R̈(t) of the frame (R along world x)."""
        w0, dw, W = b.param("rotation_rate"), b.param("rate_swing"), b.param("swing_frequency")
        A, t = b.param("origin_amplitude"), b.t
        # (1 − cos Ωt)/Ω as 2 sin²(Ωt/2)/Ω: finite (→ 0) as Ω → 0, no 0/0 in the kernel
        phi = w0 * t + dw * 2 * sp.sin(W * t / 2) ** 2 / W if self.value(
            "swing_frequency") > 0 else w0 * t
        w = w0 + dw * sp.sin(W * t)
        wdot = dw * W * sp.cos(W * t)
        R = A * sp.sin(W * t)
        return phi, w, wdot, R, A * W * sp.cos(W * t), -A * W**2 * sp.sin(W * t)

    def declare(self, b: LagrangianBuilder) -> None:
        m = b.param("mass")
        phi, w, wdot, R, dR, ddR = self._motion(b)
        c, s = sp.cos(phi), sp.sin(phi)
        if self.formulation == "moving":
            x, dx = b.coordinate("x", "m")
            y, dy = b.coordinate("y", "m")
            # inertial velocity: Ṙ x̂ + R_z(φ)(ṙ + ω ẑ × r)
            ux, uy = dx - w * y, dy + w * x
            VX, VY = dR + c * ux - s * uy, s * ux + c * uy
            X, Y = R + c * x - s * y, s * x + c * y
        else:
            X, VX = b.coordinate("X", "m")
            Y, VY = b.coordinate("Y", "m")
            x, y = c * (X - R) + s * Y, -s * (X - R) + c * Y
            # ṙ = R_z(−φ)(V − Ṙ x̂) − ω ẑ × r
            dx = c * (VX - dR) + s * VY + w * y
            dy = -s * (VX - dR) + c * VY - w * x
        b.kinetic = m * (VX**2 + VY**2) / 2
        b.invariant("inertial_momentum_x", "kg m/s", m * VX)
        b.invariant("inertial_momentum_y", "kg m/s", m * VY)
        b.invariant("inertial_angular_momentum", "kg m^2/s", m * (X * VY - Y * VX))
        b.invariant("inertial_energy", "J", m * (VX**2 + VY**2) / 2)
        forces = {  # moving-frame components of each term of m a_r (PHYS0500 line 1452)
            "translational_force": (-m * c * ddR, m * s * ddR),  # −m R_z(−φ) R̈ x̂
            "euler_force": (m * wdot * y, -m * wdot * x),  # −m ω̇ ẑ × r
            "centrifugal_force": (m * w**2 * x, m * w**2 * y),  # −m ω ẑ × (ω ẑ × r)
            "coriolis_force": (2 * m * w * dy, -2 * m * w * dx),  # −2m ω ẑ × v_r
        }
        for name, (fx, fy) in forces.items():
            b.observable(f"{name}_x", "N", fx)
            b.observable(f"{name}_y", "N", fy)
        b.observable("rotation_rate", "rad/s", w)
        b.observable("frame_angle", "rad", phi)
        b.frame("moving", "world", (R, 0, 0), (0, 0, sp.sin(phi / 2), sp.cos(phi / 2)))
        b.frame("particle", "moving", (x, y, 0))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        x, y = self.value("initial.x"), self.value("initial.y")
        vx, vy = self.value("initial_rate.x"), self.value("initial_rate.y")
        if self.formulation == "moving":
            return np.array([x, y]), np.array([vx, vy])
        w0 = self.value("rotation_rate")
        dR0 = self.value("origin_amplitude") * self.value("swing_frequency")
        return np.array([x, y]), np.array([dR0 + vx - w0 * y, vy + w0 * x])

    def time_scale(self) -> float:
        rates = [abs(self.value("rotation_rate")) + abs(self.value("rate_swing")),
                 self.value("swing_frequency")]
        fastest = max(rates)
        return 2 * math.pi / fastest if fastest > 0 else 1.0

    def visuals(self) -> tuple[Visual, ...]:
        return (Visual("axes", "moving", radius=0.5),
                Visual("sphere", "particle", radius=0.05, color=(255, 200, 80)),
                Visual("trail", "particle", color=(255, 200, 80)))


MODEL = NoninertialFrame
