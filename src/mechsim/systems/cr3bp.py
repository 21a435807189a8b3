"""Circular restricted three-body problem (planar): a test particle near two orbiting primaries.

Source: “Action and Reaction”, Case 2 "Driving forces" (L804–825).

Two primaries m₁, m₂ move on circles about their barycentre (the origin of ``world``) at
separation L and rate ω; a massless test particle moves in their plane. Its back-reaction is
ignored, so the primaries drive it: the inertial specific energy E and angular momentum L_z of
the particle are not conserved, only the Jacobi integral J = E − ω L_z (all per unit mass of the
test particle, J/kg). C_J = −2J is the usual Jacobi constant.

Layout (the document's, L814–817): with û = (cos ωt, sin ωt), m₁ sits at +(m₂/M) L û and m₂ at
−(m₁/M) L û, M = m₁ + m₂. In the co-rotating (synodic) frame m₁ is on +x and m₂ on −x: the
textbook layout (mass 1 − μ at −μ) turned by π, so every Lagrange point below is the textbook
one with both coordinates negated. Naming: L1 between the primaries, L2 beyond m₂, L3 beyond
m₁, L4 / L5 the equilateral points 60° ahead of / behind m₂ in the sense of the rotation (+z).

Typos of the document fixed here: ω² = G(m₁ + m₂)/L³ (L821 has ω without the square); G
multiplies the masses in the equation of motion (L810 omits it); the barycentric positions carry
m₂/M and m₁/M (L814–817 assume m₁ + m₂ = 1); the stray parenthesis of L817.

Formulations: ``inertial`` (x, y in ``world``; V depends on t through the primaries, so E = h
is not conserved) and ``synodic`` (ξ, η in the co-rotating frame; T is the inertial kinetic
energy written in rotating coordinates, so the engine's energy function h is J and E = T + V is
the inertial energy). Initial conditions are inertial (x, y, ẋ, ẏ) at t = 0, where the frames
coincide, for both formulations.
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Law, Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class CR3BP(LagrangianModel):
    id = "cr3bp"
    title = "Circular restricted three-body problem (planar)"
    source = ("“Action and Reaction” (blog post), Case 2 – Driving forces (circular restricted "
              "three-body problem)")
    formulations = ("inertial", "synodic")
    oracles = ("Jacobi integral J = E − ωL_z conserved while E, L_z vary; five Lagrange points "
               "are equilibria (collinear ones against published Earth–Moon values); forms agree")
    parameters = (
        positive("gravitational_constant", 1.0, "m^3/(kg s^2)", "gravitational constant G"),
        positive("primary_mass", 0.9, "kg", "mass m₁ of the first primary (on +x of synodic)"),
        positive("secondary_mass", 0.1, "kg", "mass m₂ of the second primary (on −x of synodic)"),
        positive("separation", 1.0, "m", "distance L between the primaries"),
        number("initial.x", 0.5, "m", "initial inertial x of the test particle"),
        number("initial.y", 0.0, "m", "initial inertial y of the test particle"),
        number("initial_rate.x", 0.0, "m/s", "initial inertial ẋ of the test particle"),
        number("initial_rate.y", 0.9, "m/s", "initial inertial ẏ of the test particle"),
    )

    def check(self) -> None:
        r = np.array([self.value("initial.x"), self.value("initial.y")])
        for name, p in (("primary", self.primary_positions()[0]),
                        ("secondary", self.primary_positions()[1])):
            if np.hypot(*(r - p)) < 1e-6 * self.value("separation"):
                raise ParameterError("initial.x", f"the test particle starts on the {name}")

    # --- declaration -----------------------------------------------------------------------
    def declare(self, b: LagrangianBuilder) -> None:
        G, m1, m2, L = (b.param("gravitational_constant"), b.param("primary_mass"),
                        b.param("secondary_mass"), b.param("separation"))
        M = m1 + m2
        w = sp.sqrt(G * M / L**3)
        a1, a2 = m2 / M * L, -m1 / M * L  # synodic x of m₁ and m₂
        t = b.t
        c, s = sp.cos(w * t), sp.sin(w * t)
        if self.formulation == "inertial":
            x, dx = b.coordinate("x", "m")
            y, dy = b.coordinate("y", "m")
            vx, vy = dx, dy
            xi, eta = c * x + s * y, -s * x + c * y
        else:
            xi, dxi = b.coordinate("xi", "m")
            eta, deta = b.coordinate("eta", "m")
            x, y = c * xi - s * eta, s * xi + c * eta
            ux, uy = dxi - w * eta, deta + w * xi  # inertial velocity in synodic axes
            vx, vy = c * ux - s * uy, s * ux + c * uy
        rho1 = sp.sqrt((xi - a1) ** 2 + eta**2)
        rho2 = sp.sqrt((xi - a2) ** 2 + eta**2)
        V = -G * m1 / rho1 - G * m2 / rho2
        if self.formulation == "inertial":
            b.kinetic = (vx**2 + vy**2) / 2
        else:
            b.kinetic = (ux**2 + uy**2) / 2  # = ½|v_inertial|²: T₂ + T₁ + T₀ in ξ, η
        b.potential = V
        E = (vx**2 + vy**2) / 2 + V
        Lz = x * vy - y * vx
        J = E - w * Lz
        b.invariant("jacobi", "J/kg", J)
        b.observable("inertial_energy", "J/kg", E)
        b.observable("angular_momentum_z", "m^2/s", Lz)
        b.observable("jacobi_constant", "m^2/s^2", -2 * J)
        b.observable("distance_primary", "m", rho1)
        b.observable("distance_secondary", "m", rho2)
        b.frame("synodic", "world", (0, 0, 0), (0, 0, sp.sin(w * t / 2), sp.cos(w * t / 2)))
        b.frame("primary", "synodic", (a1, 0, 0))
        b.frame("secondary", "synodic", (a2, 0, 0))
        b.frame("particle", "world", (x, y, 0))

    def laws(self) -> tuple[Law, ...]:
        # E is not conserved in either formulation (the primaries drive the particle); J is.
        return tuple(law for law in super().laws() if law.kind != "energy")

    def visuals(self) -> tuple[Visual, ...]:
        L = self.value("separation")
        return (Visual("axes", "synodic", radius=0.3 * L),
                Visual("sphere", "primary", radius=0.06 * L, color=(255, 200, 80)),
                Visual("sphere", "secondary", radius=0.035 * L, color=(120, 170, 255)),
                Visual("sphere", "particle", radius=0.015 * L),
                Visual("trail", "particle", color=(200, 200, 200)))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        x, y = self.value("initial.x"), self.value("initial.y")
        vx, vy = self.value("initial_rate.x"), self.value("initial_rate.y")
        if self.formulation == "inertial":
            return np.array([x, y]), np.array([vx, vy])
        w = self.rotation_rate()
        return np.array([x, y]), np.array([vx + w * y, vy - w * x])

    def time_scale(self) -> float:
        return 2 * math.pi / self.rotation_rate()

    # --- analytic results ------------------------------------------------------------------
    def rotation_rate(self) -> float:
        """ω = √(G(m₁ + m₂)/L³) (Kepler III; the document's L821 lacks the square)."""
        G, L = self.value("gravitational_constant"), self.value("separation")
        return math.sqrt(G * (self.value("primary_mass") + self.value("secondary_mass")) / L**3)

    def mass_ratio(self) -> float:
        """μ = m₂ / (m₁ + m₂)."""
        m1, m2 = self.value("primary_mass"), self.value("secondary_mass")
        return m2 / (m1 + m2)

    def primary_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """Synodic positions of m₁ and m₂ (the inertial ones at t = 0)."""
        mu, L = self.mass_ratio(), self.value("separation")
        return np.array([mu * L, 0.0]), np.array([-(1 - mu) * L, 0.0])

    def lagrange_points(self) -> dict[str, np.ndarray]:
        """Synodic positions of L1…L5 (this module's layout: the textbook points negated).

        Textbook layout (m₁ at −μ, m₂ at 1 − μ, units of L): the collinear points are the roots
        of ∂Ω/∂x = 0 on y = 0, Ω = ½x² + (1−μ)/r₁ + μ/r₂, bracketed in (−μ, 1−μ),
        (1−μ, 2) and (−2, −μ); L4/L5 = (½ − μ, ±√3/2).
        """
        mu, L = self.mass_ratio(), self.value("separation")

        def dOmega(x: float) -> float:
            r1, r2 = x + mu, x - (1 - mu)
            return x - (1 - mu) * r1 / abs(r1) ** 3 - mu * r2 / abs(r2) ** 3

        from scipy.optimize import brentq  # here: importing scipy.optimize costs 0.2-0.4 s

        eps = 1e-12
        x1 = brentq(dOmega, -mu + eps, 1 - mu - eps, xtol=1e-15, rtol=1e-15)
        x2 = brentq(dOmega, 1 - mu + eps, 2.0, xtol=1e-15, rtol=1e-15)
        x3 = brentq(dOmega, -2.0, -mu - eps, xtol=1e-15, rtol=1e-15)
        h = math.sqrt(3) / 2
        textbook = {"L1": (x1, 0.0), "L2": (x2, 0.0), "L3": (x3, 0.0),
                    "L4": (0.5 - mu, h), "L5": (0.5 - mu, -h)}
        return {k: -L * np.array(v) for k, v in textbook.items()}


MODEL = CR3BP
