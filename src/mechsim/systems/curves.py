"""Curves a model defines besides its trajectories: functions of one variable drawn with the
levels that read them, computed from a model's parameters alone (no integration; what needs
runs, a sweep or a set of trajectories, lives in ``mechsim.experiments``).

- ``effective_potential``: U_eff(r) = U(r) + l²/(2μr²) of a central-force model with its
  orbit's energy as a level and the turning points where they meet (PHYS0500 §4.5 and
  Fig. 4.2; the analytical-mechanics notes' “Classification of the orbits”), and
  ``kepler_effective_potential`` with the notes' four levels E₁ > 0, E₂ = 0, E₃ < 0 and
  E₄ = V_min for U = −k/r.
- ``top_potential``: V(θ) = (p_φ − p_ψ cos θ)²/(2I₁ sin²θ) + Mgh cos θ of the heavy top with
  E′ and the nutation bounds θ₁, θ₂ (PHYS0500 §7.8.1–7.8.2, eqs. 7.7–7.8).
- ``resonance_curves``: the steady amplitude D(ω) and the mean kinetic energy ⟨T⟩(ω) of the
  driven oscillator, with ω_R = √(ω₀² − 2β²) and ω_E = ω₀ (PHYS0500 §1.5, §1.5.1, typos
  corrected as in ``driven_oscillator``).
- ``pendulum_separatrix``: φ̇ = ±2ω₀ cos(φ/2), the phase curve between libration and
  rotation (E = 2mgR), for phase portraits of the pendulum.
Units are SI; every curve says its axes' names and units.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mechsim.systems._central import effective_potential as _veff
from mechsim.systems._central import kepler_elements, turning_points


@dataclass(frozen=True)
class Level:
    """A horizontal line read against a curve: its value, a label, and the abscissae where
    the curve meets it (turning points)."""

    value: float
    label: str
    crossings: tuple[float, ...] = ()


@dataclass(frozen=True)
class Curve:
    """y(x) sampled, with its axes' names and units, and the levels drawn with it."""

    name: str
    x: np.ndarray
    y: np.ndarray
    x_label: str
    x_unit: str
    y_label: str
    y_unit: str
    levels: tuple[Level, ...] = ()
    marks: dict[str, float] = field(default_factory=dict)


def _central_first_integrals(model: Any) -> tuple[Callable[[float], float], float, float,
                                                  float]:
    """(U, μ, l, E) of a central-force model (``central_force`` or ``power_law_orbit``)."""
    if hasattr(model, "orbit_energy"):
        return (model.potential_function(), model.value("mass"), model.angular_momentum(),
                model.orbit_energy())
    return (model.potential_function(), model.reduced_mass(), model.angular_momentum(),
            model.relative_energy())


def orbit_curves(model: Any) -> tuple[Curve, ...]:
    """A central-force orbit's published curves: U_eff(r) with its energy and turning points
    (none where the orbit's radial range cannot be found: a fall to the centre)."""
    try:
        return (effective_potential(model),)
    except (ValueError, ArithmeticError):
        return ()


def effective_potential(model: Any, r: np.ndarray | None = None) -> Curve:
    """U_eff(r) of the model's orbit with its energy E as a level, crossed at the turning
    points; r defaults to 200 points from a fifth of r_min (or of r₀) to twice r_max."""
    U, mu, l, E = _central_first_integrals(model)
    r0 = model.value("initial.r")
    if r is None:
        lo, hi = model.radial_range()
        inner = 0.2 * (lo if lo > 0 else r0)
        outer = 2.0 * (hi if math.isfinite(hi) else 3 * r0)
        r = np.geomspace(inner, outer, 200)
    V = _veff(U, mu, l)
    y = np.array([V(float(ri)) for ri in r])
    tp = tuple(t for t in turning_points(U, mu, E, l, r_min=float(r[0]), r_max=float(r[-1])))
    return Curve("effective_potential", np.asarray(r, dtype=float), y, "r", "m",
                 "U_eff", "J", (Level(E, "E", tp),))


def kepler_effective_potential(mu: float, k: float, l: float,
                               r: np.ndarray | None = None) -> Curve:
    """U_eff = −k/r + l²/(2μr²) with the notes' levels: E₁ = +½|V_min| (unbound, one
    turning point), E₂ = 0 (parabola), E₃ = ½V_min (ellipse, two), E₄ = V_min = −μk²/(2l²)
    (circle at r = l²/(μk)); ``marks`` holds the minimum's position and value."""
    r_c = l * l / (mu * k)
    v_min = -mu * k * k / (2 * l * l)
    if r is None:
        r = np.geomspace(0.25 * r_c, 12 * r_c, 300)

    def U(x: float) -> float:
        return -k / x

    V = _veff(U, mu, l)
    y = np.array([V(float(ri)) for ri in r])
    levels = []
    for E, label in ((-0.5 * v_min, "E₁ > 0"), (0.0, "E₂ = 0"), (0.5 * v_min, "E₃ < 0"),
                     (v_min, "E₄ = V_min")):
        if E == v_min:
            crossings: tuple[float, ...] = (r_c,)
        else:
            el = kepler_elements(mu, k, E, l)
            crossings = tuple(x for x in (el["r_min"], el["r_max"]) if math.isfinite(x))
        levels.append(Level(E, label, crossings))
    return Curve("kepler_effective_potential", np.asarray(r, dtype=float), y, "r", "m",
                 "U_eff", "J", tuple(levels), {"circular_radius": r_c, "minimum": v_min})


def top_potential(model: Any, theta: np.ndarray | None = None) -> Curve:
    """V(θ) of the heavy symmetric top (eq. 7.8) with E′ = ½I₁θ̇₀² + V(θ₀) (eq. 7.7) as a
    level, met at the nutation bounds θ₁ ≤ θ ≤ θ₂."""
    if theta is None:
        theta = np.linspace(0.02, math.pi - 0.02, 400)
    V = model.effective_potential(theta)
    I1 = model.value("transverse_inertia")
    th0 = model.value("initial.theta")
    e_prime = 0.5 * I1 * model.value("initial_rate.theta") ** 2 + float(
        model.effective_potential(np.array(th0)))
    return Curve("top_potential", np.asarray(theta, dtype=float), np.asarray(V), "θ", "rad",
                 "V(θ)", "J", (Level(e_prime, "E′", tuple(model.nutation_bounds())),))


def resonance_curves(model: Any, omega: np.ndarray | None = None) -> tuple[Curve, Curve]:
    """(D(ω), ⟨T⟩(ω)) of the driven oscillator: D = A/√((ω₀² − ω²)² + 4ω²β²), A = F₀/m,
    ⟨T⟩ = (mA²/4) ω²/((ω₀² − ω²)² + 4ω²β²); marks ω_R (where ω₀² > 2β²) and ω_E = ω₀."""
    m, w0, beta = model.value("mass"), model.natural_frequency(), model.beta()
    A = model.value("drive_amplitude") / m
    if omega is None:
        omega = np.linspace(0.0, 2.5 * w0, 501)
    omega = np.asarray(omega, dtype=float)
    den = (w0 * w0 - omega * omega) ** 2 + 4 * omega * omega * beta * beta
    marks = {"omega_0": w0, "omega_E": w0}
    if w0 * w0 > 2 * beta * beta:
        marks["omega_R"] = math.sqrt(w0 * w0 - 2 * beta * beta)
    amplitude = Curve("resonance_amplitude", omega, A / np.sqrt(den), "ω", "rad/s", "D", "m",
                      marks=dict(marks))
    kinetic = Curve("kinetic_energy_resonance", omega, m * A * A / 4 * omega**2 / den, "ω",
                    "rad/s", "⟨T⟩", "J", marks=dict(marks))
    return amplitude, kinetic


def pendulum_separatrix(model: Any, phi: np.ndarray | None = None) -> Curve:
    """The upper branch φ̇ = 2ω₀ cos(φ/2), ω₀² = g/R, of the separatrix E = 2mgR between
    the pendulum's librations and rotations (its lower branch is −φ̇)."""
    if phi is None:
        phi = np.linspace(-math.pi, math.pi, 401)
    w0 = math.sqrt(model.value("gravity") / model.value("length"))
    return Curve("pendulum_separatrix", np.asarray(phi, dtype=float), 2 * w0 * np.cos(phi / 2),
                 "φ", "rad", "φ̇", "rad/s", marks={"omega_0": w0})
