"""Scattering of a beam on a hard sphere or a repulsive Coulomb centre: one trajectory per impact
parameter, and the beam's measured differential cross-section.

Source: PHYS0500 §5.3 ("Scattering Cross-Sections", lines 1215–1372): σ(θ) dΩ′ = dN/I,
I 2πb db = −I σ(θ) 2π sin θ dθ (eq. 5.5), σ = (b/sin θ)|db/dθ| (eq. 5.6), θ = π − 2Θ (eq. 5.7)
with the orbit integral Θ(b) (line 1255), the LAB ↔ CM conversion (eq. 5.8–5.10, 1312, 1316) and
the hard-sphere example σ = a²/4, σ_t = πa² (lines 1320–1372). The Rutherford results are the
catalog's supplement (not in the document). Typos fixed: the orbit integral of line 1243 (stray
"ΔΘ", nested square root) is used in the form of line 1255; line 1249 T₀′ = μu₁² → ½μu₁²;
line 1261 σ(θ)dΩ′ = σ(ψ)dΩ′ → σ(θ)dΩ′ = σ(ψ)dΩ; eq. 1312 (one branch) holds for m₁ < m₂ only,
for m₁ > m₂ both CM branches θ = ψ + arcsin(x sin ψ) and π + ψ − arcsin(x sin ψ) add up.

Model (``target``):
- ``hard_sphere``: a point projectile m₁ on an impenetrable sphere of radius a (the document's
  example with r → 0) carried by the target m₂; the contact |r| = a is a state event (the same
  exact event function as ``collision``), the handler reflects the relative velocity at the
  surface normal.
- ``coulomb``: U = k/r, k = q₁q₂/(4πε₀) > 0 (repulsive; same-sign charges).
Coordinates: the centre of mass (cm_x, cm_y) and the relative position r = r₁ − r₂ = (x, y),
T = ½MṘ² + ½μṙ² (the two-body reduction of PHYS0500 §4.1, as in ``central_force``). In the LAB
the target is at rest and the projectile comes in along +x with kinetic energy T₀ (``energy``) on
the line y = b (``impact_parameter``); so V = m₁u₁/M, the relative speed at infinity is u₁ and
the CM energy is E = T₀′ = ½μu₁² = (m₂/M) T₀.
The run starts at |r| = ``initial.distance``: for the Coulomb centre on the exact hyperbola whose
incoming asymptote is that line (from E, L and the Laplace–Runge–Lenz vector), so the long range
of 1/r does not bias the deflection; the target sits at the world origin at t = 0. Motion in the
world x–y plane (LAB); frames ``cm`` (translating at V) and ``particle_1``, ``particle_2`` in it.

Angles (unsigned): ``cm_angle`` θ of ṙ from +x, ``lab_angle_1`` ψ of the projectile,
``lab_angle_2`` ζ of the target; for the Coulomb centre also ``asymptotic_cm_angle``, the θ of
the outgoing asymptote of the current orbit (from its conserved E, L, A; constant).

``beam(model, ...)`` runs many impact parameters through the compiled kernel and returns the
measured cross-sections (histograms of dσ = 2πb db over θ and ψ) with the analytic ones:
hard sphere σ(θ) = a²/4, θ = 2 arccos(b/a); Rutherford σ(θ) = (k/(4E))²/sin⁴(θ/2),
tan(θ/2) = k/(2Eb); LAB σ(ψ) from eq. 5.10 over both CM branches when m₁ > m₂.
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, nonnegative, number, positive
from mechsim.systems._central import declare_orbit_quantities
from mechsim.systems._scattering import (
    contact_function,
    coulomb_closest_approach,
    coulomb_deflection,
    coulomb_incoming_state,
    deflection,
    hard_sphere_cross_section,
    hard_sphere_deflection,
    lab_angle,
    reflect,
    rutherford_cross_section,
)
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

TARGETS = ("hard_sphere", "coulomb")
COULOMB = 8.9875517923e9  # 1/(4πε₀), N m²/C²


class Scattering(LagrangianModel):
    id = "scattering"
    title = "Scattering on a hard sphere or a Coulomb centre (one impact parameter; beam function)"
    source = ("PHYS0500 – Advanced Classical Mechanics, §5.3 (Scattering Cross-Sections: LAB and "
              "CM, hard-sphere example)")
    oracles = ("θ = 2arccos(b/a) and tan(θ/2) = k/(2Eb) per trajectory; beam histograms vs "
               "σ = a²/4 and Rutherford (k/4E)²/sin⁴(θ/2), LAB σ(ψ) (eq. 5.10), σ_t = πa²; "
               "orbit integral (line 1255)")
    parameters = (
        Parameter("target", "coulomb", "", "scattering centre", choices=TARGETS),
        positive("mass_1", 1.0, "kg", "projectile mass m₁"),
        positive("mass_2", 4.0, "kg", "target mass m₂ (at rest in the LAB)"),
        positive("energy", 1.0, "J", "LAB kinetic energy T₀ = ½m₁u₁² of the incoming projectile"),
        positive("sphere_radius", 2.0, "m", "radius a of the hard sphere (hard_sphere)"),
        number("charge_1", 1e-5, "C", "projectile charge q₁ (coulomb)"),
        number("charge_2", 1e-5, "C", "target charge q₂, same sign as q₁ (coulomb)"),
        nonnegative("impact_parameter", 1.0, "m", "impact parameter b"),
        positive("initial.distance", 10.0, "m", "initial distance |r₁ − r₂| of projectile and "
                 "target"),
    )

    @property
    def target(self) -> str:
        return str(self.values["target"])

    def check(self) -> None:
        d, b = self.value("initial.distance"), self.value("impact_parameter")
        if self.target == "coulomb":
            if not self.force_constant() > 0.0:
                raise ParameterError("charge_2", "must be nonzero and of the sign of charge_1 "
                                     "(repulsive Coulomb centre)")
            if not (math.isfinite(self.force_constant()) and math.isfinite(self.cm_energy())):
                raise ParameterError("charge_2", "k = q₁q₂/(4πε₀) / energy out of range")
            rmin = coulomb_closest_approach(b, self.force_constant(), self.cm_energy())
            if not d > rmin:
                raise ParameterError("initial.distance", f"must be > the closest approach "
                                     f"r_min = {rmin:.6g} m")
        else:
            if not d > max(b, self.value("sphere_radius")):
                raise ParameterError("initial.distance", "must be > sphere_radius and > "
                                     "impact_parameter")

    # --- derived constants ----------------------------------------------------------------------
    def reduced_mass(self) -> float:
        m1, m2 = self.value("mass_1"), self.value("mass_2")
        return m1 * m2 / (m1 + m2)

    def speed(self) -> float:
        """u₁ = √(2T₀/m₁): LAB speed of the incoming projectile = relative speed at infinity."""
        return math.sqrt(2.0 * self.value("energy") / self.value("mass_1"))

    def cm_energy(self) -> float:
        """E = T₀′ = ½μu₁² = (m₂/M) T₀ (line 1249 with the ½ restored)."""
        m1, m2 = self.value("mass_1"), self.value("mass_2")
        return m2 / (m1 + m2) * self.value("energy")

    def force_constant(self) -> float:
        """k = q₁q₂/(4πε₀) of U = k/r."""
        return COULOMB * self.value("charge_1") * self.value("charge_2")

    def mass_ratio(self) -> float:
        """x = m₁/m₂ = V/v₁′ (eq. 5.4, 5.9)."""
        return self.value("mass_1") / self.value("mass_2")

    # --- the Lagrangian -------------------------------------------------------------------------
    def declare(self, b: LagrangianBuilder) -> None:
        m1, m2 = b.param("mass_1"), b.param("mass_2")
        M = m1 + m2
        mu = m1 * m2 / M
        X, dX = b.coordinate("cm_x", "m")
        Y, dY = b.coordinate("cm_y", "m")
        x, dx = b.coordinate("x", "m")
        y, dy = b.coordinate("y", "m")
        b.kinetic = M * (dX**2 + dY**2) / 2 + mu * (dx**2 + dy**2) / 2
        r = sp.sqrt(x**2 + y**2)
        u = sp.sqrt(2 * b.param("energy") / m1)
        if self.target == "coulomb":
            k = COULOMB * b.param("charge_1") * b.param("charge_2")
            U = k / r
            # A = p × L + μ k r̂ for U = +k/r (declare_orbit_quantities writes U = −κ/r)
            _, Lz = declare_orbit_quantities(b, mu, x, y, dx, dy, k=-k, radius=r)
            Ax = mu * Lz * dy + mu * k * x / r
            Ay = -mu * Lz * dx + mu * k * y / r
            c, s = mu * k, mu * u * Lz  # outgoing asymptote ê: A = [[c, s], [−s, c]] ê
            b.observable("asymptotic_cm_angle", "rad",
                         sp.atan2(sp.Abs(s * Ax + c * Ay), c * Ax - s * Ay))
        else:
            U = sp.Integer(0)
            declare_orbit_quantities(b, mu, x, y, dx, dy, radius=r)
            b.event("contact", contact_function(x, y, dx, dy, b.param("sphere_radius")), -1,
                    "the projectile reaches the sphere while approaching: elastic reflection")
        b.potential = U
        b.invariant("momentum_x", "kg m/s", M * dX)
        b.invariant("momentum_y", "kg m/s", M * dY)
        b.invariant("relative_energy", "J", mu * (dx**2 + dy**2) / 2 + U)
        dx1, dy1 = dX + m2 / M * dx, dY + m2 / M * dy
        dx2, dy2 = dX - m1 / M * dx, dY - m1 / M * dy
        b.observable("cm_angle", "rad", deflection(dx, dy, u))
        b.observable("lab_angle_1", "rad", deflection(dx1, dy1, u))
        b.observable("lab_angle_2", "rad", deflection(dx2, dy2, u))
        b.observable("kinetic_energy_1", "J", m1 * (dx1**2 + dy1**2) / 2)
        b.observable("kinetic_energy_2", "J", m2 * (dx2**2 + dy2**2) / 2)
        b.frame("cm", "world", (X, Y, 0))
        b.frame("particle_1", "cm", (m2 / M * x, m2 / M * y, 0))
        b.frame("particle_2", "cm", (-m1 / M * x, -m1 / M * y, 0))

    # --- state ----------------------------------------------------------------------------------
    def relative_state(self, b: float) -> tuple[np.ndarray, np.ndarray]:
        """Relative position and velocity at t = 0 for impact parameter ``b``."""
        d, u = self.value("initial.distance"), self.speed()
        if self.target == "coulomb":
            return coulomb_incoming_state(self.reduced_mass(), self.force_constant(), u, b, d)
        return np.array([-math.sqrt(d * d - b * b), b]), np.array([u, 0.0])

    def state_for(self, b: float) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) at t = 0 for impact parameter ``b``: target at the origin, V = m₁u₁/M."""
        m1, m2 = self.value("mass_1"), self.value("mass_2")
        M = m1 + m2
        r, w = self.relative_state(b)
        V = np.array([m1 * self.speed() / M, 0.0])
        return np.concatenate([m1 / M * r, r]), np.concatenate([V, w])

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.state_for(self.value("impact_parameter"))

    def on_contact(self, t: float, y: np.ndarray) -> np.ndarray:
        """Elastic reflection of the relative velocity at the sphere's normal."""
        y[6:8] = reflect(y[2:4], y[6:8])
        return y

    def time_scale(self) -> float:
        return self.length_scale() / self.speed()

    def length_scale(self) -> float:
        """a (hard sphere) or the closest approach r_min(b) (Coulomb)."""
        if self.target == "coulomb":
            return coulomb_closest_approach(self.value("impact_parameter"),
                                            self.force_constant(), self.cm_energy())
        return self.value("sphere_radius")

    def visuals(self) -> tuple[Visual, ...]:
        L = self.length_scale()
        target = (Visual("sphere", "particle_2", radius=self.value("sphere_radius"),
                         color=(110, 160, 255)) if self.target == "hard_sphere" else
                  Visual("sphere", "particle_2", radius=0.08 * L, color=(110, 160, 255)))
        return (target,
                Visual("sphere", "particle_1", radius=0.05 * L, color=(255, 170, 60)),
                Visual("trail", "particle_1", color=(255, 170, 60)),
                Visual("trail", "particle_2", color=(110, 160, 255)),
                Visual("sphere", "cm", radius=0.02 * L, color=(255, 255, 255)),
                Visual("axes", "cm", radius=0.5 * L))

    # --- analytic oracles (PHYS0500 §5.3 and the catalog's supplement; verified in the tests) --
    def deflection(self, b: np.ndarray | float) -> np.ndarray:
        """CM deflection θ(b): 2 arccos(b/a) (hard sphere) or 2 arctan(k/(2Eb)) (Coulomb)."""
        if self.target == "coulomb":
            return coulomb_deflection(b, self.force_constant(), self.cm_energy())
        return hard_sphere_deflection(b, self.value("sphere_radius"))

    def lab_deflection(self, b: np.ndarray | float) -> np.ndarray:
        """ψ(b) from tan ψ = sin θ/(cos θ + m₁/m₂)."""
        return lab_angle(self.deflection(b), self.mass_ratio())

    def cross_section(self, theta: np.ndarray | float) -> np.ndarray:
        """σ(θ) per unit CM solid angle: a²/4 or (k/(4E))²/sin⁴(θ/2)."""
        if self.target == "coulomb":
            return rutherford_cross_section(theta, self.force_constant(), self.cm_energy())
        return hard_sphere_cross_section(theta, self.value("sphere_radius"))

    def impact_parameter_of(self, theta: float) -> float:
        """b(θ): a cos(θ/2) or (k/2E) cot(θ/2)."""
        if self.target == "coulomb":
            return self.force_constant() / (2 * self.cm_energy()) / math.tan(theta / 2)
        return self.value("sphere_radius") * math.cos(theta / 2)


# --- the beam -----------------------------------------------------------------------------------
MODEL = Scattering
