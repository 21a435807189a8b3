"""Spring (elastic) pendulum: a bob on a spring swinging in a vertical plane.

Source: Introduction to analytical mechanics, "Spring pendulum" (L630–669): spring length l + x,
angle θ from the downward vertical, T = ½ m (ẋ² + (l + x)² θ̇²), V = −m g (l + x) cos θ + ½ k x².

Formulations:
- ``polar``: the document's coordinates (``extension`` x, ``angle`` θ).
- ``cartesian``: the bob's (y, z) in the swing plane with V = m g z + ½ k (√(y² + z²) − l)²;
  the same system, used as an independent check (separable: symplectic integration).
Initial conditions are given in the document's coordinates in both.

Conventions (REP-103, z up): the bob swings in the y–z plane of the ``pivot`` frame, θ is a
right-handed rotation about +x measured from straight down, the bob sits at
((l + x) sin θ, −(l + x) cos θ) in (y, z). The potential zero is the pivot height (as in the
document), so V is not zero at equilibrium.

Document typos corrected (catalog 001 §2.2, §10 item 9): "l + χ(t)" is l + x(t) (L636) and the
θ equation's "−mq sin θ" is −m g (l + x) sin θ (L669). Equilibrium x = mg/k, small-oscillation
frequencies √(k/m) (radial) and √(g/(l + mg/k)) (swing) are derived in the catalog.
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, nonnegative, number, positive
from mechsim.systems._oscillator import free_solution
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class SpringPendulum(LagrangianModel):
    id = "spring_pendulum"
    title = "Spring (elastic) pendulum"
    source = "Introduction to analytical mechanics, “Spring pendulum”"
    formulations = ("polar", "cartesian")
    oracles = ("equilibrium stretch mg/k; small-oscillation frequencies √(k/m) and "
               "√(g/(l + mg/k)); exact vertical SHM for θ ≡ 0; E conserved; forms agree")
    parameters = (
        positive("mass", 1.0, "kg", "bob mass m"),
        positive("length", 1.0, "m", "natural length l of the spring"),
        positive("spring_constant", 40.0, "N/m", "spring constant k"),
        nonnegative("gravity", 9.81, "m/s^2", "gravitational acceleration g"),
        number("initial.extension", 0.3, "m", "initial extension x (spring length l + x)"),
        Parameter("initial.angle", 0.8, "rad", "initial angle θ from straight down",
                  minimum=-math.pi, maximum=math.pi),
        number("initial_rate.extension", 0.0, "m/s", "initial ẋ"),
        number("initial_rate.angle", 0.0, "rad/s", "initial θ̇"),
    )

    def check(self) -> None:
        if self.value("length") + self.value("initial.extension") <= 0:
            raise ParameterError("initial.extension", "must be > −length (the spring length "
                                 "l + x must be positive)")

    def declare(self, b: LagrangianBuilder) -> None:
        m, l, k, g = (b.param("mass"), b.param("length"), b.param("spring_constant"),
                      b.param("gravity"))
        if self.formulation == "polar":
            x, dx = b.coordinate("extension", "m")
            th, dth = b.coordinate("angle", "rad")
            rho = l + x
            b.kinetic = m * (dx**2 + rho**2 * dth**2) / 2
            b.potential = -m * g * rho * sp.cos(th) + k * x**2 / 2
            y, z = rho * sp.sin(th), -rho * sp.cos(th)
        else:
            y, dy = b.coordinate("y", "m")
            z, dz = b.coordinate("z", "m")
            rho = sp.sqrt(y**2 + z**2)
            x = rho - l
            th = sp.atan2(y, -z)
            b.kinetic = m * (dy**2 + dz**2) / 2
            b.potential = m * g * z + k * x**2 / 2
            b.observable("extension", "m", x)
            b.observable("angle", "rad", th)
        b.observable("spring_tension", "N", k * x)
        b.observable("spring_length", "m", rho)
        b.frame("pivot", "world", (0, 0, 0))
        b.frame("bob", "pivot", (0, y, z), (sp.sin(th / 2), 0, 0, sp.cos(th / 2)))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        x, th = self.value("initial.extension"), self.value("initial.angle")
        dx, dth = self.value("initial_rate.extension"), self.value("initial_rate.angle")
        if self.formulation == "polar":
            return np.array([x, th]), np.array([dx, dth])
        rho = self.value("length") + x
        s, c = math.sin(th), math.cos(th)
        return (np.array([rho * s, -rho * c]),
                np.array([dx * s + rho * c * dth, -dx * c + rho * s * dth]))

    def visuals(self) -> tuple[Visual, ...]:
        return (Visual("box", "pivot", size=(0.1, 0.1, 0.02), color=(150, 150, 150)),
                Visual("link", "pivot", to_frame="bob", radius=0.012, color=(200, 200, 90)),
                Visual("sphere", "bob", radius=0.08),
                Visual("trail", "bob", color=(120, 170, 255)))

    def time_scale(self) -> float:
        return 2 * math.pi / max(self.radial_frequency(), self.swing_frequency())

    # --- analytic oracles (catalog 001 §2.2, derived) ----------------------------------------
    def equilibrium_extension(self) -> float:
        """x_eq = m g / k (θ = 0)."""
        return self.value("mass") * self.value("gravity") / self.value("spring_constant")

    def radial_frequency(self) -> float:
        """ω_x = √(k/m)."""
        return math.sqrt(self.value("spring_constant") / self.value("mass"))

    def swing_frequency(self) -> float:
        """ω_θ = √(g / (l + mg/k))."""
        return math.sqrt(self.value("gravity")
                         / (self.value("length") + self.equilibrium_extension()))

    def vertical_solution(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """x(t), ẋ(t) when θ ≡ 0: SHM about mg/k at ω_x."""
        xe = self.equilibrium_extension()
        d, v = free_solution(t, self.value("initial.extension") - xe,
                             self.value("initial_rate.extension"), self.radial_frequency())
        return xe + d, v


MODEL = SpringPendulum
