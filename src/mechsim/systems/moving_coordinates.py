"""Free particle described in inertial, Galilean (co-moving) and uniformly accelerating
coordinates: how E and h depend on the choice of coordinates.

Sources: “Energy and Hamiltonians: Part 3 – Examples” ("Case 1 – E ≠ h, both conserved", L358–395)
and ("Case 2 – E ≠ h, E conserved", L397–414); Lecture 10, linearly accelerated frame (eq. 10.24)
(particle in a linearly accelerated frame, L159–163, eq. 10.24 reconstructed in the catalog).

Formulations (one coordinate each; all describe the same inertial motion x = x₀ + v₀t):
- ``inertial``: x, L = ½ m ẋ²; E = h = ½ m v₀².
- ``galilean``: q with x = q + u t (frame velocity ``frame_velocity`` u), L = ½ m (q̇ + u)²;
  h_q = ½ m q̇² − ½ m u² is conserved but ≠ E. The document's case is u = v₀ (co-moving):
  q ≡ x₀ and h_q = −½ m v₀².
- ``accelerating``: q with x = q + ½ a t² (``frame_acceleration`` a, frame at rest at t = 0),
  L = ½ m (q̇ + a t)²; m q̈ = −m a (the inertial force of 002 §4); E = ½ m v₀² is conserved,
  h_q = ½ m q̇² − ½ m a² t² = ½ m v₀² − m a v₀ t is not (dh/dt = −∂L/∂t). The gauge-equivalent
  L′ = ½ m q̇² − m a q (002 §4: L differs from it by a total time derivative) has the
  conserved h′ = ½ m q̇² + m a q, published as the invariant ``gauge_energy_function``.

Frames: the moving coordinates' frame ``moving_frame`` is a child of ``world`` translating along
x (X(t) = u t or ½ a t²), and ``particle`` is a child of it at (q, 0, 0); in the inertial form
``particle`` is a child of ``world``. Initial conditions are always the inertial x₀ = ``initial.x``
and v₀ = ``initial_rate.x``.

Document typo corrected (catalog 000 S4, pitfall 9): L395 says "q = v₀ and so h_q = 0"; in fact
q̇ = 0 (q = x₀) and h_q = −½ m v₀², constant but not zero.
"""

from __future__ import annotations

import numpy as np

from mechsim.params import number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Law, Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class MovingCoordinates(LagrangianModel):
    id = "moving_coordinates"
    title = "Free particle in inertial, Galilean and accelerating coordinates"
    source = ("“Energy and Hamiltonians: Part 3 – Examples” (blog post), Cases 1–2; Lecture 10: "
              "The Methods of Lagrange Revisited, linearly accelerated frame (eq. 10.24)")
    formulations = ("inertial", "galilean", "accelerating")
    oracles = ("x = x₀ + v₀t in every form; Galilean h_q = ½mq̇² − ½mu² (= −½mv₀² co-moving); "
               "accelerating: E = ½mv₀² constant, h_q = ½mv₀² − mav₀t, h′ = ½mq̇² + maq")
    parameters = (
        positive("mass", 1.0, "kg", "particle mass m"),
        number("frame_velocity", 1.0, "m/s", "velocity u of the Galilean frame (x = q + u t)"),
        number("frame_acceleration", 0.5, "m/s^2",
               "acceleration a of the accelerating frame (x = q + ½ a t²)"),
        number("initial.x", 0.0, "m", "inertial initial position x₀"),
        number("initial_rate.x", 1.0, "m/s", "inertial initial velocity v₀"),
    )

    def frame_origin(self, b: LagrangianBuilder) -> sp.Expr:
        """X(t), the moving frame's origin on the world x axis."""
        if self.formulation == "galilean":
            return b.param("frame_velocity") * b.t
        if self.formulation == "accelerating":
            return b.param("frame_acceleration") * b.t**2 / 2
        return sp.Integer(0)

    def declare(self, b: LagrangianBuilder) -> None:
        m = b.param("mass")
        if self.formulation == "inertial":
            x, dx = b.coordinate("x", "m")
            b.kinetic = m * dx**2 / 2
            b.frame("particle", "world", (x, 0, 0))
            return
        q, dq = b.coordinate("q", "m")
        X = self.frame_origin(b)
        Xd = sp.diff(X, b.t)
        b.kinetic = m * (dq + Xd) ** 2 / 2
        if self.formulation == "accelerating":
            a = b.param("frame_acceleration")
            b.invariant("gauge_energy_function", "J", m * dq**2 / 2 + m * a * q)
        b.observable("inertial_position", "m", q + X)
        b.observable("inertial_velocity", "m/s", dq + Xd)
        b.observable("frame_position", "m", X)
        b.observable("frame_velocity", "m/s", Xd)
        b.frame("moving_frame", "world", (X, 0, 0))
        b.frame("particle", "moving_frame", (q, 0, 0))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        x0, v0 = self.value("initial.x"), self.value("initial_rate.x")
        if self.formulation == "galilean":
            v0 -= self.value("frame_velocity")
        return np.array([x0]), np.array([v0])  # X(0) = 0 and, accelerating, Ẋ(0) = 0

    def laws(self) -> tuple[Law, ...]:
        laws = super().laws()
        if self.formulation == "accelerating":  # T depends on t, yet E is conserved (Case 2)
            laws = (Law("energy", "energy"),) + laws
        return laws

    def visuals(self) -> tuple[Visual, ...]:
        out = [Visual("sphere", "particle", radius=0.08),
               Visual("trail", "particle", color=(120, 170, 255))]
        if self.formulation != "inertial":
            out += [Visual("axes", "moving_frame", radius=0.4),
                    Visual("box", "moving_frame", size=(0.3, 0.3, 0.02), color=(90, 90, 160))]
        return tuple(out)

    def time_scale(self) -> float:
        return 1.0

    # --- analytic oracles (“Energy and Hamiltonians: Part 3 – Examples”, Cases 1–2, corrected) ----
    def energy(self) -> float:
        """E = ½ m v₀² in every formulation."""
        return 0.5 * self.value("mass") * self.value("initial_rate.x") ** 2

    def inertial_position(self, t: np.ndarray) -> np.ndarray:
        return self.value("initial.x") + self.value("initial_rate.x") * np.asarray(t, float)

    def energy_function(self, t: np.ndarray) -> np.ndarray:
        """h of the formulation's coordinate along the motion."""
        t = np.asarray(t, dtype=float)
        m, v0 = self.value("mass"), self.value("initial_rate.x")
        if self.formulation == "galilean":
            u = self.value("frame_velocity")
            return 0.5 * m * (v0 - u) ** 2 - 0.5 * m * u**2 + 0 * t
        if self.formulation == "accelerating":
            return 0.5 * m * v0**2 - m * self.value("frame_acceleration") * v0 * t
        return 0.5 * m * v0**2 + 0 * t


MODEL = MovingCoordinates
