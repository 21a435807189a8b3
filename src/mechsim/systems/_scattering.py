"""Shared physics of two-particle elastic collisions and scattering (PHYS0500 §5.2–5.3): the
elastic impulse along the line of centres, the LAB ↔ CM angle and energy relations, the
hard-sphere and Rutherford (repulsive Coulomb) deflections and cross-sections, the LAB
cross-section conversion, and the exact incoming state on a repulsive Coulomb hyperbola. Used by
``collision`` and ``scattering``.

Notation of the document: m₁ moving, m₂ at rest in the LAB; θ the CM deflection, ψ (LAB θ₁) the
LAB deflection of m₁, ζ (LAB θ₂) the LAB recoil angle of m₂, x = m₁/m₂ = V/v₁′ (eq. 5.4, 5.9).
Corrected typos used here: tan ζ has v₂′ in the numerator (line 1201); T₀′ = ½μu₁² (line 1249).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.systems._symbolic import sympy as sp

# --- the contact event and the impulse ------------------------------------------------------


def contact_function(x: sp.Expr, y: sp.Expr, dx: sp.Expr, dy: sp.Expr, a: sp.Expr) -> sp.Expr:
    """Event function of the contact |r| = a reached while approaching, for free relative
    motion (r = r₁ − r₂ = (x, y), w = ṙ): g = −r·w − √D, D = w²a² − (r × w)² = w²(a² − b²)
    (b = |r × w|/|w| the impact parameter of the current relative motion), i.e. |w| times the
    distance still to run along w before the spheres touch. It is positive before, 0 exactly at
    the contact and negative after it, and linear in t in free flight, so the dense output
    locates it exactly. (|r| − a itself would not do: free flight has zero error estimate, so
    the steps grow without bound and a step may carry the spheres through each other, leaving
    |r| − a positive at both ends.) Misses (D ≤ 0) give the positive |r| + a."""
    rw = x * dx + y * dy
    D = (dx**2 + dy**2) * a**2 - (x * dy - y * dx) ** 2
    return sp.Piecewise((-rw - sp.sqrt(D), D > 0), (sp.sqrt(x**2 + y**2) + a, True))


def deflection(vx: sp.Expr, vy: sp.Expr, speed: sp.Expr) -> sp.Expr:
    """Unsigned angle of (vx, vy) from +x (the incident direction); 0 for a velocity below
    10⁻¹² ``speed`` (a particle at rest, whose velocity may be a round-off residue)."""
    return sp.Piecewise((sp.Integer(0), vx**2 + vy**2 <= (sp.Float(1e-12) * speed) ** 2),
                        (sp.atan2(sp.Abs(vy), vx), True))


def elastic_impulse(r12: np.ndarray, v1: np.ndarray, v2: np.ndarray, m1: float, m2: float
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Velocities after an elastic impulse along the line of centres n = r12/|r12|
    (r12 = r₁ − r₂): with w = v₁ − v₂, J = 2μ (w·n) n, v₁ → v₁ − J/m₁, v₂ → v₂ + J/m₂.
    Momentum, kinetic energy and angular momentum are conserved; w·n changes sign."""
    n = r12 / np.linalg.norm(r12)
    j = 2.0 * m1 * m2 / (m1 + m2) * float(np.dot(v1 - v2, n)) * n
    return v1 - j / m1, v2 + j / m2


def reflect(r: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The relative velocity after the impulse (same as ``elastic_impulse`` in relative
    coordinates, CM velocity unchanged): w → w − 2 (w·n) n, n = r/|r|."""
    n = r / np.linalg.norm(r)
    return w - 2.0 * float(np.dot(w, n)) * n


# --- LAB ↔ CM (PHYS0500 §5.2) ------------------------------------------------------------------


def lab_angle(theta: np.ndarray | float, mass_ratio: float) -> np.ndarray:
    """ψ from tan ψ = sin θ / (cos θ + m₁/m₂) (eq. 5.3–5.4), in [0, π]."""
    th = np.asarray(theta, dtype=float)
    return np.arctan2(np.sin(th), np.cos(th) + mass_ratio)


def recoil_angle(theta: np.ndarray | float) -> np.ndarray:
    """ζ = (π − θ)/2 (line 1209, any mass ratio): the LAB recoil angle of m₂."""
    return (math.pi - np.asarray(theta, dtype=float)) / 2.0


def energy_shares(theta: np.ndarray | float, m1: float, m2: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(T₁/T₀, T₂/T₀) in the LAB: T₂/T₀ = 2m₁m₂(1 − cos θ)/(m₁ + m₂)² (catalog supplement,
    Thornton & Marion), T₁/T₀ = 1 − T₂/T₀."""
    t2 = 2.0 * m1 * m2 * (1.0 - np.cos(np.asarray(theta, dtype=float))) / (m1 + m2) ** 2
    return 1.0 - t2, t2


def max_lab_angle(m1: float, m2: float) -> float:
    """Largest LAB deflection of m₁: arcsin(m₂/m₁) when m₁ > m₂, else π (catalog pitfall 10)."""
    return math.asin(m2 / m1) if m1 > m2 else math.pi


def cm_angles_of_lab(psi: float, mass_ratio: float) -> list[float]:
    """The CM angles θ that give LAB angle ψ: θ = arcsin(x sin ψ) + ψ (line 1316), and for
    x = m₁/m₂ > 1 also θ = π − arcsin(x sin ψ) + ψ (the second branch, θ_b/θ_f of §5.2)."""
    s = mass_ratio * math.sin(psi)
    if abs(s) > 1.0:
        return []
    out = [math.asin(s) + psi]
    if mass_ratio > 1.0:
        out.append(math.pi - math.asin(s) + psi)
    return [t for t in out if 0.0 <= t <= math.pi]


# --- deflection functions and cross-sections (PHYS0500 §5.3) ----------------------------------


def hard_sphere_deflection(b: np.ndarray | float, a: float) -> np.ndarray:
    """θ = 2 arccos(b/a) for b < a (b = a cos(θ/2), line 1343 with r → 0), 0 for b ≥ a."""
    b = np.asarray(b, dtype=float)
    return np.where(b < a, 2.0 * np.arccos(np.minimum(b / a, 1.0)), 0.0)


def coulomb_deflection(b: np.ndarray | float, k: float, energy: float) -> np.ndarray:
    """Repulsive U = k/r, CM energy E = T₀′: tan(θ/2) = k/(2Eb) (catalog supplement)."""
    return 2.0 * np.arctan2(k, 2.0 * energy * np.asarray(b, dtype=float))


def coulomb_closest_approach(b: float, k: float, energy: float) -> float:
    """r_min = (k/2E)(1 + 1/sin(θ/2)) = k/(2E) + √((k/2E)² + b²)."""
    d = k / (2.0 * energy)
    return d + math.hypot(d, b)


def hard_sphere_cross_section(theta: np.ndarray | float, a: float) -> np.ndarray:
    """σ(θ) = a²/4 (line 1356), isotropic in the CM."""
    return np.full_like(np.asarray(theta, dtype=float), a * a / 4.0)


def rutherford_cross_section(theta: np.ndarray | float, k: float, energy: float) -> np.ndarray:
    """σ(θ) = (k/(4E))² / sin⁴(θ/2), CM, E = T₀′ (catalog supplement; from eq. 5.6)."""
    return (k / (4.0 * energy)) ** 2 / np.sin(np.asarray(theta, dtype=float) / 2.0) ** 4


def lab_cross_section(sigma_cm, psi: np.ndarray | float, mass_ratio: float  # type: ignore[no-untyped-def]
                      ) -> np.ndarray:
    """LAB cross-section σ(ψ) per unit LAB solid angle from the CM one (a function of θ):
    σ(ψ) = Σ σ(θ) sin²θ / (|cos(θ − ψ)| sin²ψ) over the CM angles that give ψ (eq. 5.10; for
    x = m₁/m₂ < 1 one branch, equal to eq. 1312; for x > 1 both branches, ψ < arcsin(1/x))."""
    psi = np.atleast_1d(np.asarray(psi, dtype=float))
    out = np.zeros_like(psi)
    for i, p in enumerate(psi):
        for th in cm_angles_of_lab(float(p), mass_ratio):
            out[i] += float(sigma_cm(th)) * math.sin(th) ** 2 / (
                abs(math.cos(th - p)) * math.sin(p) ** 2)
    return out


# --- Coulomb hyperbola --------------------------------------------------------------------------


def coulomb_incoming_state(mu: float, k: float, speed: float, b: float, distance: float
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Relative position and velocity at r = ``distance`` on the incoming branch of the orbit in
    U = k/r (k > 0, repulsive) whose incoming asymptote is the line y = b run along +x at
    ``speed``: exact (energy, angular momentum L_z = −μ u b and the Laplace–Runge–Lenz vector
    A = p × L + μ k r̂ = (−μk, μ²u²b), which fixes the periapsis direction; r·A = L² + μ k r
    gives the polar angle)."""
    Lz = -mu * speed * b
    A = np.array([-mu * k, mu * mu * speed * speed * b])
    c = (Lz * Lz / distance + mu * k) / float(np.linalg.norm(A))
    if c > 1.0 + 1e-12:
        raise ValueError("distance is inside the closest approach")
    gamma = math.acos(min(c, 1.0))
    phi = math.atan2(A[1], A[0]) + (gamma if Lz <= 0 else -gamma)
    rhat = np.array([math.cos(phi), math.sin(phi)])
    that = np.array([-math.sin(phi), math.cos(phi)])
    v2 = speed * speed - 2.0 * k / (mu * distance)
    vt = Lz / (mu * distance)
    vr = -math.sqrt(max(v2 - vt * vt, 0.0))
    return distance * rhat, vr * rhat + vt * that
