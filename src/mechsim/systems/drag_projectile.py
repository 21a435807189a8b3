"""Projectile with linear air drag, damping from a Rayleigh dissipation function.

Sources: Introduction to analytical mechanics, "Lagrange's equation of motion with frictional
forces" (L832–875:
Q_j = −∂D/∂q̇_j, D = ½ Σ f_kl q̇_k q̇_l, dE/dt = −2D) and §2.6 (L877–900): a particle of mass m
with V = m g z, D = ½ α (ẋ² + ẏ² + ż²), giving m ẍ + α ẋ = 0, m ÿ + α ẏ = 0,
m z̈ + α ż + m g = 0.

Conventions: Cartesian (x, y, z) of the ``launch`` frame, z up (as in the document and
REP-103); V = m g z, zero at launch height. Closed form (catalog [derived]), τ = m/α:
ẋ = ẋ₀ e^{−t/τ}, x = x₀ + ẋ₀ τ (1 − e^{−t/τ}) (likewise y); ż = −gτ + (ż₀ + gτ) e^{−t/τ},
z = z₀ − gτ t + τ (ż₀ + gτ)(1 − e^{−t/τ}); terminal velocity −(m g/α) ẑ. x and y are cyclic in
L, yet p_x = m ẋ and p_y decay: D acts on them (001 §2.6 pitfall), so they are observables,
not invariants. The ground is drawn at z = 0 but not enforced (no impact).

Document typos corrected (catalog 001 §10 item 11): friction is "derived from a potential
V(q, q̇, t)" at L841 — it comes from D; D is written with f_jk q̇_k q̇_l at L859 for f_kl.
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.params import nonnegative, number, positive
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class DragProjectile(LagrangianModel):
    id = "drag_projectile"
    title = "Projectile with linear air drag (Rayleigh dissipation)"
    source = ("Introduction to analytical mechanics, “Lagrange's equation of motion with "
              "frictional forces” (Rayleigh dissipation, projectile with air friction)")
    oracles = ("closed-form trajectory with τ = m/α, terminal velocity −mg/α, horizontal "
               "asymptote x₀ + ẋ₀τ, dE/dt = −2D, p_x = mẋ₀e^{−t/τ}")
    parameters = (
        positive("mass", 1.0, "kg", "projectile mass m"),
        nonnegative("drag_coefficient", 0.5, "kg/s", "linear drag coefficient α (force −α v)"),
        nonnegative("gravity", 9.81, "m/s^2", "gravitational acceleration g"),
        number("initial.x", 0.0, "m", "initial x"),
        number("initial.y", 0.0, "m", "initial y"),
        number("initial.z", 0.0, "m", "initial height z"),
        number("initial_rate.x", 12.0, "m/s", "initial ẋ"),
        number("initial_rate.y", 0.0, "m/s", "initial ẏ"),
        number("initial_rate.z", 15.0, "m/s", "initial ż"),
    )
    AXES = ("x", "y", "z")

    def declare(self, b: LagrangianBuilder) -> None:
        m, a, g = b.param("mass"), b.param("drag_coefficient"), b.param("gravity")
        q, v = zip(*(b.coordinate(c, "m") for c in self.AXES), strict=True)
        speed2 = sum(vi**2 for vi in v)
        b.kinetic = m * speed2 / 2
        b.potential = m * g * q[2]
        b.rayleigh = a * speed2 / 2
        b.observable("speed", "m/s", speed2 ** 0.5)
        b.observable("rayleigh_function", "W", a * speed2 / 2)
        b.observable("power_dissipated", "W", a * speed2)
        b.observable("momentum_x", "kg m/s", m * v[0])
        b.observable("momentum_y", "kg m/s", m * v[1])
        b.frame("launch", "world", (0, 0, 0))
        b.frame("projectile", "launch", q)

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.array([self.value(f"initial.{c}") for c in self.AXES]),
                np.array([self.value(f"initial_rate.{c}") for c in self.AXES]))

    def visuals(self) -> tuple[Visual, ...]:
        ground = tuple((x, y, 0.0) for x, y in ((-5, -5), (40, -5), (40, 5), (-5, 5), (-5, -5)))
        return (Visual("polyline", "launch", points=ground, color=(110, 160, 110)),
                Visual("axes", "launch", radius=1.0),
                Visual("sphere", "projectile", radius=0.2, color=(230, 120, 90)),
                Visual("trail", "projectile", color=(120, 170, 255)))

    def time_scale(self) -> float:
        a = self.value("drag_coefficient")
        return self.value("mass") / a if a > 0 else 1.0

    # --- analytic oracles (catalog 001 §2.6, derived) ----------------------------------------
    def relaxation_time(self) -> float:
        """τ = m / α (infinite without drag)."""
        a = self.value("drag_coefficient")
        return self.value("mass") / a if a > 0 else math.inf

    def terminal_velocity(self) -> float:
        """ż_∞ = −m g / α."""
        return -self.value("gravity") * self.relaxation_time()

    def horizontal_asymptote(self) -> tuple[float, float]:
        """(x_∞, y_∞) = (x₀ + ẋ₀ τ, y₀ + ẏ₀ τ)."""
        tau = self.relaxation_time()
        return (self.value("initial.x") + self.value("initial_rate.x") * tau,
                self.value("initial.y") + self.value("initial_rate.y") * tau)

    def exact_solution(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities, shape (len(t), 3) each."""
        t = np.asarray(t, dtype=float)
        q0, v0 = self.initial_state()
        g, tau = self.value("gravity"), self.relaxation_time()
        if math.isinf(tau):  # no drag: the parabola
            acc = np.array([0.0, 0.0, -g])
            return (q0 + v0 * t[..., None] + 0.5 * acc * t[..., None] ** 2,
                    v0 + acc * t[..., None])
        e = np.exp(-t / tau)[..., None]
        vinf = np.array([0.0, 0.0, -g * tau])
        vel = vinf + (v0 - vinf) * e
        pos = q0 + vinf * t[..., None] + tau * (v0 - vinf) * (1 - e)
        return pos, vel


MODEL = DragProjectile
