"""Damped oscillator driven by a periodic force: the solution as a superposition of harmonic
responses.

Source: PHYS0500 §1.6 "Principle of Superposition" (lines 292–323) on the oscillator of
§1.3–1.5, m ẍ + b ẋ + k x = F(t). The operator 𝓛 = d²/dt² + a d/dt + b of line 296 (there
a = 2β = b/m and its b is ω₀², not the damping) is linear, so for F = Σ Fₙ the solution is
x = Σ xₙ with 𝓛xₙ = Fₙ/m; a periodic force is written as its Fourier series and each harmonic
answers as in §1.4 (lines 314–323).

The drive integrated here is the truncated series, ω the fundamental (``drive_frequency``),
N = ``harmonics`` the highest harmonic kept:

    F(t) = F₀ [a₀ + Σ_{n=1}^{N} (aₙ cos nωt + bₙ sin nωt)]

with the dimensionless coefficients of the ``waveform``:
- ``square``: F₀ sgn(sin ωt); bₙ = 4/(nπ) for odd n, all others 0;
- ``sawtooth``: F₀ ωt/π for −π < ωt < π, repeated (rises from −F₀ to F₀, drops at ωt = π);
  bₙ = 2(−1)ⁿ⁺¹/(nπ);
- ``user``: ``fourier.a_0`` … ``fourier.a_6`` and ``fourier.b_1`` … ``fourier.b_6`` (terms with
  n ≤ min(N, 6)); they must stay 0 for the other waveforms, so that no setting is ignored.
A truncated square or sawtooth keeps its Gibbs overshoot: the force is the partial sum, and the
oracle is the sum of the responses to the same harmonics. (The responses fall off as 1/n³, so
the motion converges fast to the response to the discontinuous wave; the tests check that too.)

Damping enters as the Rayleigh function ½ b ẋ², the drive as the generalized force F(t), so the
work terms close total − total₀ = W_ext − W_d with W_d = ∫ b ẋ² dt.

Conventions: x along the ``anchor`` frame's x axis (REP-103), x = 0 the rest length and the
potential zero, as for the other 1-D oscillators (``_oscillator.LinearOscillator``).

Typos of the document fixed here (catalog 003 §1.6): line 308 lacks the parentheses of
𝓛(c₁x₁ + c₂x₂); line 314 mixes aₙ and cₙ (𝓛(Σ cₙxₙ) = Σ cₙFₙ); the §1.4 amplitude has
(ω₀² − ω²)² with a minus sign (line 213).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, nonnegative, number, positive
from mechsim.systems._oscillator import LinearOscillator, tone_response
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.lagrangian import LagrangianBuilder

WAVEFORMS = ("square", "sawtooth", "user")
MAX_HARMONICS = 100
USER_HARMONICS = 6
_USER = ["fourier.a_0"] + [f"fourier.{c}_{n}" for n in range(1, USER_HARMONICS + 1)
                           for c in ("a", "b")]


def _harmonic(name: str) -> int:
    return int(name.rsplit("_", 1)[1])


class PeriodicDrive(LinearOscillator):
    id = "periodic_drive"
    title = "Damped oscillator driven by a periodic force (Fourier series, superposition)"
    source = ("PHYS0500 – Advanced Classical Mechanics, §1.6 (Principle of Superposition: a "
              "periodic force as a Fourier series)")
    oracles = ("steady state = Σ of the harmonic responses Dₙcos(nωt − φₙ − δₙ), converging to "
               "the response to the discontinuous square wave; transient + steady state; "
               "input power = bẋ² over a period; work balance")
    parameters = (
        positive("mass", 1.0, "kg", "mass m"),
        positive("spring_constant", 4.0, "N/m", "spring constant k"),
        nonnegative("damping", 0.4, "kg/s", "linear damping coefficient b (force −b ẋ)"),
        Parameter("waveform", "square", "", "periodic force: square F₀ sgn(sin ωt), sawtooth "
                  "F₀ωt/π on (−π, π), or user (the fourier.* coefficients)", choices=WAVEFORMS),
        nonnegative("drive_amplitude", 1.0, "N",
                    "F₀: amplitude of the square or sawtooth, scale of the user series"),
        positive("drive_frequency", 0.7, "rad/s", "fundamental angular frequency ω "
                 "(period 2π/ω)"),
        Parameter("harmonics", 15, "", "highest harmonic n kept in the series",
                  minimum=1, maximum=MAX_HARMONICS),
        *(number(name, 0.0, "", f"user waveform: {'cos' if '.a_' in name else 'sin'} "
                 f"coefficient of harmonic {_harmonic(name)} (times F₀)") for name in _USER),
        number("initial.x", 0.0, "m", "initial displacement"),
        number("initial_rate.x", 0.0, "m/s", "initial velocity"),
    )

    @property
    def waveform(self) -> str:
        return str(self.values["waveform"])

    @property
    def harmonics(self) -> int:
        return int(self.values["harmonics"])

    def check(self) -> None:
        for name in _USER:
            if self.value(name) == 0.0:
                continue
            if self.waveform != "user":
                raise ParameterError(name, f"is used only with waveform: user (the waveform "
                                     f"is {self.waveform}); leave it 0")
            if _harmonic(name) > self.harmonics:
                raise ParameterError(name, f"harmonic {_harmonic(name)} is above harmonics = "
                                     f"{self.harmonics}: raise harmonics or leave it 0")

    def _series(self, user: Callable[[str], sp.Expr]) -> list[tuple[int, sp.Expr, sp.Expr]]:
        """(n, aₙ, bₙ) of the kept harmonics; ``user`` gives the user coefficients (symbols in
        the declaration, numbers for the oracles)."""
        N, zero = self.harmonics, sp.Integer(0)
        if self.waveform == "square":
            return [(n, zero, sp.Integer(4) / (n * sp.pi)) for n in range(1, N + 1, 2)]
        if self.waveform == "sawtooth":
            return [(n, zero, sp.Integer(2 * (-1) ** (n + 1)) / (n * sp.pi))
                    for n in range(1, N + 1)]
        return [(0, user("fourier.a_0"), zero)] + [
            (n, user(f"fourier.a_{n}"), user(f"fourier.b_{n}"))
            for n in range(1, min(N, USER_HARMONICS) + 1)]

    def declare(self, b: LagrangianBuilder) -> None:
        x, dx, m, k = self.spring(b)
        c, F0, w = b.param("damping"), b.param("drive_amplitude"), b.param("drive_frequency")
        b.rayleigh = c * dx**2 / 2
        drive = F0 * sum((an * sp.cos(n * w * b.t) + bn * sp.sin(n * w * b.t)
                          for n, an, bn in self._series(b.param)), sp.Integer(0))
        b.forces = [drive]
        b.observable("drive_force", "N", drive)
        b.observable("power_in", "W", drive * dx)
        b.observable("power_dissipated", "W", c * dx**2)

    # --- analytic oracles (PHYS0500 §1.4 and §1.6) -------------------------------------------
    def fourier_coefficients(self) -> list[tuple[int, float, float]]:
        """(n, aₙ, bₙ) of the integrated series, dimensionless (the force is F₀ times it)."""
        return [(n, float(an), float(bn))
                for n, an, bn in self._series(lambda name: sp.Float(self.value(name)))]

    def drive_tones(self) -> list[tuple[float, float, float]]:
        """Each nonzero harmonic F₀(aₙ cos nωt + bₙ sin nωt) as the tone Fₙ cos(nωt − φₙ),
        Fₙ = F₀√(aₙ² + bₙ²), φₙ = atan2(bₙ, aₙ)."""
        F0, w = self.value("drive_amplitude"), self.value("drive_frequency")
        return [(F0 * math.hypot(an, bn), n * w, math.atan2(bn, an))
                for n, an, bn in self.fourier_coefficients() if F0 * math.hypot(an, bn) != 0.0]

    def harmonic_responses(self) -> list[tuple[float, float, float, float]]:
        """(ωₙ, Dₙ, φₙ, δₙ) per tone: its steady response is Dₙ cos(ωₙt − φₙ − δₙ) (§1.4)."""
        m, w0, beta = self.value("mass"), self.natural_frequency(), self.beta()
        out = []
        for F, w, phi in self.drive_tones():
            D, delta = tone_response(F / m, w, w0, beta)
            out.append((w, D, phi, delta))
        return out

    def steady_state(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The periodic steady state x_ss(t), ẋ_ss(t): the sum of the harmonic responses (the
        document's x = Σ cₙxₙ, line 318). Raises ValueError at an undamped resonance."""
        out = self.particular_solution(t)
        if out is None:
            raise ValueError("undamped resonance: a kept harmonic is at ω₀ and b = 0")
        return out

    def time_scale(self) -> float:
        """The shorter of the free period and the period of the highest harmonic driven."""
        top = max((w for _, w, _ in self.drive_tones()), default=0.0)
        return 2 * math.pi / max(self.natural_frequency(), top)


MODEL = PeriodicDrive
