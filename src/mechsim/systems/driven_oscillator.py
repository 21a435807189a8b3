"""Harmonically driven, damped oscillator: resonance, Q factor, power balance.

Source: PHYS0500 §1.3–1.5 (ch. 1, "Damped Oscillations", "Driven Oscillations",
"Resonance"), m ẍ + b ẋ + k x = F₀ cos ωt (eq. at line 183).

Typos of the document fixed here (see the catalog, 003 §1.4–1.5): ω₀² (not ω₀) multiplies x in
line 101; D = A/√((ω₀² − ω²)² + 4ω²β²) with a minus sign (line 213 has a plus); ⟨T⟩ has
+4ω²β² in its denominator (line 280). Damping enters through the Rayleigh function
D = ½ b ẋ² (dissipated power b ẋ²), the drive as the generalized force F₀ cos ωt.
Q follows the document: Q = ω_R / (2β) (line 258); it needs ω₀² > 2β².
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.params import nonnegative, number, positive
from mechsim.systems._oscillator import LinearOscillator, tone_response
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.lagrangian import LagrangianBuilder


class DrivenOscillator(LinearOscillator):
    id = "driven_oscillator"
    title = "Driven damped harmonic oscillator"
    source = ("PHYS0500 – Advanced Classical Mechanics, §1.3–1.5 (Damped and Driven Oscillations, "
              "Resonance Phenomena)")
    oracles = "full solution (transient + steady state), amplitude D and phase δ, ω_R, Q = ω_R/2β"
    parameters = (
        positive("mass", 1.0, "kg", "mass m"),
        positive("spring_constant", 4.0, "N/m", "spring constant k"),
        nonnegative("damping", 0.4, "kg/s", "linear damping coefficient b (force −b ẋ)"),
        nonnegative("drive_amplitude", 1.0, "N", "drive force amplitude F₀"),
        nonnegative("drive_frequency", 1.8, "rad/s", "drive angular frequency ω"),
        number("initial.x", 0.0, "m", "initial displacement"),
        number("initial_rate.x", 0.0, "m/s", "initial velocity"),
    )

    def declare(self, b: LagrangianBuilder) -> None:
        x, dx, m, k = self.spring(b)
        c, F0, w = b.param("damping"), b.param("drive_amplitude"), b.param("drive_frequency")
        b.rayleigh = c * dx**2 / 2
        drive = F0 * sp.cos(w * b.t)
        b.forces = [drive]
        b.observable("drive_force", "N", drive)
        b.observable("power_in", "W", drive * dx)
        b.observable("power_dissipated", "W", c * dx**2)

    # --- analytic oracles (PHYS0500 §1.4–1.5, corrected) ------------------------------------
    def steady_state(self) -> tuple[float, float]:
        """Amplitude D and phase lag δ ∈ [0, π] of the particular solution x_p = D cos(ωt − δ)
        (PHYS0500 eq. 1.2, with the minus sign its line 213 drops)."""
        return tone_response(self.value("drive_amplitude") / self.value("mass"),
                             self.value("drive_frequency"), self.natural_frequency(),
                             self.beta())

    def resonance_frequency(self) -> float:
        """Amplitude resonance ω_R = √(ω₀² − 2β²) (exists only for ω₀² > 2β²)."""
        w0, b = self.natural_frequency(), self.beta()
        if w0**2 <= 2 * b**2:
            raise ValueError("no amplitude resonance: ω₀² ≤ 2β²")
        return math.sqrt(w0**2 - 2 * b**2)

    def quality_factor(self) -> float:
        """Q = ω_R / (2β), the document's definition (line 258)."""
        return self.resonance_frequency() / (2 * self.beta())

    def exact_solution(self, t: np.ndarray) -> np.ndarray:
        """x(t) for an underdamped oscillator (ω₀ > β): steady state plus decaying transient."""
        w0, b, w = self.natural_frequency(), self.beta(), self.value("drive_frequency")
        if b >= w0:
            raise ValueError("exact_solution covers the underdamped case only")
        D, delta = self.steady_state()
        w1 = math.sqrt(w0**2 - b**2)
        C = self.value("initial.x") - D * math.cos(delta)
        E = (self.value("initial_rate.x") - D * w * math.sin(delta) + b * C) / w1
        return D * np.cos(w * t - delta) + np.exp(-b * t) * (C * np.cos(w1 * t)
                                                              + E * np.sin(w1 * t))

MODEL = DrivenOscillator
