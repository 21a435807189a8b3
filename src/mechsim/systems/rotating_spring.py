"""Mass on a spring driven round at a constant rate by a motor (constrained planar SHO).

Source: “Energy and Hamiltonians: Part 3 – Examples”, "Case 4 – E ≠ h, h conserved" (L472–509): the
rheonomic constraint θ̇ = ω, L = ½ m (ṙ² + r²ω²) − ½ k (r − ℓ₀)², E = ½ m (ṙ² + r²ω²) + ½ k
(r − ℓ₀)²,
h_r = ½ m (ṙ² − r²ω²) + ½ k (r − ℓ₀)².

Formulations:
- ``reduced``: r only, θ = θ₀ + ωt. L has no explicit t, so h_r is conserved (law
  ``energy_function``) while E is not: E − h_r = m r²ω², and the motor's work
  ∫ τ ω dt = m ω² (r² − r₀²) closes total − total₀ = work_external, with the motor torque
  τ = d(m r² θ̇)/dt = 2 m r ṙ ω.
- ``multiplier``: r and θ with the constraint θ − θ₀ − ωt = 0; its multiplier λ is the motor
  torque. Here L(r, θ, ṙ, θ̇) is the free planar one, so the engine's energy function equals E;
  h_r is published as the invariant ``reduced_energy_function``.

Conventions: the plane of motion is the world x–y plane, θ counter-clockwise about +z; the
co-rotating frame ``rotating_frame`` (child of ``world``, yaw θ) carries the mass at (r, 0, 0).

Document typos corrected (catalog 000 S7, pitfall 13): L484 writes the potential ½ m k (r − ℓ₀)²
and L499 the equation r̈ = (ω² − ω₀²) r + k ℓ₀ with ω₀² = k/m; the two agree only for m = 1. The
potential used here is ½ k (r − ℓ₀)², giving r̈ = (ω² − ω₀²) r + ω₀² ℓ₀ and the equilibrium
r_eq = ω₀² ℓ₀ / (ω₀² − ω²) (L507 prints k ℓ₀ / (ω₀² − ω²)). The radial motion oscillates about
r_eq only for ω < ω₀; for ω > ω₀ it runs away exponentially (allowed, but not the default).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.params import Parameter, number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Law, Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class RotatingSpring(LagrangianModel):
    id = "rotating_spring"
    title = "Motor-driven rotating spring (constrained planar SHO)"
    source = ("“Energy and Hamiltonians: Part 3 – Examples” (blog post), Case 4 – E ≠ h, h "
              "conserved")
    formulations = ("reduced", "multiplier")
    oracles = ("exact r(t) about r_eq = ω₀²ℓ₀/(ω₀² − ω²) with Ω = √(ω₀² − ω²); h_r conserved, "
               "E − h_r = mr²ω², motor work mω²(r² − r₀²), λ = motor torque 2mrṙω")
    parameters = (
        positive("mass", 1.0, "kg", "mass m"),
        positive("spring_constant", 4.0, "N/m", "spring constant k"),
        positive("rest_length", 1.0, "m", "spring rest length ℓ₀"),
        number("angular_velocity", 1.0, "rad/s", "motor rate ω = θ̇ (counter-clockwise > 0)"),
        Parameter("initial.r", 1.0, "m", "initial radius r₀", minimum=0.0,
                  exclusive_minimum=True),
        number("initial_rate.r", 0.0, "m/s", "initial radial velocity ṙ₀"),
        number("initial.theta", 0.0, "rad", "initial angle θ₀ of the arm"),
    )

    def declare(self, b: LagrangianBuilder) -> None:
        m, k = b.param("mass"), b.param("spring_constant")
        l0, w = b.param("rest_length"), b.param("angular_velocity")
        th0 = b.param("initial.theta")
        r, dr = b.coordinate("r", "m")
        if self.formulation == "reduced":
            theta, dth = th0 + w * b.t, w
            b.kinetic = m * (dr**2 + r**2 * w**2) / 2
            torque = 2 * m * r * dr * w
            b.observable("angle", "rad", theta)
        else:
            theta, dth = b.coordinate("theta", "rad")
            b.kinetic = m * (dr**2 + r**2 * dth**2) / 2
            b.constraint("motor", theta - th0 - w * b.t)
            torque = b.multiplier(0)
            b.invariant("reduced_energy_function", "J",
                        m * (dr**2 - r**2 * w**2) / 2 + k * (r - l0) ** 2 / 2)
        b.potential = k * (r - l0) ** 2 / 2
        b.observable("motor_torque", "N m", torque)
        b.observable("motor_power", "W", torque * w)
        b.observable("angular_momentum", "kg m^2/s", m * r**2 * dth)
        b.observable("spring_force", "N", -k * (r - l0))
        b.frame("rotating_frame", "world", (0, 0, 0), (0, 0, sp.sin(theta / 2),
                                                       sp.cos(theta / 2)))
        b.frame("mass", "rotating_frame", (r, 0, 0))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        r0, v0 = self.value("initial.r"), self.value("initial_rate.r")
        if self.formulation == "reduced":
            return np.array([r0]), np.array([v0])
        return (np.array([r0, self.value("initial.theta")]),
                np.array([v0, self.value("angular_velocity")]))

    def laws(self) -> tuple[Law, ...]:
        # The reduced L has no explicit t, so the structural default would claim E conserved;
        # the motor does work: only h_r (and the balance) hold.
        return tuple(law for law in super().laws() if law.kind != "energy")

    def visuals(self) -> tuple[Visual, ...]:
        return (Visual("axes", "rotating_frame", radius=0.3),
                Visual("link", "rotating_frame", to_frame="mass", radius=0.01,
                       color=(200, 200, 90)),
                Visual("sphere", "mass", radius=0.08),
                Visual("trail", "mass", color=(120, 170, 255)))

    def time_scale(self) -> float:
        return 2 * math.pi / max(self.natural_frequency(), abs(self.value("angular_velocity")))

    # --- analytic oracles (“Energy and Hamiltonians: Part 3 – Examples”, Case 4, units made
    # consistent)
    def natural_frequency(self) -> float:
        """ω₀ = √(k/m)."""
        return math.sqrt(self.value("spring_constant") / self.value("mass"))

    def equilibrium_radius(self) -> float:
        """r_eq = ω₀² ℓ₀ / (ω₀² − ω²) (unstable for ω > ω₀; none for ω = ω₀)."""
        w0sq, w = self.natural_frequency() ** 2, self.value("angular_velocity")
        return w0sq * self.value("rest_length") / (w0sq - w * w)

    def exact_radius(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """r(t), ṙ(t) of r̈ = (ω² − ω₀²) r + ω₀² ℓ₀."""
        t = np.asarray(t, dtype=float)
        w0sq, w = self.natural_frequency() ** 2, self.value("angular_velocity")
        r0, v0 = self.value("initial.r"), self.value("initial_rate.r")
        s = w0sq - w * w
        if s == 0.0:
            acc = w0sq * self.value("rest_length")
            return r0 + v0 * t + acc * t**2 / 2, v0 + acc * t
        d = r0 - self.equilibrium_radius()
        W = math.sqrt(abs(s))
        if s > 0:
            c, sn = np.cos(W * t), np.sin(W * t)
            return (self.equilibrium_radius() + d * c + v0 / W * sn, -d * W * sn + v0 * c)
        ch, sh = np.cosh(W * t), np.sinh(W * t)
        return self.equilibrium_radius() + d * ch + v0 / W * sh, d * W * sh + v0 * ch


MODEL = RotatingSpring
