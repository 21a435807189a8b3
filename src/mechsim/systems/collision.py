"""Elastic collision of two smooth spheres in a plane: LAB and CM frames, exact contact event.

Source: PHYS0500 §5.2 ("Elastic Collisions of Two Particles", lines 1081–1213). The
document derives from the conservation laws alone the LAB ↔ CM relations; the force law it says
is missing is supplied here by finite-size hard spheres: m₁ (radius R₁) moves with velocity u₁
along +x, m₂ (radius R₂) is at rest in the LAB, and the line of u₁ passes the centre of m₂ at the
impact parameter b. Between contacts both move freely (V = 0). The contact is a state event,
|r₁ − r₂| = R₁ + R₂ reached while approaching, located on the dense output (its event function
is the distance still to run along the relative velocity before the spheres touch, linear in t
in free flight, see ``_scattering.contact_function``); the handler applies the elastic impulse
along the line of centres (frictionless spheres), which conserves momentum, kinetic energy and
angular momentum exactly across the jump.

Conventions: motion in the world x–y plane (z = 0), which is the LAB frame; particle 2 starts at
the origin, particle 1 at distance ``initial.distance`` on the line y = b (b ≥ 0 above the axis).
Formulations: ``lab`` (coordinates x_1, y_1, x_2, y_2) and ``cm`` (centre of mass cm_x, cm_y
and relative position x, y of r = r₁ − r₂; T = ½MṘ² + ½μṙ²). Frames: ``cm`` (the CM frame,
translating at the constant V = m₁u₁/M), ``particle_1`` and ``particle_2`` as children of ``cm``
(so their poses are the CM-frame positions, and tf composes the LAB ones).

Angles (unsigned, as in the document): θ = CM deflection (of r₁ − r₂'s velocity from u₁),
ψ = ``lab_angle_1`` (LAB θ₁) of m₁, ζ = ``lab_angle_2`` (LAB θ₂) of m₂ (0 while m₂ is at rest).
Oracles (checked in the tests): θ = 2 arccos(b/(R₁ + R₂)); tan ψ = sin θ/(cos θ + m₁/m₂)
(eq. 5.3–5.4); 2ζ = π − θ (line 1209); T₂/T₀ = 2m₁m₂(1 − cos θ)/M² (catalog supplement);
sin ψ_max = m₂/m₁ for m₁ > m₂; ψ = θ/2 and ψ + ζ = π/2 for m₁ = m₂ (lines 1188, 1213).

Typos fixed (see the catalog): v₁′ = m₂u₁/M (line 1159 prints m₂u₂); tan ζ has v₂′ in the
numerator (line 1201 prints v₁′); the second T₁ of line 1101 is T₁′.
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import nonnegative, positive
from mechsim.systems._scattering import (
    contact_function,
    deflection,
    elastic_impulse,
    energy_shares,
    hard_sphere_deflection,
    lab_angle,
    max_lab_angle,
    recoil_angle,
    reflect,
)
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class Collision(LagrangianModel):
    id = "collision"
    title = "Elastic collision of two spheres (LAB and CM frames, contact event)"
    source = "PHYS0500 – Advanced Classical Mechanics, §5.2 (Elastic Collisions of Two Particles)"
    formulations = ("lab", "cm")
    oracles = ("contact time; θ = 2arccos(b/(R₁+R₂)); tan ψ = sinθ/(cosθ + m₁/m₂); 2ζ = π − θ; "
               "T₂/T₀ = 2m₁m₂(1 − cosθ)/M²; sin ψ_max = m₂/m₁; momentum, energy, L across the "
               "impulse")
    parameters = (
        positive("mass_1", 2.0, "kg", "mass m₁ of the moving particle"),
        positive("mass_2", 1.0, "kg", "mass m₂ of the struck particle (at rest in the LAB)"),
        positive("radius_1", 0.1, "m", "radius R₁ of sphere 1"),
        positive("radius_2", 0.15, "m", "radius R₂ of sphere 2"),
        positive("initial.speed", 1.0, "m/s", "LAB speed u₁ of particle 1 (along +x)"),
        nonnegative("impact_parameter", 0.15, "m", "impact parameter b: distance of particle "
                    "2's centre from the line of u₁ (a collision needs b < R₁ + R₂)"),
        positive("initial.distance", 1.0, "m", "initial distance |r₁ − r₂| of the centres"),
    )

    def check(self) -> None:
        a = self.value("radius_1") + self.value("radius_2")
        d = self.value("initial.distance")
        if d <= a:
            raise ParameterError("initial.distance", f"must be > radius_1 + radius_2 = {a:g} "
                                 "(the spheres must not overlap)")
        if d <= self.value("impact_parameter"):
            raise ParameterError("initial.distance", "must be > impact_parameter")

    def declare(self, b: LagrangianBuilder) -> None:
        m1, m2 = b.param("mass_1"), b.param("mass_2")
        M = m1 + m2
        mu = m1 * m2 / M
        a = b.param("radius_1") + b.param("radius_2")
        u = b.param("initial.speed")
        if self.formulation == "lab":
            x1, dx1 = b.coordinate("x_1", "m")
            y1, dy1 = b.coordinate("y_1", "m")
            x2, dx2 = b.coordinate("x_2", "m")
            y2, dy2 = b.coordinate("y_2", "m")
            b.kinetic = m1 * (dx1**2 + dy1**2) / 2 + m2 * (dx2**2 + dy2**2) / 2
            X, Y = (m1 * x1 + m2 * x2) / M, (m1 * y1 + m2 * y2) / M
            dX, dY = (m1 * dx1 + m2 * dx2) / M, (m1 * dy1 + m2 * dy2) / M
            x, y, dx, dy = x1 - x2, y1 - y2, dx1 - dx2, dy1 - dy2
        else:
            X, dX = b.coordinate("cm_x", "m")
            Y, dY = b.coordinate("cm_y", "m")
            x, dx = b.coordinate("x", "m")
            y, dy = b.coordinate("y", "m")
            b.kinetic = M * (dX**2 + dY**2) / 2 + mu * (dx**2 + dy**2) / 2
            x1, y1, x2, y2 = X + m2 / M * x, Y + m2 / M * y, X - m1 / M * x, Y - m1 / M * y
            dx1, dy1 = dX + m2 / M * dx, dY + m2 / M * dy
            dx2, dy2 = dX - m1 / M * dx, dY - m1 / M * dy
        b.potential = sp.Integer(0)
        r = sp.sqrt(x**2 + y**2)
        b.event("contact", contact_function(x, y, dx, dy, a), -1,
                "the spheres touch (|r₁ − r₂| = R₁ + R₂) while approaching: elastic impulse")
        b.invariant("momentum_x", "kg m/s", M * dX)
        b.invariant("momentum_y", "kg m/s", M * dY)
        b.invariant("angular_momentum", "kg m^2/s",
                    m1 * (x1 * dy1 - y1 * dx1) + m2 * (x2 * dy2 - y2 * dx2))
        b.invariant("internal_kinetic_energy", "J", mu * (dx**2 + dy**2) / 2)
        b.observable("lab_angle_1", "rad", deflection(dx1, dy1, u))
        b.observable("lab_angle_2", "rad", deflection(dx2, dy2, u))
        b.observable("cm_angle", "rad", deflection(dx, dy, u))
        T1, T2 = m1 * (dx1**2 + dy1**2) / 2, m2 * (dx2**2 + dy2**2) / 2
        b.observable("kinetic_energy_1", "J", T1)
        b.observable("kinetic_energy_2", "J", T2)
        b.observable("energy_fraction_2", "", T2 / (T1 + T2))
        b.observable("gap", "m", r - a)
        b.observable("cm_velocity_1_x", "m/s", dx1 - dX)
        b.observable("cm_velocity_1_y", "m/s", dy1 - dY)
        b.observable("cm_velocity_2_x", "m/s", dx2 - dX)
        b.observable("cm_velocity_2_y", "m/s", dy2 - dY)
        b.frame("cm", "world", (X, Y, 0))
        b.frame("particle_1", "cm", (x1 - X, y1 - Y, 0))
        b.frame("particle_2", "cm", (x2 - X, y2 - Y, 0))

    # --- state ----------------------------------------------------------------------------------
    def _lab_initial(self) -> tuple[np.ndarray, ...]:
        d, bb = self.value("initial.distance"), self.value("impact_parameter")
        r1 = np.array([-math.sqrt(d * d - bb * bb), bb])
        return r1, np.zeros(2), np.array([self.value("initial.speed"), 0.0]), np.zeros(2)

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        r1, r2, v1, v2 = self._lab_initial()
        if self.formulation == "lab":
            return np.concatenate([r1, r2]), np.concatenate([v1, v2])
        m1, m2 = self.value("mass_1"), self.value("mass_2")
        M = m1 + m2
        return (np.concatenate([(m1 * r1 + m2 * r2) / M, r1 - r2]),
                np.concatenate([(m1 * v1 + m2 * v2) / M, v1 - v2]))

    def on_contact(self, t: float, y: np.ndarray) -> np.ndarray:
        """Elastic impulse along the line of centres (frictionless spheres)."""
        if self.formulation == "lab":
            v1, v2 = elastic_impulse(y[0:2] - y[2:4], y[4:6], y[6:8], self.value("mass_1"),
                                     self.value("mass_2"))
            y[4:6], y[6:8] = v1, v2
        else:
            y[6:8] = reflect(y[2:4], y[6:8])
        return y

    def time_scale(self) -> float:
        return (self.value("radius_1") + self.value("radius_2")) / self.value("initial.speed")

    def visuals(self) -> tuple[Visual, ...]:
        return (Visual("sphere", "particle_1", radius=self.value("radius_1"), color=(255, 170, 60)),
                Visual("sphere", "particle_2", radius=self.value("radius_2"),
                       color=(110, 160, 255)),
                Visual("trail", "particle_1", color=(255, 170, 60)),
                Visual("trail", "particle_2", color=(110, 160, 255)),
                Visual("sphere", "cm", radius=0.015, color=(255, 255, 255)),
                Visual("trail", "cm", color=(200, 200, 200)),
                Visual("axes", "cm", radius=0.1))

    # --- analytic oracles (PHYS0500 §5.2; verified in the tests) -------------------------------
    def contact_time(self) -> float:
        """Relative motion is x = −√(d² − b²) + u₁t at height b: touches at x = −√(a² − b²)."""
        a = self.value("radius_1") + self.value("radius_2")
        d, bb = self.value("initial.distance"), self.value("impact_parameter")
        if bb >= a:
            return math.inf
        return (math.sqrt(d * d - bb * bb) - math.sqrt(a * a - bb * bb)) / self.value(
            "initial.speed")

    def cm_angle(self) -> float:
        """θ = 2 arccos(b/(R₁ + R₂)) (reflection at the contact normal; PHYS0500 line 1343)."""
        a = self.value("radius_1") + self.value("radius_2")
        return float(hard_sphere_deflection(self.value("impact_parameter"), a))

    def lab_angles(self) -> tuple[float, float]:
        """(ψ, ζ): tan ψ = sin θ/(cos θ + m₁/m₂), ζ = (π − θ)/2 (ζ = 0 without contact)."""
        th = self.cm_angle()
        psi = float(lab_angle(th, self.value("mass_1") / self.value("mass_2")))
        return psi, (float(recoil_angle(th)) if th > 0 else 0.0)

    def energy_shares(self) -> tuple[float, float]:
        """(T₁/T₀, T₂/T₀) after the collision."""
        t1, t2 = energy_shares(self.cm_angle(), self.value("mass_1"), self.value("mass_2"))
        return float(t1), float(t2)

    def max_lab_angle(self) -> float:
        """arcsin(m₂/m₁) for m₁ > m₂ (π otherwise)."""
        return max_lab_angle(self.value("mass_1"), self.value("mass_2"))


MODEL = Collision
