"""Simple pendulum, reduced coordinates and Lagrange-multiplier form.

Source: “Dynamical Systems and Constraints: Part 3 – Simple Pendulum” (L3–97).

Conventions (the document's are ambiguous or wrong here):
- Axes follow REP-103: z up. The pendulum swings in the y–z plane of its ``pivot`` frame;
  ``angle`` φ is measured from straight down and a positive φ is a right-handed rotation about
  +x, so the bob sits at (0, R sin φ, −R cos φ). (The document points gravity along +x.)
- V = m g R (1 − cos φ): zero at the lowest point, which is what L13 intends (its L has the
  zero at pivot height). Only the constant differs.
- Closed form (method ``exact``, reduced form): with ω₀² = g/R and k² = sin²(φ/2) + φ̇²/4ω₀²
  (E = 2 m g R k²), a libration (k ≤ 1) is sin(φ/2) = k sn(ω₀t + u₀ | k²), φ̇ = 2kω₀ cn, taken
  as φ/2 = atan2(k sn, dn) (well conditioned at the turning points); a rotation (k > 1) is
  φ/2 = am(kω₀t + u₀ | 1/k²), φ̇ = 2kω₀ dn (Landau & Lifshitz §11 problem 1; the catalog's
  exact period 4√(R/g)K(k) is its quarter-period). φ keeps its whole turns (unwrapped).
- Multiplier forms: the document's own, ``polar_multiplier``, keeps both plane polar coordinates
  (ρ, φ) with the constraint ρ − R = 0 (its L' = L + λ(ρ − R), L78), so that the radial
  equation is m ρ̈ = m ρ φ̇² + m g cos φ + λ (L82) and λ = −m R φ̇² − m g cos φ (L90) is the
  outward radial force: λ = −T (the document's "λ = T", L95, has the sign wrong; its L93 also
  drops m from the first term). ``multiplier`` is the same constraint in Cartesian (y, z),
  √(y² + z²) − R = 0, whose λ is the same radial force. ``tension`` T = m g cos φ + m R φ̇²
  (L28) in every form but the small-angle one.
- ``small_angle``: the linearised pendulum beside the exact one, V = ½ m g R φ² (sin φ ≈ φ):
  φ = φ₀ cos ω₀t + (φ̇₀/ω₀) sin ω₀t, period 2π√(R/g) whatever the amplitude (the exact period
  exceeds it by 1 + φ₀²/16 + 11φ₀⁴/3072 + …).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from mechsim.codegen.contract import CLOSED_FORM_SIGNATURE
from mechsim.params import Parameter, nonnegative, positive
from mechsim.systems._elliptic import agm_ratios, am_dn, elliptic_f, sn_cn_dn
from mechsim.systems._oscillator import free_solution, state_rows
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


@njit(CLOSED_FORM_SIGNATURE, cache=True)
def _reduced_rows(t0: float, y0: np.ndarray, t: np.ndarray, c: np.ndarray,
                  rows: np.ndarray) -> bool:
    """The reduced form's motion in closed form (see the module docstring) at the times t from
    y0 at t0 into rows [φ, φ̇, rest of y0 unchanged (no work terms act)]; c = [g, R]."""
    g, R = c[0], c[1]
    phi0, rate0 = y0[0], y0[1]
    turns = 2.0 * math.pi * round(phi0 / (2.0 * math.pi))
    half0 = 0.5 * (phi0 - turns)  # in [−π/2, π/2]
    for i in range(t.size):
        for j in range(2, y0.size):
            rows[i, j] = y0[j]
    if g == 0.0:
        for i in range(t.size):
            rows[i, 0] = phi0 + rate0 * (t[i] - t0)
            rows[i, 1] = rate0
        return True
    w0 = math.sqrt(g / R)
    s0, c0, r0 = math.sin(half0), math.cos(half0), rate0 / (2.0 * w0)
    k2 = s0 * s0 + r0 * r0
    k = math.sqrt(k2)
    if k2 <= 1.0:  # libration: sn u₀ = s0/k, cn u₀ = r0/k, dn u₀ = c0
        m1 = (c0 - r0) * (c0 + r0)  # 1 − k², without its cancellation
        u0 = elliptic_f(math.atan2(s0, r0), m1) if k > 0.0 else 0.0
        ratios, scale = agm_ratios(k2, m1)
        a_n = scale * 0.5 ** ratios.size
        for i in range(t.size):
            sn, cn, dn = sn_cn_dn(w0 * (t[i] - t0) + u0, ratios, a_n, m1)
            rows[i, 0] = turns + 2.0 * math.atan2(k * sn, dn)
            rows[i, 1] = 2.0 * k * w0 * cn
        return True
    # rotation in the sense of φ̇₀: φ/2 = am(±kω₀τ + u₀ | 1/k²)
    sense = 1.0 if rate0 > 0.0 else -1.0
    m1 = (r0 - c0) * (r0 + c0) / k2
    u0 = elliptic_f(half0, m1)
    ratios, scale = agm_ratios(1.0 / k2, m1)
    for i in range(t.size):
        am, dn = am_dn(sense * k * w0 * (t[i] - t0) + u0, ratios, scale, m1)
        rows[i, 0] = turns + 2.0 * am
        rows[i, 1] = 2.0 * sense * k * w0 * dn
    return True


class Pendulum(LagrangianModel):
    id = "pendulum"
    title = "Simple pendulum (reduced, polar and Cartesian multiplier, small-angle forms)"
    source = "“Dynamical Systems and Constraints: Part 3 – Simple Pendulum” (blog post)"
    formulations = ("reduced", "multiplier", "polar_multiplier", "small_angle", "hamiltonian")
    oracles = ("closed-form φ(t) (Jacobi sn, am; libration and rotation) = radau15; exact "
               "period 4√(R/g)K(k); tension mg(3cosφ − 2cosφ₀); polar and Cartesian λ = −T; "
               "forms agree; small angle: φ₀cos ω₀t, period 2π√(R/g) for every amplitude")
    parameters = (
        positive("mass", 1.0, "kg", "bob mass m"),
        positive("length", 1.0, "m", "rod length R"),
        nonnegative("gravity", 9.81, "m/s^2", "gravitational acceleration g"),
        Parameter("initial.angle", 1.0, "rad", "initial angle φ from straight down",
                  minimum=-math.pi, maximum=math.pi),
        Parameter("initial_rate.angle", 0.0, "rad/s", "initial angular rate φ̇"),
    )

    def declare(self, b: LagrangianBuilder) -> None:
        m, R, g = b.param("mass"), b.param("length"), b.param("gravity")
        if self.formulation == "reduced":
            phi, dphi = b.coordinate("angle", "rad")
            b.kinetic = m * R**2 * dphi**2 / 2
            b.potential = m * g * R * (1 - sp.cos(phi))
            b.observable("tension", "N", m * g * sp.cos(phi) + m * R * dphi**2)
            bob = (sp.Integer(0), R * sp.sin(phi), -R * sp.cos(phi))
            angle = phi
        elif self.formulation == "small_angle":
            phi, dphi = b.coordinate("angle", "rad")
            b.kinetic = m * R**2 * dphi**2 / 2
            b.potential = m * g * R * phi**2 / 2
            bob = (sp.Integer(0), R * sp.sin(phi), -R * sp.cos(phi))
            angle = phi
        elif self.formulation == "polar_multiplier":
            rho, drho = b.coordinate("rho", "m")
            phi, dphi = b.coordinate("angle", "rad")
            b.kinetic = m * (drho**2 + rho**2 * dphi**2) / 2
            b.potential = m * g * (R - rho * sp.cos(phi))
            b.constraint("rod_length", rho - R)
            lam = b.multiplier(0)
            b.observable("tension", "N", -lam)
            b.observable("multiplier", "N", lam)
            bob = (sp.Integer(0), rho * sp.sin(phi), -rho * sp.cos(phi))
            angle = phi
        else:
            y, dy = b.coordinate("y", "m")
            z, dz = b.coordinate("z", "m")
            b.kinetic = m * (dy**2 + dz**2) / 2
            b.potential = m * g * (z + R)
            b.constraint("rod_length", sp.sqrt(y**2 + z**2) - R)
            lam = b.multiplier(0)
            b.observable("tension", "N", -lam)
            b.observable("multiplier", "N", lam)
            angle = sp.atan2(y, -z)
            b.observable("angle", "rad", angle)
            bob = (sp.Integer(0), y, z)
        b.frame("pivot", "world", (0, 0, 0))
        b.frame("bob", "pivot", bob, (sp.sin(angle / 2), 0, 0, sp.cos(angle / 2)))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        phi, w = self.value("initial.angle"), self.value("initial_rate.angle")
        R = self.value("length")
        if self.formulation in ("reduced", "small_angle"):
            return np.array([phi]), np.array([w])
        if self.formulation == "polar_multiplier":
            return np.array([R, phi]), np.array([0.0, w])
        return (np.array([R * math.sin(phi), -R * math.cos(phi)]),
                np.array([R * math.cos(phi) * w, R * math.sin(phi) * w]))

    def time_scale(self) -> float:
        g = self.value("gravity")
        return 2 * math.pi * math.sqrt(self.value("length") / g) if g > 0 else 1.0

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray,
                  work_terms: bool = True) -> np.ndarray | None:
        """The reduced and small-angle forms' motion in closed form (see the module docstring);
        the rest of the state (work terms: none act) carried unchanged. None for the multiplier
        forms."""
        if self.formulation not in ("reduced", "small_angle"):
            return None
        tau = np.asarray(t, dtype=float) - t0
        g, R = self.value("gravity"), self.value("length")
        phi0, rate0 = float(y0[0]), float(y0[1])
        if self.formulation == "small_angle":
            return state_rows(y0, list(free_solution(tau, phi0, rate0, math.sqrt(g / R))))
        rows = np.empty((tau.size, len(y0)))
        _reduced_rows(float(t0), np.ascontiguousarray(y0, dtype=float),
                      np.ascontiguousarray(t, dtype=float), np.array([g, R]), rows)
        return rows

    def closed_form_kernel(self, y0: np.ndarray) -> tuple[Any, np.ndarray] | None:
        """``_reduced_rows`` in the reduced formulation (small angle: ``propagate``)."""
        if self.formulation != "reduced":
            return None
        return _reduced_rows, np.array([self.value("gravity"), self.value("length")])

    # --- analytic oracles (tests/test_pendulum.py checks the integrated motion against them) -
    def amplitude(self) -> float:
        """Turning angle φ_max of a libration: cos φ_max = cos φ₀ − R φ̇₀² / (2 g)."""
        c = math.cos(self.value("initial.angle")) - (
            self.value("length") * self.value("initial_rate.angle") ** 2
            / (2 * self.value("gravity")))
        if c <= -1.0:
            raise ValueError("the pendulum circulates: no amplitude")
        return math.acos(c)

    def exact_period(self) -> float:
        """T = 4 √(R/g) K(k), k = sin(φ_max / 2) (K takes the parameter m = k²)."""
        k = math.sin(self.amplitude() / 2)
        from scipy.special import ellipk  # here: importing scipy.special costs 0.3 s

        return 4 * math.sqrt(self.value("length") / self.value("gravity")) * float(ellipk(k * k))

    def tension_at(self, phi: np.ndarray) -> np.ndarray:
        """Rod tension at angle φ: T = m g (3 cos φ − 2 cos φ_max) (from energy conservation)."""
        return self.value("mass") * self.value("gravity") * (
            3 * np.cos(phi) - 2 * math.cos(self.amplitude()))

MODEL = Pendulum
