"""Two bodies attracting each other in a uniform external field: the centre of mass falls as a
free particle while the relative motion is the Kepler problem.

Source: Introduction to analytical mechanics, "Central force problem – with two body" (L1392–1695:
Newton's equations
m₁r̈₁ = m₁g + F, m₂r̈₂ = m₂g − F, L1416–1485; the change to centre of mass and relative
coordinates, L1486–1535; the Lagrangian, L1536–1595) with §2.17 (Kepler problem, L1697–1896).
With R = (m₁r₁ + m₂r₂)/M and r = r₁ − r₂ (body 1 seen from body 2),
T = ½ M Ṙ² + ½ μ ṙ², μ = m₁m₂/M, and the field's potential −Σ mᵢ g·rᵢ = −M g·R depends on R
alone, so L = [½ M Ṙ² + M g·R] + [½ μ ṙ² − U(r)] separates: M R̈ = M g (a free fall: a parabola)
and μ r̈ = −∇U (the Kepler problem for U = −k/r). The document works in the plane of the orbit;
here the orbit and the fall are three-dimensional, so L = μ r × ṙ is a vector (the orbit lies
in the plane normal to it) and the Laplace–Runge–Lenz vector A = μ ṙ × L − μ k r̂ is conserved
too (catalog supplement; it is what makes the −k/r orbit close).

Formulations: ``cm`` integrates (R, r): coordinates ``cm_x``, ``cm_y``, ``cm_z``, ``x``, ``y``,
``z``; ``bodies`` integrates the positions r₁ = (x_1, y_1, z_1) and r₂ = (x_2, y_2, z_2) with
L = ½m₁ṙ₁² + ½m₂ṙ₂² − (m₁ + m₂) g z_cm − U(|r₁ − r₂|), the document's Newtonian starting
point. Both take their initial state from the (R, r) parameters (r₁ = R + (m₂/M) r,
r₂ = R − (m₁/M) r).

Conventions: REP-103 world axes, z up; the field is g = −g ẑ (``gravity`` g ≥ 0), the potential
zero at z = 0 and at r → ∞. Frames: ``cm`` (the falling centre of mass, axes parallel to the
world's), ``body_1`` and ``body_2`` (children of ``cm``: their CM-frame positions) and ``orbit``
(child of ``cm``: z along L, x toward periapsis along A).

Long runs: the diagnostics measure drifts against the initial energies, while the falling
centre of mass's T and V grow as t² (and Ż as t), so round-off alone brings the total energy's
relative drift to ~1e-7 after 120 s of fall and ~1e-5 (WARN) after 600 s, though it stays
~1e-11 of the energies present then; the relative energy, L and A stay at ~1e-11. The CM's own
invariant is its vertical momentum in the frame falling freely from rest, M(Ż + gt), linear in
the state (~1e-8 after 600 s) rather than ½MŻ² + MgZ.

Typos fixed (catalog 001 §2.16–2.18): V = −k/r (L1898 prints −k/2); the text's l is the
magnitude of L here.
"""

from __future__ import annotations

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import nonnegative, number, positive
from mechsim.systems._central import (
    declare_orbit_vectors,
    kepler_elements,
    orbit_quaternion,
    pericentre_time,
    vector_law_scales,
)
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

_CM = ("cm_x", "cm_y", "cm_z")
_REL = ("x", "y", "z")


class TwoBodyField(LagrangianModel):
    id = "two_body_field"
    title = "Two bodies in a uniform field (free-falling centre of mass, Kepler relative orbit)"
    source = ("Introduction to analytical mechanics, “Central force problem – with two body” (two "
              "bodies in a uniform external field) and “Classification of the orbits” (Kepler)")
    formulations = ("cm", "bodies")
    oracles = ("CM parabola R₀ + V₀t − ½gt²ẑ; relative orbit from Kepler's equation; relative "
               "energy, vector L and LRL vector A conserved, orbit in the plane ⟂ L; forms agree")
    parameters = (
        positive("mass_1", 1.0, "kg", "mass m₁ of body 1"),
        positive("mass_2", 0.5, "kg", "mass m₂ of body 2"),
        positive("force_constant", 1.0, "N m^2", "k of the attraction U = −k/r (k = Gm₁m₂ "
                 "for gravity)"),
        nonnegative("gravity", 9.81, "m/s^2", "strength g of the uniform field −g ẑ"),
        number("initial.cm_x", 0.0, "m", "initial centre of mass x"),
        number("initial.cm_y", 0.0, "m", "initial centre of mass y"),
        number("initial.cm_z", 0.0, "m", "initial centre of mass height z"),
        number("initial_rate.cm_x", 1.0, "m/s", "initial centre-of-mass velocity x"),
        number("initial_rate.cm_y", 0.0, "m/s", "initial centre-of-mass velocity y"),
        number("initial_rate.cm_z", 8.0, "m/s", "initial centre-of-mass velocity z"),
        number("initial.x", 1.0, "m", "initial relative position x of r = r₁ − r₂"),
        number("initial.y", 0.0, "m", "initial relative position y"),
        number("initial.z", 0.0, "m", "initial relative position z"),
        number("initial_rate.x", 0.0, "m/s", "initial relative velocity x"),
        number("initial_rate.y", 1.2, "m/s", "initial relative velocity y"),
        number("initial_rate.z", 0.4, "m/s", "initial relative velocity z"),
    )

    def check(self) -> None:
        r = np.array([self.value(f"initial.{c}") for c in _REL])
        v = np.array([self.value(f"initial_rate.{c}") for c in _REL])
        if not np.any(r):
            raise ParameterError("initial.x", "the bodies must start apart (r = r₁ − r₂ ≠ 0)")
        if not np.any(np.cross(r, v)):
            raise ParameterError("initial_rate.x", "relative velocity along r: a head-on fall "
                                 "reaches r = 0 (L = 0); give the orbit angular momentum")

    def declare(self, b: LagrangianBuilder) -> None:
        m1, m2 = b.param("mass_1"), b.param("mass_2")
        k, g = b.param("force_constant"), b.param("gravity")
        M = m1 + m2
        mu = m1 * m2 / M
        if self.formulation == "cm":
            R, dR = zip(*(b.coordinate(c, "m") for c in _CM), strict=True)
            r, dr = zip(*(b.coordinate(c, "m") for c in _REL), strict=True)
            b.kinetic = M * sum(c**2 for c in dR) / 2 + mu * sum(c**2 for c in dr) / 2
        else:
            r1, v1 = zip(*(b.coordinate(f"{c}_1", "m") for c in _REL), strict=True)
            r2, v2 = zip(*(b.coordinate(f"{c}_2", "m") for c in _REL), strict=True)
            b.kinetic = m1 * sum(c**2 for c in v1) / 2 + m2 * sum(c**2 for c in v2) / 2
            R = tuple((m1 * a + m2 * c) / M for a, c in zip(r1, r2, strict=True))
            dR = tuple((m1 * a + m2 * c) / M for a, c in zip(v1, v2, strict=True))
            r = tuple(a - c for a, c in zip(r1, r2, strict=True))
            dr = tuple(a - c for a, c in zip(v1, v2, strict=True))
        rn = sp.sqrt(sum(c**2 for c in r))
        if self.formulation == "cm":
            b.potential = M * g * R[2] - k / rn
        else:
            b.potential = g * (m1 * r1[2] + m2 * r2[2]) - k / rn
        b.invariant("momentum_x", "kg m/s", M * dR[0])
        b.invariant("momentum_y", "kg m/s", M * dR[1])
        # the CM's vertical momentum seen from a frame falling freely from rest at t = 0:
        # M(Ż + gt), conserved; better conditioned than ½MŻ² + MgZ, whose terms grow as t²
        b.invariant("momentum_z_falling_frame", "kg m/s", M * (dR[2] + g * b.t))
        b.invariant("relative_energy", "J", mu * sum(c**2 for c in dr) / 2 - k / rn)
        L, A = declare_orbit_vectors(b, mu, r, dr, k)
        b.observable("separation", "m", rn)
        b.observable("cm_height", "m", R[2])
        b.observable("cm_vertical_velocity", "m/s", dR[2])
        b.frame("cm", "world", R)
        b.frame("body_1", "cm", tuple(m2 / M * c for c in r))
        b.frame("body_2", "cm", tuple(-m1 / M * c for c in r))
        b.frame("orbit", "cm", (0, 0, 0), orbit_quaternion(L, A))

    def _state(self) -> tuple[np.ndarray, ...]:
        R = np.array([self.value(f"initial.{c}") for c in _CM])
        V = np.array([self.value(f"initial_rate.{c}") for c in _CM])
        r = np.array([self.value(f"initial.{c}") for c in _REL])
        v = np.array([self.value(f"initial_rate.{c}") for c in _REL])
        return R, V, r, v

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        R, V, r, v = self._state()
        if self.formulation == "cm":
            return np.concatenate([R, r]), np.concatenate([V, v])
        m1, m2 = self.value("mass_1"), self.value("mass_2")
        M = m1 + m2
        return (np.concatenate([R + m2 / M * r, R - m1 / M * r]),
                np.concatenate([V + m2 / M * v, V - m1 / M * v]))

    def visuals(self) -> tuple[Visual, ...]:
        m1, m2 = self.value("mass_1"), self.value("mass_2")
        s = 0.08 * float(np.linalg.norm(self._state()[2])) / max(m1, m2) ** (1 / 3)
        return (Visual("sphere", "body_1", radius=s * m1 ** (1 / 3), color=(255, 200, 80)),
                Visual("sphere", "body_2", radius=s * m2 ** (1 / 3), color=(120, 170, 255)),
                Visual("trail", "body_1", color=(255, 200, 80)),
                Visual("trail", "body_2", color=(120, 170, 255)),
                Visual("sphere", "cm", radius=0.2 * s, color=(255, 255, 255)),
                Visual("trail", "cm", color=(200, 200, 200)),
                Visual("axes", "orbit", radius=0.3 * float(np.linalg.norm(self._state()[2]))))

    def law_scales(self) -> dict[str, float]:
        """Components of L against |L|, of A against μk (a zero component would otherwise
        turn round-off into a large relative drift)."""
        _, _, r, v = self._state()
        mu = self.reduced_mass()
        return vector_law_scales(super().law_scales(), mu * float(np.linalg.norm(np.cross(r, v))),
                                 mu * self.value("force_constant"))

    def time_scale(self) -> float:
        """The pericentre passage of the relative orbit (GM = k/μ)."""
        _, _, r, v = self._state()
        return pericentre_time(self.value("force_constant") / self.reduced_mass(), r, v)

    # --- analytic oracles (Introduction to analytical mechanics, “Central force problem – with two
    # body”)
    def reduced_mass(self) -> float:
        """μ = m₁m₂/(m₁ + m₂)."""
        m1, m2 = self.value("mass_1"), self.value("mass_2")
        return m1 * m2 / (m1 + m2)

    def cm_position(self, t: np.ndarray) -> np.ndarray:
        """R(t) = R₀ + V₀t − ½ g t² ẑ: the free fall of the centre of mass (M R̈ = M g)."""
        R, V, _, _ = self._state()
        t = np.asarray(t, dtype=float)[:, None]
        return R + V * t - 0.5 * self.value("gravity") * t**2 * np.array([0.0, 0.0, 1.0])

    def kepler_elements(self) -> dict[str, float]:
        """Relative orbit elements from E = ½μṙ² − k/r and l = |μ r × ṙ| (see ``_central``)."""
        _, _, r, v = self._state()
        mu, k = self.reduced_mass(), self.value("force_constant")
        E = 0.5 * mu * float(v @ v) - k / float(np.linalg.norm(r))
        return kepler_elements(mu, k, E, mu * float(np.linalg.norm(np.cross(r, v))))


MODEL = TwoBodyField
