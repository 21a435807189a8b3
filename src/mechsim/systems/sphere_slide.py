"""Particle sliding off a fixed smooth sphere: a one-sided constraint that lets go.

Source: Introduction to analytical mechanics, “Classification of constraints” (L159–167), the
"particle rolling from the top of a sphere", the document's example of a constraint "expressed as an
inequality". The document gives only the figure; the departure angle cos θ = 2/3 is the catalog's
derived oracle.

Model: a point mass on the outside of a fixed frictionless sphere of radius R, released near the
top. The contact is one-sided, r ≥ R: the wall can push (normal force N ≥ 0) but not pull.
While in contact the constraint r − R = 0 holds with a multiplier λ, and λ is the normal force
(outward positive). The particle leaves exactly when λ falls through zero; that is a state
event, after which the constraint is released (discrete mode ``phase``: 0 on the sphere,
1 in free flight) and the motion is a projectile parabola. Nothing re-attaches it: after
leaving, the particle's path stays outside the sphere.

Conventions: motion in the x–z plane of the ``sphere`` frame (origin at the sphere's centre,
which sits at height R above the world origin, so the sphere rests on the ground z = 0); θ is
the angle from the upward vertical, positive towards +x, so the particle is at
(r sin θ, 0, r cos θ). V = m g (R + z_rel), zero on the ground. Formulations: ``polar`` (r, θ)
and ``cartesian`` (x, z relative to the centre); in both λ multiplies ∂g/∂q with
g = |r| − R, so λ is the outward normal force.

Oracles (energy conservation plus N = 0): N(θ) = m g (3 cos θ − 2 cos θ₀) − m R θ̇₀², departure at
cos θ* = (2 cos θ₀ + R θ̇₀²/g)/3, i.e. 2/3 from rest at the top (θ₀ → 0).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, nonnegative, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class SphereSlide(LagrangianModel):
    id = "sphere_slide"
    title = "Particle sliding off a smooth sphere (one-sided constraint, departure event)"
    source = ("Introduction to analytical mechanics, “Classification of constraints” (inequality "
              "constraint: particle rolling from the top of a sphere)")
    formulations = ("polar", "cartesian")
    oracles = ("normal force mg(3cosθ − 2cosθ₀) − mRθ̇₀², departure at cosθ = (2cosθ₀ + Rθ̇₀²/g)/3 "
               "(2/3 from rest) and its time by quadrature, projectile flight after")
    parameters = (
        positive("mass", 1.0, "kg", "particle mass m"),
        positive("radius", 1.0, "m", "sphere radius R"),
        positive("gravity", 9.81, "m/s^2", "gravitational acceleration g"),
        Parameter("initial.angle", 0.01, "rad", "initial angle θ₀ from the top (a tiny push "
                  "off the unstable top)", minimum=0.0, maximum=math.pi / 2,
                  exclusive_maximum=True),
        nonnegative("initial_rate.angle", 0.0, "rad/s", "initial angular rate θ̇₀"),
    )

    def check(self) -> None:
        R, g = self.value("radius"), self.value("gravity")
        th0, w0 = self.value("initial.angle"), self.value("initial_rate.angle")
        if R * w0**2 >= g * math.cos(th0):
            raise ParameterError("initial_rate.angle", f"too fast: R θ̇₀² must be < g cos θ₀ = "
                                 f"{g * math.cos(th0) / R:.6g} R⁻¹ (else the particle never "
                                 "touches the sphere)")

    def declare(self, b: LagrangianBuilder) -> None:
        m, R, g = b.param("mass"), b.param("radius"), b.param("gravity")
        phase = b.mode("phase")
        on = 1 - phase
        if self.formulation == "polar":
            r, dr = b.coordinate("radius", "m")
            th, dth = b.coordinate("angle", "rad")
            b.kinetic = m * (dr**2 + r**2 * dth**2) / 2
            x, z = r * sp.sin(th), r * sp.cos(th)
            b.constraint("surface", r - R, active=on)
            angle = th
        else:
            x, dx = b.coordinate("x", "m")
            z, dz = b.coordinate("z", "m")
            b.kinetic = m * (dx**2 + dz**2) / 2
            r = sp.sqrt(x**2 + z**2)
            b.constraint("surface", r - R, active=on)
            angle = sp.atan2(x, z)
            b.observable("angle", "rad", angle)
        b.potential = m * g * (R + z)
        lam = b.multiplier(0)
        b.observable("normal_force", "N", lam)
        b.observable("height", "m", R + z)
        b.observable("distance_from_centre", "m", r)
        b.event("departure", phase + on * lam, direction=-1,
                description="the normal force falls through zero: the particle leaves")
        b.frame("sphere", "world", (0, 0, R))
        b.frame("particle", "sphere", (x, 0, z),
                (0, sp.sin(angle / 2), 0, sp.cos(angle / 2)))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        R = self.value("radius")
        th, w = self.value("initial.angle"), self.value("initial_rate.angle")
        if self.formulation == "polar":
            return np.array([R, th]), np.array([0.0, w])
        return (np.array([R * math.sin(th), R * math.cos(th)]),
                np.array([R * math.cos(th) * w, -R * math.sin(th) * w]))

    def on_departure(self, t: float, y: np.ndarray) -> np.ndarray:
        y[-1] = 1.0  # phase: free flight; position and velocity are continuous
        return y

    def time_scale(self) -> float:
        return math.sqrt(self.value("radius") / self.value("gravity"))

    def visuals(self) -> tuple[Visual, ...]:
        R = self.value("radius")
        circle = tuple((R * math.sin(a), 0.0, R * math.cos(a))
                       for a in np.linspace(0, 2 * math.pi, 97))
        return (Visual("sphere", "sphere", radius=R, color=(150, 150, 160)),
                Visual("polyline", "sphere", points=circle, radius=0.01, color=(90, 90, 100)),
                Visual("sphere", "particle", radius=0.04 * R, color=(230, 120, 60)),
                Visual("trail", "particle", color=(120, 170, 255)))

    # --- analytic oracles (energy conservation and N = 0; verified in the tests) -------------
    def departure_cosine(self) -> float:
        """cos θ* = (2 cos θ₀ + R θ̇₀² / g) / 3: where N = m g cos θ − m R θ̇² reaches 0."""
        R, g = self.value("radius"), self.value("gravity")
        return (2 * math.cos(self.value("initial.angle"))
                + R * self.value("initial_rate.angle") ** 2 / g) / 3

    def normal_force_at(self, theta: np.ndarray) -> np.ndarray:
        """N(θ) = m g (3 cos θ − 2 cos θ₀) − m R θ̇₀² on the sphere."""
        m, R, g = self.value("mass"), self.value("radius"), self.value("gravity")
        return m * g * (3 * np.cos(theta) - 2 * math.cos(self.value("initial.angle"))) \
            - m * R * self.value("initial_rate.angle") ** 2


MODEL = SphereSlide
