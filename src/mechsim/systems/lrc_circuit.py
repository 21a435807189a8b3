"""Series LRC circuit driven by an emf: the electrical analogue of the driven damped oscillator.

Source: PHYS0500 §1.7 "Analogy Between Electrical and Mechanical Quantities" (lines 325–333),
whose table maps x → q (charge), ẋ → q̇ = I (current), m → L (inductance), b → R (resistance),
1/k → C (capacitance), F → ℰ (impressed emf); with §1.3–1.5 (damped and driven oscillations,
resonance and Q) for the oracles that carry over (catalog 003 §1.7, [DERIVED]).

Declared by its Lagrangian in the charge q: L = ½ L q̇² − q²/(2C) (the magnetic energy ½ L I²
plays T, the electric energy q²/(2C) plays V), the Rayleigh function ½ R q̇² (Joule power R I²
= 2D) and the generalized force ℰ(t) = ℰ₀ cos ωt, giving Kirchhoff's voltage law
L q̈ + R q̇ + q/C = ℰ₀ cos ωt. So total = magnetic + electric energy, ``work_dissipated`` is the
Joule heat ∫ R I² dt and ``work_external`` the work of the source ∫ ℰ I dt.

Conventions: SI electrical units (C, A, H, Ω, F, V, J, W); q is the charge on the capacitor plate
that the positive current I = q̇ charges, and ℰ > 0 drives I in that direction. A circuit has no
pose: the model publishes no frames. Q follows the circuit convention Q = ω₀L/R = (1/R)√(L/C)
(= ω₀/2β, 2π × stored energy / energy lost per cycle at light damping; the current's
half-power bandwidth is exactly R/L = ω₀/Q); the document's Q = ω_R/2β of §1.5 is
``document_quality_factor``. The charge amplitude peaks at ω_R = √(ω₀² − 2β²), the current
amplitude exactly at ω₀ (the analogue of the kinetic-energy resonance ω_E = ω₀, 003 line 288).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.params import nonnegative, number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.driven_oscillator import DrivenOscillator
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class LRCCircuit(LagrangianModel):
    id = "lrc_circuit"
    title = "Series LRC circuit driven by an emf (electrical analogue of the oscillator)"
    source = ("PHYS0500 – Advanced Classical Mechanics, §1.7 (Analogy Between Electrical and "
              "Mechanical Quantities), with §1.3–1.5")
    oracles = ("ω₀ = 1/√(LC); current amplitude ℰ₀/√(R² + (ωL − 1/ωC)²), peak at ω₀, "
               "half-power bandwidth R/L "
               "(Q = ω₀L/R); charge peak ω_R; Joule heat ∫RI²dt = work dissipated; same q(t) as "
               "the mechanical analogue (m, b, k, F) = (L, R, 1/C, ℰ)")
    parameters = (
        positive("inductance", 1.0, "H", "inductance L"),
        nonnegative("resistance", 0.4, "Ω", "resistance R"),
        positive("capacitance", 0.25, "F", "capacitance C"),
        nonnegative("emf_amplitude", 1.0, "V", "amplitude ℰ₀ of the driving emf ℰ₀ cos ωt"),
        nonnegative("emf_frequency", 1.8, "rad/s", "angular frequency ω of the emf"),
        number("initial.q", 0.0, "C", "initial charge q on the capacitor"),
        number("initial_rate.q", 0.0, "A", "initial current I = q̇"),
    )

    def declare(self, b: LagrangianBuilder) -> None:
        q, current = b.coordinate("q", "C")
        L, R, C = b.param("inductance"), b.param("resistance"), b.param("capacitance")
        E0, w = b.param("emf_amplitude"), b.param("emf_frequency")
        b.kinetic = L * current**2 / 2
        b.potential = q**2 / (2 * C)
        b.rayleigh = R * current**2 / 2
        emf = E0 * sp.cos(w * b.t)
        b.forces = [emf]
        b.observable("current", "A", current)
        b.observable("magnetic_energy", "J", L * current**2 / 2)
        b.observable("electric_energy", "J", q**2 / (2 * C))
        b.observable("capacitor_voltage", "V", q / C)
        b.observable("resistor_voltage", "V", R * current)
        b.observable("emf", "V", emf)
        b.observable("power_in", "W", emf * current)
        b.observable("joule_power", "W", R * current**2)

    # --- the analogue (PHYS0500 §1.7 table) --------------------------------------------------
    def mechanical_analogue(self) -> DrivenOscillator:
        """The driven oscillator with m = L, b = R, k = 1/C, F₀ = ℰ₀ and x = q, ẋ = I."""
        return DrivenOscillator(
            mass=self.value("inductance"), damping=self.value("resistance"),
            spring_constant=1.0 / self.value("capacitance"),
            drive_amplitude=self.value("emf_amplitude"),
            drive_frequency=self.value("emf_frequency"),
            **{"initial.x": self.value("initial.q"),
               "initial_rate.x": self.value("initial_rate.q")})

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray,
                  work_terms: bool = True) -> np.ndarray | None:
        """Exact: the analogue's closed form (same state layout [q, I, W_ext, W_d] and the same
        energies under the mapping)."""
        return self.mechanical_analogue().propagate(t0, y0, t, work_terms)

    def time_scale(self) -> float:
        return 2 * math.pi / self.natural_frequency()

    # --- analytic oracles --------------------------------------------------------------------
    def natural_frequency(self) -> float:
        """ω₀ = 1/√(LC)."""
        return 1.0 / math.sqrt(self.value("inductance") * self.value("capacitance"))

    def beta(self) -> float:
        """β = R/(2L)."""
        return self.value("resistance") / (2 * self.value("inductance"))

    def quality_factor(self) -> float:
        """Q = ω₀L/R = (1/R)√(L/C) (infinite without resistance)."""
        R = self.value("resistance")
        return math.inf if R == 0 else self.natural_frequency() * self.value("inductance") / R

    def document_quality_factor(self) -> float:
        """The document's Q = ω_R/(2β) (PHYS0500 line 258), via the analogue."""
        return self.mechanical_analogue().quality_factor()

    def charge_resonance_frequency(self) -> float:
        """ω_R = √(ω₀² − 2β²): where the charge amplitude peaks (needs ω₀² > 2β²)."""
        return self.mechanical_analogue().resonance_frequency()

    def impedance(self, omega: float | None = None) -> complex:
        """Z = R + i(ωL − 1/(ωC)) at ω (default: the emf's); the steady current is
        Re[(ℰ₀/Z) e^{iωt}]."""
        w = self.value("emf_frequency") if omega is None else omega
        return complex(self.value("resistance"),
                       w * self.value("inductance") - 1.0 / (w * self.value("capacitance")))

    def current_amplitude(self, omega: float | None = None) -> float:
        """Steady current amplitude ℰ₀/|Z|, largest (ℰ₀/R) at ω = ω₀."""
        return self.value("emf_amplitude") / abs(self.impedance(omega))


MODEL = LRCCircuit
