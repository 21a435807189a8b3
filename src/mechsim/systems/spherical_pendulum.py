"""Spherical pendulum, free or driven by an applied torque G about the vertical.

Source: Lecture 10 (eqs. 10.47–10.48): "a mass moving on the surface of a sphere
of radius l", θ from the down direction, φ the azimuth; L = ½ m l²(θ̇² + sin²θ φ̇²) + m g l cos θ
and d/dt(m l² sin²θ φ̇) = G.

Conventions: see ``_spherical_pendulum`` (REP-103, z up, V = −m g l cos θ, zero at pivot
height). The torque G (parameter ``torque``) is a constant generalized force on φ, so the
energy changes as dE/dt = G φ̇ (work W = G Δφ) and p_φ = m l² sin²θ φ̇ grows as G t. With
G = 0 the model declares p_φ as an invariant and E is conserved; with G ≠ 0 neither is, and
only the work balance is a law. The equations in the document are garbled (symbol-font
glyphs lost); they are rebuilt from the Lagrangian, not typed in.

Oracles: conical pendulum φ̇² = g/(l cos θ₀) (θ₀ < π/2), small oscillation about the cone
ω² = (g/(l cos θ₀))(1 + 3 cos²θ₀); with torque: E − E₀ = G (φ − φ₀), p_φ − p_φ₀ = G t.
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.params import Parameter, number, positive
from mechsim.systems import _spherical_pendulum as sph
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class SphericalPendulum(LagrangianModel):
    id = "spherical_pendulum"
    title = "Spherical pendulum (free, or with an applied vertical torque)"
    source = ("Lecture 10: The Methods of Lagrange Revisited, spherical pendulum, free and with an "
              "applied vertical torque G (eqs. 10.47–10.48)")
    oracles = ("conical rate φ̇² = g/(l cosθ₀), cone oscillation ω² = g(1 + 3cos²θ₀)/(l cosθ₀), "
               "p_φ and E conserved; with torque E − E₀ = GΔφ, Δp_φ = G t")
    parameters = (
        positive("mass", 1.0, "kg", "bob mass m"),
        positive("length", 1.0, "m", "rod length l"),
        positive("gravity", 9.81, "m/s^2", "gravitational acceleration g"),
        number("torque", 0.0, "N m", "applied torque G about the vertical (0: free pendulum)"),
        Parameter("initial.polar_angle", 1.0, "rad", "initial polar angle θ from straight down",
                  minimum=0.0, maximum=math.pi, exclusive_minimum=True, exclusive_maximum=True),
        number("initial_rate.polar_angle", 0.0, "rad/s", "initial θ̇"),
        number("initial.azimuth", 0.0, "rad", "initial azimuth φ"),
        number("initial_rate.azimuth", 4.0, "rad/s", "initial φ̇ (the conical rate for θ₀ = 1 "
               "rad, l = 1 m, g = 9.81 is 4.2610)"),
    )

    def declare(self, b: LagrangianBuilder) -> None:
        m, l, g = b.param("mass"), b.param("length"), b.param("gravity")
        th, dth = b.coordinate("polar_angle", "rad")
        phi, dphi = b.coordinate("azimuth", "rad")
        b.kinetic = sph.kinetic(m, l, th, dth, dphi)
        b.potential = sph.potential(m, l, g, th)
        p_phi = sph.azimuthal_momentum(m, l, th, dphi)
        if self.value("torque") != 0.0:
            G = b.param("torque")
            b.forces = [0, G]
            b.observable("azimuthal_momentum", "kg m^2/s", p_phi)
            b.observable("torque_power", "W", G * dphi)
        else:
            b.invariant("azimuthal_momentum", "kg m^2/s", p_phi)
        b.frame("pivot", "world", (0, 0, 0))
        b.frame("bob", "pivot", sph.bob(l, th, phi))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.array([self.value("initial.polar_angle"), self.value("initial.azimuth")]),
                np.array([self.value("initial_rate.polar_angle"),
                          self.value("initial_rate.azimuth")]))

    def time_scale(self) -> float:
        return 2 * math.pi * math.sqrt(self.value("length") / self.value("gravity"))

    def visuals(self) -> tuple[Visual, ...]:
        return (Visual("link", "pivot", to_frame="bob", radius=0.01),
                Visual("sphere", "bob", radius=0.05, color=(230, 120, 60)),
                Visual("trail", "bob", color=(120, 170, 255)),
                Visual("axes", "pivot", radius=0.2))

    # --- analytic oracles (verified with sympy; checked numerically in the tests) -----------
    def conical_rate(self, theta0: float) -> float:
        """φ̇ of the steady cone at polar angle θ₀ < π/2: φ̇² = g/(l cos θ₀)."""
        return math.sqrt(self.value("gravity") / (self.value("length") * math.cos(theta0)))


MODEL = SphericalPendulum
