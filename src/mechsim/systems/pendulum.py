"""Simple pendulum, reduced coordinates and Lagrange-multiplier form.

Source: seed 000, S1 "Dynamical Systems and Constraints: Part 3 – Simple Pendulum" (L3–97).

Conventions (the document's are ambiguous or wrong here):
- Axes follow REP-103: z up. The pendulum swings in the y–z plane of its ``pivot`` frame;
  ``angle`` φ is measured from straight down and a positive φ is a right-handed rotation about
  +x, so the bob sits at (0, R sin φ, −R cos φ). (The document points gravity along +x.)
- V = m g R (1 − cos φ): zero at the lowest point, which is what L13 intends (its L has the
  zero at pivot height). Only the constant differs.
- Multiplier form: Cartesian (y, z) with the constraint ρ − R = 0 (the document's ρ = R, L78),
  so λ is the outward radial force and λ = −T (the document's "λ = T", L95, has the sign wrong;
  its L93 also drops m from the first term). ``tension`` T = m g cos φ + m R φ̇² (L28).
"""

from __future__ import annotations

import math

import numpy as np
import sympy as sp
from scipy.special import ellipk

from mechsim.params import Parameter, nonnegative, positive
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class Pendulum(LagrangianModel):
    id = "pendulum"
    title = "Simple pendulum (reduced and Lagrange-multiplier forms)"
    source = "seed 000 S1: Dynamical Systems and Constraints, Part 3 – Simple Pendulum"
    formulations = ("reduced", "multiplier")
    oracles = "exact period 4√(R/g)K(k); tension mg(3cosφ − 2cosφ₀); λ = −T; both forms agree"
    parameters = (
        positive("mass", 1.0, "kg", "bob mass m"),
        positive("length", 1.0, "m", "rod length R"),
        nonnegative("gravity", 9.81, "m/s^2", "gravitational acceleration g"),
        Parameter("initial.angle", 1.0, "rad", "initial angle φ from straight down",
                  minimum=-math.pi, maximum=math.pi),
        Parameter("initial_rate.angle", 0.0, "rad/s", "initial angular rate φ̇"),
    )

    def declare(self, b: LagrangianBuilder) -> None:
        m, R, g = b.param("mass"), b.param("length"), b.param("gravity")
        if self.formulation == "reduced":
            phi, dphi = b.coordinate("angle", "rad")
            b.kinetic = m * R**2 * dphi**2 / 2
            b.potential = m * g * R * (1 - sp.cos(phi))
            b.observable("tension", "N", m * g * sp.cos(phi) + m * R * dphi**2)
            bob = (sp.Integer(0), R * sp.sin(phi), -R * sp.cos(phi))
            angle = phi
        else:
            y, dy = b.coordinate("y", "m")
            z, dz = b.coordinate("z", "m")
            b.kinetic = m * (dy**2 + dz**2) / 2
            b.potential = m * g * (z + R)
            b.constraint("rod_length", sp.sqrt(y**2 + z**2) - R)
            lam = b.multiplier(0)
            b.observable("tension", "N", -lam)
            b.observable("multiplier", "N", lam)
            angle = sp.atan2(y, -z)
            b.observable("angle", "rad", angle)
            bob = (sp.Integer(0), y, z)
        b.frame("pivot", "world", (0, 0, 0))
        b.frame("bob", "pivot", bob, (sp.sin(angle / 2), 0, 0, sp.cos(angle / 2)))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        phi, w = self.value("initial.angle"), self.value("initial_rate.angle")
        if self.formulation == "reduced":
            return np.array([phi]), np.array([w])
        R = self.value("length")
        return (np.array([R * math.sin(phi), -R * math.cos(phi)]),
                np.array([R * math.cos(phi) * w, R * math.sin(phi) * w]))

    def time_scale(self) -> float:
        g = self.value("gravity")
        return 2 * math.pi * math.sqrt(self.value("length") / g) if g > 0 else 1.0

    # --- analytic oracles (derived in the catalog, checked in tests/test_pendulum.py) --------
    def amplitude(self) -> float:
        """Turning angle φ_max of a libration: cos φ_max = cos φ₀ − R φ̇₀² / (2 g)."""
        c = math.cos(self.value("initial.angle")) - (
            self.value("length") * self.value("initial_rate.angle") ** 2
            / (2 * self.value("gravity")))
        if c <= -1.0:
            raise ValueError("the pendulum circulates: no amplitude")
        return math.acos(c)

    def exact_period(self) -> float:
        """T = 4 √(R/g) K(k), k = sin(φ_max / 2) (K takes the parameter m = k²)."""
        k = math.sin(self.amplitude() / 2)
        return 4 * math.sqrt(self.value("length") / self.value("gravity")) * float(ellipk(k * k))

    def tension_at(self, phi: np.ndarray) -> np.ndarray:
        """Rod tension at angle φ: T = m g (3 cos φ − 2 cos φ_max) (from energy conservation)."""
        return self.value("mass") * self.value("gravity") * (
            3 * np.cos(phi) - 2 * math.cos(self.amplitude()))

MODEL = Pendulum
