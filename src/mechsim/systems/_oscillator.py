"""Closed-form solution of the free linear oscillator ẍ + 2βẋ + ω₀²x = 0 (shared oracle).

Used by harmonic_oscillator (β = 0), damped_oscillator (all three regimes), planar_oscillator
(per axis) and coupled_oscillators (per normal mode). Not a system (leading underscore).
"""

from __future__ import annotations

import math

import numpy as np


def regime(omega0: float, beta: float, rtol: float = 1e-12) -> str:
    """"underdamped" (β < ω₀, includes β = 0), "critical" (β = ω₀) or "overdamped"."""
    if abs(beta - omega0) <= rtol * max(omega0, beta):
        return "critical"
    return "underdamped" if beta < omega0 else "overdamped"


def free_solution(t: np.ndarray, x0: float, v0: float, omega0: float,
                  beta: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """x(t), ẋ(t) of ẍ + 2βẋ + ω₀²x = 0 with x(0) = x₀, ẋ(0) = v₀.

    Underdamped (ω₁ = √(ω₀² − β²)): x = e^{−βt}[x₀ cos ω₁t + (v₀ + βx₀)/ω₁ sin ω₁t];
    critical: x = e^{−βt}[x₀ + (v₀ + βx₀)t]; overdamped (ω₂ = √(β² − ω₀²)): cosh/sinh.
    """
    t = np.asarray(t, dtype=float)
    decay = np.exp(-beta * t)
    c = v0 + beta * x0
    kind = regime(omega0, beta)
    if kind == "critical":
        return decay * (x0 + c * t), decay * (v0 - beta * c * t)
    s = omega0 * omega0 * x0 + beta * v0
    if kind == "underdamped":
        w = math.sqrt(omega0 * omega0 - beta * beta)
        cs, sn = np.cos(w * t), np.sin(w * t)
        return decay * (x0 * cs + c / w * sn), decay * (v0 * cs - s / w * sn)
    w = math.sqrt(beta * beta - omega0 * omega0)
    ch, sh = np.cosh(w * t), np.sinh(w * t)
    return decay * (x0 * ch + c / w * sh), decay * (v0 * ch - s / w * sh)
