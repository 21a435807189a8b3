"""Atwood machine and compound wheel (wheel-and-axle with two hanging masses).

Sources: Introduction to analytical mechanics, "Atwood's machine – equation of motion Lagrangian"
(L611–629):
V = −M₁ g x − M₂ g (l − x), (M₁ + M₂) ẍ = (M₁ − M₂) g; and Introduction to analytical mechanics,
"Conditions of balance" (L372–409): drums of radii R₁, R₂ on one axle, δz₁ = R₁ δφ, δz₂ = −R₂ δφ,
the string tensions are the constraint forces, equilibrium m₁ R₁ = m₂ R₂.

One model covers both: mass 1 hangs from a drum of radius R₁ (``radius_1``) on the −y side of
the axle, mass 2 from a drum of radius R₂ on the +y side, the wheel has moment of inertia I
(``pulley_inertia``; 0 = the document's massless pulley). R₁ = R₂ = R, I = 0 is the classic
Atwood machine with x = ``hang_length`` + R φ the document's string length on M₁'s side.
Dynamics (the dynamic extension of §2.11, catalog [derived]):
φ̈ = g (m₁R₁ − m₂R₂) / (I + m₁R₁² + m₂R₂²), tensions T₁ = m₁ (g − R₁ φ̈), T₂ = m₂ (g + R₂ φ̈).

Formulations:
- ``reduced``: the wheel angle φ only (the document's single coordinate); tensions are
  computed from the acceleration.
- ``multiplier``: φ and the heights z₁, z₂ with the string constraints z₁ + h + R₁ φ = 0 and
  z₂ + h − R₂ φ = 0; the multipliers are the tensions T₁, T₂ (the document's F^z).

Conventions (REP-103, z up): the axle is the ``axle`` frame's x axis; φ is a right-handed
rotation of ``wheel`` about +x, so mass 1 descends when φ grows (z₁ = −h − R₁ φ,
z₂ = −h + R₂ φ; h = ``hang_length`` at φ = 0). V = m₁ g z₁ + m₂ g z₂ (zero at axle height).

Document typos (catalog 001 §10 item 9): a stray superscript X at L618. The compound wheel is
statics only in the text; its dynamics here are the catalog's derived extension.
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.params import nonnegative, number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class Atwood(LagrangianModel):
    id = "atwood"
    title = "Atwood machine and compound wheel (massive pulley optional)"
    source = ("Introduction to analytical mechanics, “Atwood's machine – equation of motion "
              "Lagrangian” and “Conditions of balance” (compound wheel)")
    formulations = ("reduced", "multiplier")
    oracles = ("φ̈ = g(m₁R₁ − m₂R₂)/(I + m₁R₁² + m₂R₂²); Atwood ẍ = (M₁ − M₂)g/(M₁ + M₂), "
               "T = 2M₁M₂g/(M₁ + M₂); multipliers = tensions; rest iff m₁R₁ = m₂R₂")
    parameters = (
        positive("mass_1", 2.0, "kg", "mass m₁ on drum 1 (−y side)"),
        positive("mass_2", 1.0, "kg", "mass m₂ on drum 2 (+y side)"),
        positive("radius_1", 0.2, "m", "radius R₁ of drum 1"),
        positive("radius_2", 0.2, "m", "radius R₂ of drum 2 (= R₁ for an Atwood machine)"),
        nonnegative("pulley_inertia", 0.0, "kg m^2", "moment of inertia I of the wheel about "
                    "its axle (0: massless pulley)"),
        nonnegative("gravity", 9.81, "m/s^2", "gravitational acceleration g"),
        positive("hang_length", 1.0, "m", "string hanging below each drum at φ = 0"),
        number("initial.angle", 0.0, "rad", "initial wheel angle φ"),
        number("initial_rate.angle", 0.0, "rad/s", "initial wheel rate φ̇"),
    )

    def declare(self, b: LagrangianBuilder) -> None:
        m1, m2 = b.param("mass_1"), b.param("mass_2")
        R1, R2 = b.param("radius_1"), b.param("radius_2")
        I, g, h = b.param("pulley_inertia"), b.param("gravity"), b.param("hang_length")
        phi, dphi = b.coordinate("angle", "rad")
        if self.formulation == "reduced":
            z1, z2 = -h - R1 * phi, -h + R2 * phi
            dz1, dz2 = -R1 * dphi, R2 * dphi
            acc = b.acceleration(phi)
            T1, T2 = m1 * (g - R1 * acc), m2 * (g + R2 * acc)
        else:
            z1, dz1 = b.coordinate("z_1", "m")
            z2, dz2 = b.coordinate("z_2", "m")
            b.constraint("string_1", z1 + h + R1 * phi)
            b.constraint("string_2", z2 + h - R2 * phi)
            T1, T2 = b.multiplier(0), b.multiplier(1)
        b.kinetic = I * dphi**2 / 2 + m1 * dz1**2 / 2 + m2 * dz2**2 / 2
        b.potential = m1 * g * z1 + m2 * g * z2
        b.observable("tension_1", "N", T1)
        b.observable("tension_2", "N", T2)
        b.observable("string_length_1", "m", -z1)
        b.observable("net_torque", "N m", T1 * R1 - T2 * R2)
        b.frame("axle", "world", (0, 0, 0))
        b.frame("wheel", "axle", (0, 0, 0), (sp.sin(phi / 2), 0, 0, sp.cos(phi / 2)))
        b.frame("drum_1_tangent", "axle", (0, -R1, 0))
        b.frame("drum_2_tangent", "axle", (0, R2, 0))
        b.frame("mass_1", "axle", (0, -R1, z1))
        b.frame("mass_2", "axle", (0, R2, z2))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        phi, w = self.value("initial.angle"), self.value("initial_rate.angle")
        if self.formulation == "reduced":
            return np.array([phi]), np.array([w])
        h, R1, R2 = self.value("hang_length"), self.value("radius_1"), self.value("radius_2")
        return (np.array([phi, -h - R1 * phi, -h + R2 * phi]),
                np.array([w, -R1 * w, R2 * w]))

    def visuals(self) -> tuple[Visual, ...]:
        def circle(r: float) -> tuple[tuple[float, float, float], ...]:
            return tuple((0.0, r * math.cos(a), r * math.sin(a))
                         for a in np.linspace(0, 2 * math.pi, 49))

        R1, R2 = self.value("radius_1"), self.value("radius_2")
        return (Visual("polyline", "wheel", points=circle(R1), color=(230, 120, 90)),
                Visual("polyline", "wheel", points=circle(R2), color=(90, 160, 230)),
                Visual("axes", "wheel", radius=0.8 * min(R1, R2)),
                Visual("link", "drum_1_tangent", to_frame="mass_1", radius=0.005),
                Visual("link", "drum_2_tangent", to_frame="mass_2", radius=0.005),
                Visual("box", "mass_1", size=(0.05, 0.05, 0.05), color=(230, 120, 90)),
                Visual("box", "mass_2", size=(0.05, 0.05, 0.05), color=(90, 160, 230)))

    def time_scale(self) -> float:
        g = self.value("gravity")
        return math.sqrt(self.value("hang_length") / g) if g > 0 else 1.0

    # --- analytic oracles (Introduction to analytical mechanics, “Atwood's machine – equation of
    # motion Lagrangian” and “Conditions of balance” and its derived dynamic extension)
    def angular_acceleration(self) -> float:
        """φ̈ = g (m₁R₁ − m₂R₂) / (I + m₁R₁² + m₂R₂²)."""
        m1, m2 = self.value("mass_1"), self.value("mass_2")
        R1, R2 = self.value("radius_1"), self.value("radius_2")
        return self.value("gravity") * (m1 * R1 - m2 * R2) / (
            self.value("pulley_inertia") + m1 * R1**2 + m2 * R2**2)

    def tensions(self) -> tuple[float, float]:
        """T₁ = m₁ (g − R₁ φ̈), T₂ = m₂ (g + R₂ φ̈)."""
        a, g = self.angular_acceleration(), self.value("gravity")
        return (self.value("mass_1") * (g - self.value("radius_1") * a),
                self.value("mass_2") * (g + self.value("radius_2") * a))

    def is_balanced(self, rtol: float = 1e-12) -> bool:
        """The document's equilibrium condition m₁R₁ = m₂R₂."""
        a = self.value("mass_1") * self.value("radius_1")
        b = self.value("mass_2") * self.value("radius_2")
        return abs(a - b) <= rtol * max(a, b)

    def angle_at(self, t: np.ndarray) -> np.ndarray:
        """φ(t) = φ₀ + φ̇₀ t + ½ φ̈ t² (constant acceleration)."""
        t = np.asarray(t, dtype=float)
        return (self.value("initial.angle") + self.value("initial_rate.angle") * t
                + 0.5 * self.angular_acceleration() * t**2)


MODEL = Atwood
