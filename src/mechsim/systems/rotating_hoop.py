"""Pendulum (bead on a hoop) whose plane is forced to turn about the vertical at constant ω.

Source: Lecture 10 (eqs. 10.49–10.50 and the multiplier remark L323–327): "the
plane of the pendulum is spun at constant angular velocity φ̇ = ω", the torque being "adjusted
to give the constant rotation"; equivalently a bead on a frictionless hoop of radius l spinning
about its vertical diameter.

Conventions: see ``_spherical_pendulum`` (θ from straight down, z up, V = −m g l cos θ). The
hoop's plane has azimuth φ = ωt + φ₀ (parameter ``initial.azimuth`` = φ₀).

Formulations:
- ``reduced``: L = ½ m l²(θ̇² + ω² sin²θ) + m g l cos θ (10.49). T has the term T₀ = ½ m l² ω²
  sin²θ that is not quadratic in the velocities; L has no explicit t, so the energy function
  h = E′ = ½ m l² θ̇² − m g l cos θ − ½ m l² ω² sin²θ (the document's "effective energy") is
  conserved, while the real energy E = T + V is not: E − E₀ = ∫ G ω dt with the required torque
  G = 2 m l² ω sin θ cos θ θ̇ (observable ``torque``).
- ``multiplier``: (θ, φ) with the rheonomic constraint φ − ωt − φ₀ = 0 added with λ (the
  document's "λ(φ − ωt)", garbled as ``( )tl j w-``): λ is exactly the torque G.

The document states E′ = T′ + V′ is conserved; laws here: the effective energy (an invariant in
both forms, and h in the reduced form), the work balance, the constraint — never E.

Oracles: critical speed ω_c = √(g/l); below it θ = 0 is stable with ω_osc² = g/l − ω²; above
it the bead settles off-axis at θ₀ = arccos(g/(lω²)) with ω_osc² = ω² sin²θ₀ (sympy-checked).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.params import Parameter, nonnegative, number, positive
from mechsim.systems import _spherical_pendulum as sph
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Law, Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class RotatingHoop(LagrangianModel):
    id = "rotating_hoop"
    title = "Pendulum forced to turn about the vertical at constant ω (bead on a spinning hoop)"
    source = ("Lecture 10: The Methods of Lagrange Revisited, spherical pendulum whose plane is "
              "forced to rotate at constant ω (eqs. 10.49–10.50)")
    formulations = ("reduced", "multiplier")
    oracles = ("E′ = h conserved, E − E₀ = ∫Gω dt, ω_c = √(g/l), θ₀ = arccos(g/lω²), "
               "ω_osc² = ω²sin²θ₀ (above) or g/l − ω² (below), λ = G")
    parameters = (
        positive("mass", 1.0, "kg", "bead mass m"),
        positive("length", 1.0, "m", "hoop radius (pendulum length) l"),
        positive("gravity", 9.81, "m/s^2", "gravitational acceleration g"),
        nonnegative("angular_velocity", 5.0, "rad/s", "imposed rotation rate ω of the plane "
                    "(critical ω_c = √(g/l) = 3.132 rad/s at the defaults)"),
        Parameter("initial.angle", 0.3, "rad", "initial angle θ from straight down",
                  minimum=-math.pi, maximum=math.pi),
        number("initial_rate.angle", 0.0, "rad/s", "initial θ̇"),
        number("initial.azimuth", 0.0, "rad", "azimuth φ₀ of the plane at t = 0"),
    )

    def declare(self, b: LagrangianBuilder) -> None:
        m, l, g = b.param("mass"), b.param("length"), b.param("gravity")
        w, phi0 = b.param("angular_velocity"), b.param("initial.azimuth")
        th, dth = b.coordinate("angle", "rad")
        V = sph.potential(m, l, g, th)
        if self.formulation == "reduced":
            phi = w * b.t + phi0
            b.kinetic = sph.kinetic(m, l, th, dth, w)
            torque = 2 * m * l**2 * w * sp.sin(th) * sp.cos(th) * dth
        else:
            phi, dphi = b.coordinate("azimuth", "rad")
            b.kinetic = sph.kinetic(m, l, th, dth, dphi)
            b.constraint("rotation", phi - w * b.t - phi0)
            torque = b.multiplier(0)
            b.observable("multiplier", "N m", torque)
        b.potential = V
        b.invariant("effective_energy", "J",
                    m * l**2 * dth**2 / 2 + V - m * l**2 * w**2 * sp.sin(th) ** 2 / 2)
        b.observable("torque", "N m", torque)
        b.observable("torque_power", "W", torque * w)
        b.frame("hoop", "world", (0, 0, 0), (0, 0, sp.sin(phi / 2), sp.cos(phi / 2)))
        b.frame("bead", "hoop", (l * sp.sin(th), 0, -l * sp.cos(th)))

    def laws(self) -> tuple[Law, ...]:
        # E = T + V is not conserved (the torque works on the bead): never list "energy".
        return tuple(law for law in super().laws() if law.kind != "energy")

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        th, dth = self.value("initial.angle"), self.value("initial_rate.angle")
        if self.formulation == "reduced":
            return np.array([th]), np.array([dth])
        return (np.array([th, self.value("initial.azimuth")]),
                np.array([dth, self.value("angular_velocity")]))

    def time_scale(self) -> float:
        return 2 * math.pi * math.sqrt(self.value("length") / self.value("gravity"))

    def visuals(self) -> tuple[Visual, ...]:
        l = self.value("length")  # noqa: E741
        ring = tuple((l * math.sin(a), 0.0, -l * math.cos(a))
                     for a in np.linspace(0, 2 * math.pi, 97))
        return (Visual("polyline", "hoop", points=ring, radius=0.01, color=(180, 180, 190)),
                Visual("axes", "hoop", radius=0.3),
                Visual("sphere", "bead", radius=0.05, color=(230, 120, 60)),
                Visual("trail", "bead", color=(120, 170, 255)))

    # --- analytic oracles (Lecture 10, spherical pendulum forced to rotate (eqs. 10.49–10.50),
    # sympy-checked)
    def critical_speed(self) -> float:
        """ω_c = √(g/l): above it θ = 0 is unstable and the off-axis equilibrium appears."""
        return math.sqrt(self.value("gravity") / self.value("length"))


MODEL = RotatingHoop
