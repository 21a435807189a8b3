"""One-dimensional simple harmonic oscillator.

Sources: PHYS0500 §1.1 "Simple Harmonic Oscillations, Energy" (lines 19–65) and Introduction to
analytical mechanics, “Conservation of energy” (L1007–1009, L1369–1373, L2136–2146): m ẍ = −k x,
ω₀² = k/m, T = ½ k A² cos²(ω₀t − δ),
U = ½ k A² sin²(ω₀t − δ), E = ½ k A²; Introduction to analytical mechanics shows h = ẋ
∂L/∂ẋ − L = T + V = E.

Conventions: the mass moves along x of its ``anchor`` frame (REP-103 world axes); x = 0 is the
unstretched spring and the potential zero. Amplitude and phase follow the document's sine form
x = A sin(ω₀t − δ) (lines 49–60), so x₀ = −A sin δ and ẋ₀ = ω₀ A cos δ.

Typos of the documents fixed here (catalog 003 §1.1): the second line of eq. 41 reads
sin δ cos ωt for sin δ sin ωt; line 51 has a stray "F" and A for A²; line 60 prints
sin²(ω₀^tδ) for sin²(ω₀t − δ); line 64 has w₀ for ω₀; ω₀ is used before its definition (line 99).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.params import number, positive
from mechsim.systems._oscillator import LinearOscillator, free_solution
from mechsim.systems.lagrangian import LagrangianBuilder


class HarmonicOscillator(LinearOscillator):
    id = "harmonic_oscillator"
    title = "Simple harmonic oscillator"
    source = ("PHYS0500 – Advanced Classical Mechanics, §1.1 (Simple Harmonic Oscillations, "
              "Energy); Introduction to analytical mechanics, “Conservation of energy” (harmonic "
              "oscillator)")
    oracles = ("exact x(t) = x₀cos ω₀t + (v₀/ω₀)sin ω₀t, period 2π√(m/k), E = ½kA² = h, "
               "period averages ⟨T⟩ = ⟨V⟩ = E/2")
    parameters = (
        positive("mass", 1.0, "kg", "mass m"),
        positive("spring_constant", 4.0, "N/m", "spring constant k"),
        number("initial.x", 0.5, "m", "initial displacement x₀ from the spring's rest length"),
        number("initial_rate.x", 0.0, "m/s", "initial velocity ẋ₀"),
    )

    def declare(self, b: LagrangianBuilder) -> None:
        x, _, _, k = self.spring(b)
        b.observable("spring_force", "N", -k * x)

    # --- analytic oracles (PHYS0500 §1.1, Introduction to analytical mechanics, “Conservation of
    # energy”)
    def period(self) -> float:
        """2π/ω₀ = 2π√(m/k)."""
        return 2 * math.pi / self.natural_frequency()

    def amplitude(self) -> float:
        """A = √(x₀² + (v₀/ω₀)²)."""
        return math.hypot(self.value("initial.x"),
                          self.value("initial_rate.x") / self.natural_frequency())

    def phase(self) -> float:
        """δ of the document's sine form x = A sin(ω₀t − δ)."""
        return math.atan2(-self.value("initial.x"),
                          self.value("initial_rate.x") / self.natural_frequency())

    def energy(self) -> float:
        """E = ½ k A² (= ½ m v₀² + ½ k x₀²)."""
        return 0.5 * self.value("spring_constant") * self.amplitude() ** 2

    def exact_solution(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x(t), ẋ(t)."""
        return free_solution(t, self.value("initial.x"), self.value("initial_rate.x"),
                             self.natural_frequency())


MODEL = HarmonicOscillator
