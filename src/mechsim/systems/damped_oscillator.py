"""Damped free harmonic oscillator: under-, critically and over-damped motion.

Sources: PHYS0500 §1.3 "Damped Oscillations" (lines 87–173; §1.3.1–1.3.3) and “Energy and
Hamiltonians: Part 3 – Examples”, Case 5 (E&H Part 3 "Case 5 – E ≠ h, neither conserved", L511–529;
"Action and Reaction, Case 1 – Dissipative forces", L786–802): m ẍ + b ẋ + k x = 0, β = b/2m,
ω₀² = k/m.

Formulation: damping enters as the Rayleigh dissipation function D = ½ b ẋ² (dissipated power
b ẋ² = 2D), so total = E = ½ m ẋ² + ½ k x² and dE/dt = −b ẋ² is closed by work_dissipated.
The document's other route, the Caldirola–Kanai Lagrangian L = e^{bt/m}[½ m ẋ² − ½ k x²]
(000 L515, its γ is our ``damping`` b), gives the same equation of motion (e^{bt/m} times it;
checked with sympy in the tests) but an L whose T and V are not the physical energies, so it is
not integrated separately; its energy function h = e^{bt/m} E (L527) is published as the
observable ``caldirola_kanai_energy_function``, with dh/dt = −∂L/∂t = −(b/m) L.

Conventions: x along the ``anchor`` frame's x axis, x = 0 the rest length and potential zero.

Document typos corrected (catalog 003 §1.3, 000 S8): ẍ + 2βẋ + ω₀² x (003 line 101 has ω₀ x);
roots r = −β ± √(β² − ω₀²) (line 105 has −b); e^{−βt} (line 110 drops t); e^{−iω₁t}
(line 131 has ω₂); ω₂ = √(β² − ω₀²) (line 173 drops the root); E = ½ m ẋ² + ½ k x² (000 L523
drops m); the underdamped frequency is √(k/m − Γ²/4m²) (000 L798 has the sign flipped).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.params import nonnegative, number, positive
from mechsim.systems._oscillator import LinearOscillator, free_solution, regime
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.lagrangian import LagrangianBuilder


class DampedOscillator(LinearOscillator):
    id = "damped_oscillator"
    title = "Damped harmonic oscillator (under-, critically and over-damped)"
    source = ("PHYS0500 – Advanced Classical Mechanics, §1.3 (Damped Oscillations); “Energy and "
              "Hamiltonians: Part 3 – Examples” (blog post), Case 5 (Caldirola–Kanai)")
    oracles = ("exact x(t) in all three regimes, maxima spaced 2π/ω₁ with ratio e^{βT₁}, "
               "dE/dt = −bẋ², Caldirola–Kanai h = e^{bt/m}E with dh/dt = −(b/m)L")
    parameters = (
        positive("mass", 1.0, "kg", "mass m"),
        positive("spring_constant", 4.0, "N/m", "spring constant k"),
        nonnegative("damping", 0.4, "kg/s",
                     "linear damping coefficient b (force −b ẋ; γ in the blog post, Γ in its "
                     "Action-Reaction post); critical at b = 2√(mk)"),
        number("initial.x", 1.0, "m", "initial displacement x₀"),
        number("initial_rate.x", 0.0, "m/s", "initial velocity ẋ₀"),
    )

    def declare(self, b: LagrangianBuilder) -> None:
        x, dx, m, k = self.spring(b)
        c = b.param("damping")
        b.rayleigh = c * dx**2 / 2
        b.observable("caldirola_kanai_energy_function", "J",
                     sp.exp(c * b.t / m) * (m * dx**2 / 2 + k * x**2 / 2))
        b.observable("power_dissipated", "W", c * dx**2)
        b.observable("damping_force", "N", -c * dx)

    # --- analytic oracles (PHYS0500 §1.3, corrected) -----------------------------------------
    def critical_damping(self) -> float:
        """b_c = 2√(m k) (β = ω₀)."""
        return 2 * math.sqrt(self.value("mass") * self.value("spring_constant"))

    def regime(self) -> str:
        """"underdamped", "critical" or "overdamped"."""
        return regime(self.natural_frequency(), self.beta())

    def damped_frequency(self) -> float:
        """ω₁ = √(ω₀² − β²) (underdamped only)."""
        w0, b = self.natural_frequency(), self.beta()
        if b >= w0:
            raise ValueError("no oscillation: β ≥ ω₀")
        return math.sqrt(w0 * w0 - b * b)

    def logarithmic_decrement(self) -> float:
        """ln of the ratio of successive maxima, β T₁ = 2πβ/ω₁ (003 lines 143–145)."""
        return 2 * math.pi * self.beta() / self.damped_frequency()

    def exact_solution(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x(t), ẋ(t) in whichever regime the parameters give."""
        return free_solution(t, self.value("initial.x"), self.value("initial_rate.x"),
                             self.natural_frequency(), self.beta())


MODEL = DampedOscillator
