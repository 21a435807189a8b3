"""Double pendulum with general masses and lengths: angle and multiplier formulations.

Source: Introduction to analytical mechanics, "Double pendulum" (L671–805; again L2064–2091 as the
cross-term example of "Small Oscillations"): absolute angles θ₁, θ₂ of two massless rods from the
downward vertical, point masses m₁, m₂,
T = ½ m₁ l₁² θ̇₁² + ½ m₂ (l₁² θ̇₁² + l₂² θ̇₂² + 2 l₁ l₂ θ̇₁ θ̇₂ cos(θ₁ − θ₂)),
V = m₁ g [l₁ + l₂ − l₁ cos θ₁] + m₂ g [l₁ + l₂ − (l₁ cos θ₁ + l₂ cos θ₂)] (zero at the lowest
possible position, as in the document).

Formulations:
- ``angles``: the document's (θ₁, θ₂).
- ``multiplier``: the bobs' Cartesian (y₁, z₁, y₂, z₂) with the rod constraints
  |p₁| − l₁ = 0, |p₂ − p₁| − l₂ = 0; λ_k = −(tension of rod k).
Both publish the rod tensions ``tension_1``, ``tension_2`` (in the angle form from the
accelerations: T₂ = m₂ (a₂ − g)·(p₁ − p₂)/l₂, T₁ = (m₁ (a₁ − g) − T₂ (p₂ − p₁)/l₂)·(−p₁/l₁)).

Conventions: the document's axes are x down, y horizontal; here (REP-103, z up) the pendulum
swings in the y–z plane of the ``pivot`` frame, θ is a right-handed rotation about +x from
straight down: p₁ = l₁ (sin θ₁, −cos θ₁), p₂ = p₁ + l₂ (sin θ₂, −cos θ₂) in (y, z). Frames chain
``pivot`` (world) → ``bob_1`` (yaw-free rotation θ₁ about x) → ``bob_2`` (relative angle θ₂ − θ₁).

Document typos corrected (catalog 001 §2.3, §10 item 10): the second kinetic term uses m₂, not
m₁ (L691, L718, L2083); V's second term is −m₂ g[… cos θ₂] (L734); the equal-mass equation at
L767 has +l θ̇₂² sin(θ₁ − θ₂), not −, and 2l, not 2l₁ (checked with sympy in the tests);
L2079's velocity l₂ θ̇₂ cos θ₂. The engine derives the equations from L, so none can reach the
code. Small oscillations, equal masses and lengths: ω² = (2 ± √2) g/l, A₂ = ∓√2 A₁.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg

from mechsim.params import Parameter, nonnegative, number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


def _accel(p: sp.Matrix, q: list[sp.Symbol], v: list[sp.Symbol], a: list[sp.Symbol]) -> sp.Matrix:
    """Second time derivative of p(q): J a + Σ ∂²p/∂q_i∂q_j v_i v_j."""
    J = p.jacobian(q)
    return J * sp.Matrix(a) + (J * sp.Matrix(v)).jacobian(q) * sp.Matrix(v)


class DoublePendulum(LagrangianModel):
    id = "double_pendulum"
    title = "Double pendulum (angles and Lagrange-multiplier forms)"
    source = "Introduction to analytical mechanics, “Double pendulum” and “Small Oscillations”"
    formulations = ("angles", "multiplier", "hamiltonian")
    oracles = ("small-oscillation modes from |V − ω²T| = 0, (2 ± √2)g/l and A₂ = ∓√2A₁ for "
               "equal masses; E conserved over long chaotic runs; forms and tensions agree")
    parameters = (
        positive("mass_1", 1.0, "kg", "upper bob mass m₁"),
        positive("mass_2", 1.0, "kg", "lower bob mass m₂"),
        positive("length_1", 1.0, "m", "upper rod length l₁"),
        positive("length_2", 1.0, "m", "lower rod length l₂"),
        nonnegative("gravity", 9.81, "m/s^2", "gravitational acceleration g"),
        Parameter("initial.angle_1", 2.0, "rad", "initial θ₁ from straight down",
                  minimum=-math.pi, maximum=math.pi),
        Parameter("initial.angle_2", 2.5, "rad", "initial θ₂ from straight down (absolute)",
                  minimum=-math.pi, maximum=math.pi),
        number("initial_rate.angle_1", 0.0, "rad/s", "initial θ̇₁"),
        number("initial_rate.angle_2", 0.0, "rad/s", "initial θ̇₂"),
    )

    def declare(self, b: LagrangianBuilder) -> None:
        m1, m2 = b.param("mass_1"), b.param("mass_2")
        l1, l2, g = b.param("length_1"), b.param("length_2"), b.param("gravity")
        gvec = sp.Matrix([0, -g])
        if self.formulation == "angles":
            t1, d1 = b.coordinate("angle_1", "rad")
            t2, d2 = b.coordinate("angle_2", "rad")
            p1 = sp.Matrix([l1 * sp.sin(t1), -l1 * sp.cos(t1)])
            p2 = p1 + sp.Matrix([l2 * sp.sin(t2), -l2 * sp.cos(t2)])
            b.kinetic = (m1 * l1**2 * d1**2 / 2 + m2 * (l1**2 * d1**2 + l2**2 * d2**2 + 2 * l1
                                                        * l2 * d1 * d2 * sp.cos(t1 - t2)) / 2)
            b.potential = (m1 * g * (l1 + l2 - l1 * sp.cos(t1))
                           + m2 * g * (l1 + l2 - (l1 * sp.cos(t1) + l2 * sp.cos(t2))))
            a = [b.acceleration(t1), b.acceleration(t2)]
            a1 = _accel(p1, [t1, t2], [d1, d2], a)
            a2 = _accel(p2, [t1, t2], [d1, d2], a)
            u1, u2 = -p1 / l1, (p2 - p1) / l2
            T2 = (m2 * (a2 - gvec)).dot(-u2)
            T1 = (m1 * (a1 - gvec) - T2 * u2).dot(u1)
        else:
            y1, dy1 = b.coordinate("y_1", "m")
            z1, dz1 = b.coordinate("z_1", "m")
            y2, dy2 = b.coordinate("y_2", "m")
            z2, dz2 = b.coordinate("z_2", "m")
            b.kinetic = m1 * (dy1**2 + dz1**2) / 2 + m2 * (dy2**2 + dz2**2) / 2
            b.potential = m1 * g * (l1 + l2 + z1) + m2 * g * (l1 + l2 + z2)
            b.constraint("rod_1", sp.sqrt(y1**2 + z1**2) - l1)
            b.constraint("rod_2", sp.sqrt((y2 - y1) ** 2 + (z2 - z1) ** 2) - l2)
            T1, T2 = -b.multiplier(0), -b.multiplier(1)
            t1 = sp.atan2(y1, -z1)
            t2 = sp.atan2(y2 - y1, -(z2 - z1))
            b.observable("angle_1", "rad", t1)
            b.observable("angle_2", "rad", t2)
        b.observable("tension_1", "N", T1)
        b.observable("tension_2", "N", T2)
        d = t2 - t1
        b.frame("pivot", "world", (0, 0, 0))
        b.frame("bob_1", "pivot", (0, l1 * sp.sin(t1), -l1 * sp.cos(t1)),
                (sp.sin(t1 / 2), 0, 0, sp.cos(t1 / 2)))
        b.frame("bob_2", "bob_1", (0, l2 * sp.sin(d), -l2 * sp.cos(d)),
                (sp.sin(d / 2), 0, 0, sp.cos(d / 2)))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        t1, t2 = self.value("initial.angle_1"), self.value("initial.angle_2")
        w1, w2 = self.value("initial_rate.angle_1"), self.value("initial_rate.angle_2")
        if self.formulation == "angles":
            return np.array([t1, t2]), np.array([w1, w2])
        l1, l2 = self.value("length_1"), self.value("length_2")
        y1, z1 = l1 * math.sin(t1), -l1 * math.cos(t1)
        v1y, v1z = l1 * math.cos(t1) * w1, l1 * math.sin(t1) * w1
        return (np.array([y1, z1, y1 + l2 * math.sin(t2), z1 - l2 * math.cos(t2)]),
                np.array([v1y, v1z, v1y + l2 * math.cos(t2) * w2,
                          v1z + l2 * math.sin(t2) * w2]))

    def visuals(self) -> tuple[Visual, ...]:
        return (Visual("box", "pivot", size=(0.1, 0.1, 0.02), color=(150, 150, 150)),
                Visual("link", "pivot", to_frame="bob_1", radius=0.015),
                Visual("link", "bob_1", to_frame="bob_2", radius=0.015),
                Visual("sphere", "bob_1", radius=0.07, color=(230, 120, 90)),
                Visual("sphere", "bob_2", radius=0.07, color=(90, 160, 230)),
                Visual("trail", "bob_2", color=(120, 170, 255)))

    def time_scale(self) -> float:
        return 2 * math.pi / float(np.max(self.small_oscillation_frequencies()))

    # --- analytic oracles (Introduction to analytical mechanics, “Double pendulum” and “Small
    # Oscillations”)
    def small_oscillation_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """T and V of ½ q̇ᵀTq̇ + ½ qᵀVq about θ₁ = θ₂ = 0 (catalog 001 §2.3)."""
        m1, m2 = self.value("mass_1"), self.value("mass_2")
        l1, l2, g = self.value("length_1"), self.value("length_2"), self.value("gravity")
        T = np.array([[(m1 + m2) * l1**2, m2 * l1 * l2], [m2 * l1 * l2, m2 * l2**2]])
        V = np.diag([(m1 + m2) * g * l1, m2 * g * l2])
        return T, V

    def small_oscillation_frequencies(self) -> np.ndarray:
        """ω (ascending) from |V − ω²T| = 0; (2 ∓ √2) g/l for equal masses and lengths."""
        T, V = self.small_oscillation_matrices()
        return np.sqrt(np.maximum(scipy.linalg.eigh(V, T, eigvals_only=True), 0.0))

    def mode_ratios(self) -> np.ndarray:
        """A₂/A₁ of each mode (ascending frequency): +√2 (slow), −√2 (fast) for equal ones."""
        T, V = self.small_oscillation_matrices()
        _, vec = scipy.linalg.eigh(V, T)
        return vec[1] / vec[0]


MODEL = DoublePendulum
