"""Particle in a uniform, time-dependent force field: V = x F(t).

Source: “Energy and Hamiltonians: Part 3 – Examples”, "Case 6 – E = h, neither conserved"
(L531–551):
L = ½ m ẋ² − x F(t), E = h = ½ m ẋ² + x F(t).

Conventions: motion along x of the ``origin`` frame. The document's potential V = x F(t) is
kept, so the force on the particle is −F(t) x̂ (published as ``applied_force``). The profile
F(t) is chosen by the string parameter ``force``:
- ``constant``: F = F₀;
- ``ramp``: F = F₀ + Ḟ t (``force_rate`` Ḟ);
- ``sinusoid``: F = F₀ sin Ωt (``force_frequency`` Ω).
E = h (L has no velocity-linear or velocity-free kinetic parts) and dE/dt = dh/dt = ∂V/∂t =
x Ḟ: the field's explicit time dependence is the external power (``power_in``), so
total − total₀ = work_external.

Document typo corrected (catalog 000 S9): the equation of motion of this L is m ẍ = −F(t);
L545 prints m ẍ = F(t). With it the document's own claim dE/dt = x Ḟ holds (checked in the
tests).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.params import Parameter, nonnegative, number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

PROFILES = ("sinusoid", "constant", "ramp")


class ForcedParticle(LagrangianModel):
    id = "forced_particle"
    title = "Particle under a time-dependent uniform force (V = x F(t))"
    source = ("“Energy and Hamiltonians: Part 3 – Examples” (blog post), Case 6 – E = h, neither "
              "conserved")
    oracles = ("exact x(t) = x₀ + v₀t − ∬F/m for constant, ramp and sinusoidal F(t); "
               "E = h; dE/dt = xḞ (sign corrected: m ẍ = −F)")
    parameters = (
        positive("mass", 1.0, "kg", "particle mass m"),
        Parameter("force", "sinusoid", "", "profile of F(t) in V = x F(t)", choices=PROFILES),
        number("force_amplitude", 1.0, "N", "F₀: the constant value, the ramp's F(0), or the "
               "sinusoid's amplitude"),
        number("force_rate", 0.5, "N/s", "Ḟ of the ramp F = F₀ + Ḟ t"),
        nonnegative("force_frequency", 2.0, "rad/s", "Ω of the sinusoid F = F₀ sin Ωt"),
        number("initial.x", 0.0, "m", "initial position x₀"),
        number("initial_rate.x", 0.5, "m/s", "initial velocity ẋ₀"),
    )

    @property
    def profile(self) -> str:
        return str(self.values["force"])

    def force_expression(self, b: LagrangianBuilder) -> sp.Expr:
        F0, t = b.param("force_amplitude"), b.t
        if self.profile == "constant":
            return F0
        if self.profile == "ramp":
            return F0 + b.param("force_rate") * t
        return F0 * sp.sin(b.param("force_frequency") * t)

    def declare(self, b: LagrangianBuilder) -> None:
        x, dx = b.coordinate("x", "m")
        m = b.param("mass")
        F = self.force_expression(b)
        b.kinetic = m * dx**2 / 2
        b.potential = x * F
        b.observable("force_field", "N", F)
        b.observable("applied_force", "N", -F)
        b.observable("power_in", "W", x * sp.diff(F, b.t))
        b.frame("origin", "world", (0, 0, 0))
        b.frame("particle", "origin", (x, 0, 0))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array([self.value("initial.x")]), np.array([self.value("initial_rate.x")])

    def visuals(self) -> tuple[Visual, ...]:
        return (Visual("axes", "origin", radius=0.3),
                Visual("sphere", "particle", radius=0.08),
                Visual("trail", "particle", color=(120, 170, 255)))

    def time_scale(self) -> float:
        w = self.value("force_frequency")
        return 2 * math.pi / w if self.profile == "sinusoid" and w > 0 else 1.0

    # --- analytic oracles (“Energy and Hamiltonians: Part 3 – Examples”, Case 6, sign corrected)
    def force_at(self, t: np.ndarray) -> np.ndarray:
        """F(t)."""
        t = np.asarray(t, dtype=float)
        F0 = self.value("force_amplitude")
        if self.profile == "constant":
            return F0 + 0 * t
        if self.profile == "ramp":
            return F0 + self.value("force_rate") * t
        return F0 * np.sin(self.value("force_frequency") * t)

    def exact_solution(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x(t), ẋ(t) of m ẍ = −F(t)."""
        t = np.asarray(t, dtype=float)
        m, F0 = self.value("mass"), self.value("force_amplitude")
        x0, v0 = self.value("initial.x"), self.value("initial_rate.x")
        if self.profile in ("constant", "ramp"):
            rate = self.value("force_rate") if self.profile == "ramp" else 0.0
            v = v0 - (F0 * t + rate * t**2 / 2) / m
            x = x0 + v0 * t - (F0 * t**2 / 2 + rate * t**3 / 6) / m
            return x, v
        w = self.value("force_frequency")
        if w == 0.0:
            return x0 + v0 * t, v0 + 0 * t
        v = v0 - F0 / (m * w) * (1 - np.cos(w * t))
        x = x0 + v0 * t - F0 / (m * w) * (t - np.sin(w * t) / w)
        return x, v


MODEL = ForcedParticle
