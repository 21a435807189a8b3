"""Rigid dumbbell (diatomic molecule): two point masses joined by a massless rigid rod, free or
in a uniform gravitational field.

Source: Introduction to analytical mechanics, "Constraints" (L96–104: "Consider a diatomic molecule
or a dumbbell ...
d_ij = Constant. Six degrees of freedom of two particles reduces to five due to a constraint
r − d_ij = 0"; holonomic, L123–131) with the two-body reduction of §2.16 (L1486–1535):
R = (m₁r₁ + m₂r₂)/M and r₁ − r₂ = d n̂ give T = ½ M Ṙ² + ½ μ d² |dn̂/dt|², μ = m₁m₂/M, and
the uniform field's potential M g Z depends on R alone. So the centre of mass flies a parabola,
the rod turns as a free rotor (no torque about the CM: L_CM = μ d² n̂ × dn̂/dt is conserved, n̂
turns uniformly at ω = |dn̂/dt| about L̂), and the rod tension is the centripetal force of the
relative motion, T = μ d ω² (gravity pulls both ends alike and adds nothing).

Formulations (catalog 001 §1.1, §5 item 2):
- ``reduced``: the five coordinates left by the constraint, the CM (``cm_x``, ``cm_y``,
  ``cm_z``) and the rod direction n̂ = (sinθ cosφ, sinθ sinφ, cosθ) (``theta`` from +z, ``phi``
  from +x); the observable ``tension`` is μ d (θ̇² + sin²θ φ̇²). Like any two-angle chart of a
  direction it is singular where n̂ ∥ z: it refuses motions that bring the rod within 5° of
  the vertical (use ``multiplier`` there).
- ``multiplier``: the six Cartesian coordinates of the two masses with the constraint
  g = |r₁ − r₂| − d = 0 and its multiplier λ (force λ n̂ on mass 1, −λ n̂ on mass 2), so the
  ``tension`` (pulling the masses together when positive) is −λ.

Long runs in gravity: the CM's T and V grow as t² while drifts are measured against the initial
energies, so round-off alone brings the total energy's relative drift to ~4e-6 (WARN) after
600 s of fall; the rotation's invariants stay at round-off, and the CM's vertical momentum in
the frame falling freely from rest, M(Ż + gt) (its invariant, linear in the state), at ~1e-9.

Conventions: REP-103, z up, gravity −g ẑ (``gravity`` = 0 for a free dumbbell); n̂ points from
mass 2 to mass 1; mass 1 sits at R + (m₂/M) d n̂, mass 2 at R − (m₁/M) d n̂. Frames: ``cm``
(the CM, axes parallel to the world's), ``rod`` (at the CM, z along n̂, x = θ̂, y = φ̂),
``mass_1``, ``mass_2`` (children of ``cm``).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, nonnegative, number, positive
from mechsim.systems._central import vector_law_scales
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

POLE_MARGIN = math.radians(5.0)
_CM = ("cm_x", "cm_y", "cm_z")


class Dumbbell(LagrangianModel):
    id = "dumbbell"
    title = "Rigid dumbbell / diatomic molecule (free or in gravity)"
    source = ("Introduction to analytical mechanics, “Constraints” (diatomic molecule or dumbbell, "
              "rigid rod r − d = 0) and “Central force problem – with two body” (centre of mass "
              "and relative coordinates)")
    formulations = ("reduced", "multiplier")
    oracles = ("CM parabola; rod turns uniformly about the fixed L̂ (L_CM conserved); tension "
               "μdω² (= −λ), also in gravity; rotational energy ½μd²ω²; 6 − 1 = 5 DOF; forms "
               "agree")
    parameters = (
        positive("mass_1", 1.0, "kg", "mass m₁ at the end n̂ points to"),
        positive("mass_2", 2.0, "kg", "mass m₂ at the other end"),
        positive("rod_length", 1.0, "m", "distance d between the masses"),
        nonnegative("gravity", 9.81, "m/s^2", "strength g of the field −g ẑ (0: free)"),
        number("initial.cm_x", 0.0, "m", "initial centre of mass x"),
        number("initial.cm_y", 0.0, "m", "initial centre of mass y"),
        number("initial.cm_z", 0.0, "m", "initial centre of mass height z"),
        number("initial_rate.cm_x", 1.0, "m/s", "initial centre-of-mass velocity x"),
        number("initial_rate.cm_y", 0.0, "m/s", "initial centre-of-mass velocity y"),
        number("initial_rate.cm_z", 6.0, "m/s", "initial centre-of-mass velocity z"),
        Parameter("initial.theta", math.pi / 2, "rad", "initial polar angle θ of n̂ from +z",
                  minimum=0.0, maximum=math.pi, exclusive_minimum=True,
                  exclusive_maximum=True),
        number("initial.phi", 0.0, "rad", "initial azimuth φ of n̂ from +x"),
        number("initial_rate.theta", 1.5, "rad/s", "initial θ̇"),
        number("initial_rate.phi", 3.0, "rad/s", "initial φ̇"),
    )

    def check(self) -> None:
        if self.formulation == "reduced" and self.pole_distance() < POLE_MARGIN:
            raise ParameterError(
                "formulation", f"the rod comes within {math.degrees(self.pole_distance()):.3g}° "
                f"of the vertical, where the angles θ, φ are singular (limit "
                f"{math.degrees(POLE_MARGIN):g}°): use formulation: multiplier")

    def declare(self, b: LagrangianBuilder) -> None:
        m1, m2, d, g = (b.param("mass_1"), b.param("mass_2"), b.param("rod_length"),
                        b.param("gravity"))
        M = m1 + m2
        mu = m1 * m2 / M
        if self.formulation == "reduced":
            R, dR = zip(*(b.coordinate(c, "m") for c in _CM), strict=True)
            th, dth = b.coordinate("theta", "rad")
            ph, dph = b.coordinate("phi", "rad")
            n = (sp.sin(th) * sp.cos(ph), sp.sin(th) * sp.sin(ph), sp.cos(th))
            rel = tuple(d * c for c in n)
            drel = tuple(d * (sp.diff(c, th) * dth + sp.diff(c, ph) * dph) for c in n)
            omega2 = dth**2 + sp.sin(th) ** 2 * dph**2
            b.kinetic = M * sum(c**2 for c in dR) / 2 + mu * d**2 * omega2 / 2
            b.potential = M * g * R[2]
            b.observable("tension", "N", mu * d * omega2)
        else:
            r1, v1 = zip(*(b.coordinate(f"{c}_1", "m") for c in "xyz"), strict=True)
            r2, v2 = zip(*(b.coordinate(f"{c}_2", "m") for c in "xyz"), strict=True)
            b.kinetic = m1 * sum(c**2 for c in v1) / 2 + m2 * sum(c**2 for c in v2) / 2
            b.potential = g * (m1 * r1[2] + m2 * r2[2])
            rel = tuple(a - c for a, c in zip(r1, r2, strict=True))
            drel = tuple(a - c for a, c in zip(v1, v2, strict=True))
            sep = sp.sqrt(sum(c**2 for c in rel))
            b.constraint("rod_length", sep - d)
            lam = b.multiplier(0)
            b.observable("tension", "N", -lam)
            b.observable("multiplier", "N", lam)
            R = tuple((m1 * a + m2 * c) / M for a, c in zip(r1, r2, strict=True))
            dR = tuple((m1 * a + m2 * c) / M for a, c in zip(v1, v2, strict=True))
            n = tuple(c / sep for c in rel)
            th, ph = sp.acos(n[2]), sp.atan2(n[1], n[0])
        # about the CM: L = μ r × ṙ and the relative kinetic energy ½ μ ṙ², r = r₁ − r₂
        L = (mu * (rel[1] * drel[2] - rel[2] * drel[1]),
             mu * (rel[2] * drel[0] - rel[0] * drel[2]),
             mu * (rel[0] * drel[1] - rel[1] * drel[0]))
        rel2 = sum(c**2 for c in rel)
        b.invariant("momentum_x", "kg m/s", M * dR[0])
        b.invariant("momentum_y", "kg m/s", M * dR[1])
        # the CM's vertical momentum seen from a frame falling freely from rest at t = 0:
        # M(Ż + gt), conserved; better conditioned than ½MŻ² + MgZ, whose terms grow as t²
        b.invariant("momentum_z_falling_frame", "kg m/s", M * (dR[2] + g * b.t))
        for axis, c in zip("xyz", L, strict=True):
            b.invariant(f"angular_momentum_{axis}", "kg m^2/s", c)
        b.invariant("rotational_energy", "J", mu * sum(c**2 for c in drel) / 2)
        b.observable("angular_speed", "rad/s",
                     sp.sqrt(L[0] ** 2 + L[1] ** 2 + L[2] ** 2) / (mu * rel2))
        b.observable("cm_height", "m", R[2])
        sth, cth, sph, cph = sp.sin(th / 2), sp.cos(th / 2), sp.sin(ph / 2), sp.cos(ph / 2)
        b.frame("cm", "world", R)
        b.frame("rod", "cm", (0, 0, 0), (-sph * sth, cph * sth, sph * cth, cph * cth))
        b.frame("mass_1", "cm", tuple(m2 / M * c for c in rel))
        b.frame("mass_2", "cm", tuple(-m1 / M * c for c in rel))

    # --- state ----------------------------------------------------------------------------
    def rod_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Initial n̂ and dn̂/dt."""
        th, ph = self.value("initial.theta"), self.value("initial.phi")
        dth, dph = self.value("initial_rate.theta"), self.value("initial_rate.phi")
        st, ct, sp_, cp = math.sin(th), math.cos(th), math.sin(ph), math.cos(ph)
        n = np.array([st * cp, st * sp_, ct])
        return n, dth * np.array([ct * cp, ct * sp_, -st]) + st * dph * np.array([-sp_, cp, 0.0])

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        R = np.array([self.value(f"initial.{c}") for c in _CM])
        V = np.array([self.value(f"initial_rate.{c}") for c in _CM])
        if self.formulation == "reduced":
            return (np.concatenate([R, [self.value("initial.theta"), self.value("initial.phi")]]),
                    np.concatenate([V, [self.value("initial_rate.theta"),
                                        self.value("initial_rate.phi")]]))
        m1, m2, d = self.value("mass_1"), self.value("mass_2"), self.value("rod_length")
        M = m1 + m2
        n, dn = self.rod_state()
        return (np.concatenate([R + m2 / M * d * n, R - m1 / M * d * n]),
                np.concatenate([V + m2 / M * d * dn, V - m1 / M * d * dn]))

    def visuals(self) -> tuple[Visual, ...]:
        d = self.value("rod_length")
        m1, m2 = self.value("mass_1"), self.value("mass_2")
        s = 0.12 * d / max(m1, m2) ** (1 / 3)
        return (Visual("sphere", "mass_1", radius=s * m1 ** (1 / 3), color=(255, 120, 90)),
                Visual("sphere", "mass_2", radius=s * m2 ** (1 / 3), color=(120, 170, 255)),
                Visual("link", "mass_1", to_frame="mass_2", radius=0.015 * d,
                       color=(200, 200, 200)),
                Visual("trail", "cm", color=(200, 200, 200)),
                Visual("trail", "mass_1", color=(255, 120, 90)),
                Visual("axes", "rod", radius=0.3 * d))

    def law_scales(self) -> dict[str, float]:
        """L components against |L| (a zero component would turn round-off into drift)."""
        return vector_law_scales(super().law_scales(),
                                 float(np.linalg.norm(self.angular_momentum())))

    def time_scale(self) -> float:
        """A turn of the rod, else √(d/g); 1 s where neither is a positive finite time."""
        w, g = self.angular_speed(), self.value("gravity")
        ts = 2 * math.pi / w if w > 0 else math.sqrt(self.value("rod_length") / g) if g > 0 \
            else 1.0
        return ts if math.isfinite(ts) and ts > 0 else 1.0

    # --- analytic oracles ------------------------------------------------------------------
    def reduced_mass(self) -> float:
        m1, m2 = self.value("mass_1"), self.value("mass_2")
        return m1 * m2 / (m1 + m2)

    def angular_momentum(self) -> np.ndarray:
        """L about the CM, μ d² n̂ × dn̂/dt (constant: no torque about the CM)."""
        n, dn = self.rod_state()
        return self.reduced_mass() * self.value("rod_length") ** 2 * np.cross(n, dn)

    def angular_speed(self) -> float:
        """ω = |dn̂/dt| (constant)."""
        return float(np.linalg.norm(self.rod_state()[1]))

    def tension(self) -> float:
        """T = μ d ω² (constant; the same with or without gravity)."""
        return self.reduced_mass() * self.value("rod_length") * self.angular_speed() ** 2

    def pole_distance(self) -> float:
        """Smallest angle between the rod and the vertical during the motion: n̂ turns in the
        plane ⟂ L, so it is 90° − (angle of L from z) folded into [0, 90°]."""
        L = np.cross(*self.rod_state())  # the direction of L is all that matters
        if not np.any(L):  # not turning: the rod keeps its direction
            th = self.value("initial.theta")
            return min(th, math.pi - th)
        return abs(math.pi / 2 - math.atan2(math.hypot(L[0], L[1]), L[2]))


MODEL = Dumbbell
