"""Particle sliding without friction inside the vertical paraboloid z = a r².

Source: Lecture 10 (eqs. 10.31–10.36), the worked example of Lagrange's
undetermined multipliers: L = ½ m(ṙ² + r²φ̇² + ż²) − m g z with f = z − a r² = 0; the steady
horizontal circle needs v₀ = r₀√(2ag), and "for total (conserved) energy E and (conserved)
angular momentum J_z the Lagrange multiplier has the form" λ = (m g + 4aE + 8a³J_z²/m)/(1 + 4a²r²)².

Conventions: cylindrical (r, φ, z) about the paraboloid's axis +z (REP-103), vertex at the
origin, V = m g z (zero at the vertex). The multiplier enters as M q̈ = f + λ ∂f/∂q, so the
constraint force is λ(−2ar, 0, 1) in (r, φ, z) components: λ is its vertical component, λ ≥ 0
(the wall pushes inward and up; the one-sided contact never lets go, since E ≥ 0) and the
normal force magnitude is λ√(1 + 4a²r²). The document's equations are garbled (symbol-font
glyphs lost); z₀ = a r₀² (L213–216) fixes the reading z = a r² rather than z = r²/a.

Formulations: ``multiplier`` (the document's, with λ) and ``reduced`` (z = a r² substituted;
λ = m[g + 2a(ṙ² + r²φ̇²)]/(1 + 4a²r²) as an observable, from the z equation).
Oracles (sympy-checked): steady circle φ̇ = √(2ag) at any r₀ with λ = mg; small radial
oscillation ω_r = 2√(2ag)/√(1 + 4a²r₀²); the λ(E, J_z, r) identity; E and J_z conserved.
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class ParaboloidBead(LagrangianModel):
    id = "paraboloid_bead"
    title = "Particle sliding inside a vertical paraboloid z = a r² (Lagrange multiplier)"
    source = ("Lecture 10: The Methods of Lagrange Revisited, particle sliding inside a smooth "
              "vertical paraboloid (eqs. 10.31–10.36)")
    formulations = ("multiplier", "reduced")
    oracles = ("steady circle v₀ = r₀√(2ag) with λ = mg, λ = (mg + 4aE + 8a³J²/m)/(1+4a²r²)² ≥ 0, "
               "ω_r = 2√(2ag)/√(1+4a²r₀²), E and J_z conserved")
    parameters = (
        positive("mass", 1.0, "kg", "particle mass m"),
        positive("paraboloid_coefficient", 0.5, "1/m", "a in z = a r²"),
        positive("gravity", 9.81, "m/s^2", "gravitational acceleration g"),
        positive("initial.radius", 1.0, "m", "initial distance r₀ from the axis"),
        number("initial_rate.radius", 0.0, "m/s", "initial ṙ"),
        number("initial.azimuth", 0.0, "rad", "initial azimuth φ"),
        number("initial_rate.azimuth", 2.8, "rad/s", "initial φ̇ (the steady circle needs "
               "√(2ag) = 3.1321 rad/s at the defaults; less makes the radius oscillate)"),
    )

    def check(self) -> None:
        if self.value("initial_rate.azimuth") == 0.0:
            raise ParameterError("initial_rate.azimuth", "must be non-zero: with J_z = 0 the "
                                 "particle passes through the axis, where (r, φ) are singular")

    def declare(self, b: LagrangianBuilder) -> None:
        m, a, g = b.param("mass"), b.param("paraboloid_coefficient"), b.param("gravity")
        r, dr = b.coordinate("radius", "m")
        phi, dphi = b.coordinate("azimuth", "rad")
        if self.formulation == "multiplier":
            z, dz = b.coordinate("height", "m")
            b.kinetic = m * (dr**2 + r**2 * dphi**2 + dz**2) / 2
            b.constraint("surface", z - a * r**2)
            lam = b.multiplier(0)
        else:
            z = a * r**2
            b.kinetic = m * ((1 + 4 * a**2 * r**2) * dr**2 + r**2 * dphi**2) / 2
            lam = m * (g + 2 * a * (dr**2 + r**2 * dphi**2)) / (1 + 4 * a**2 * r**2)
        b.potential = m * g * z
        b.invariant("angular_momentum", "kg m^2/s", m * r**2 * dphi)
        b.observable("multiplier", "N", lam)
        b.observable("normal_force", "N", lam * sp.sqrt(1 + 4 * a**2 * r**2))
        b.observable("height", "m", z)
        b.frame("paraboloid", "world", (0, 0, 0))
        b.frame("particle", "paraboloid", (r * sp.cos(phi), r * sp.sin(phi), z))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        a = self.value("paraboloid_coefficient")
        r0, dr0 = self.value("initial.radius"), self.value("initial_rate.radius")
        q = [r0, self.value("initial.azimuth")]
        v = [dr0, self.value("initial_rate.azimuth")]
        if self.formulation == "multiplier":
            q.append(a * r0 * r0)
            v.append(2 * a * r0 * dr0)
        return np.array(q), np.array(v)

    def time_scale(self) -> float:
        return 2 * math.pi / math.sqrt(2 * self.value("paraboloid_coefficient")
                                       * self.value("gravity"))

    def visuals(self) -> tuple[Visual, ...]:
        a = self.value("paraboloid_coefficient")
        rmax = 1.5 * self.value("initial.radius")
        prof = tuple((float(r), 0.0, a * float(r) ** 2) for r in np.linspace(-rmax, rmax, 61))
        prof2 = tuple((0.0, x, z) for x, _, z in prof)
        rim = tuple((rmax * math.cos(t), rmax * math.sin(t), a * rmax * rmax)
                    for t in np.linspace(0, 2 * math.pi, 73))
        out = [Visual("polyline", "paraboloid", points=p, radius=0.005, color=(170, 170, 180))
               for p in (prof, prof2, rim)]
        return (*out, Visual("sphere", "particle", radius=0.05, color=(230, 120, 60)),
                Visual("trail", "particle", color=(120, 170, 255)))

    # --- analytic oracles (Lecture 10, particle inside a vertical paraboloid (eqs. 10.31–10.36),
    # reconstructed and sympy-checked)
    def steady_rate(self) -> float:
        """φ̇ of the horizontal circle: φ̇² = 2ag (any r₀), so v₀ = r₀√(2ag)."""
        return math.sqrt(2 * self.value("paraboloid_coefficient") * self.value("gravity"))


MODEL = ParaboloidBead
