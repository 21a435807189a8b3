"""A knife edge (skate) or Chaplygin sled on an inclined plane: a constraint on the velocities
that no constraint on the positions integrates to, with its multiplier the blade's lateral force.

Source: “Dynamical Systems and Constraints: Part 1 – General Theory” (constraints in
differential form, A_α dq_α + A dt = 0, and the multipliers they need, Y_α = Φ_α + Σ_k λ_k
A^(k)_α; the post prints q_α for dq_α and a + for the third −); Lecture 10: The Methods of
Lagrange Revisited, constraints and undetermined multipliers (eqs. 10.25–10.30: "even if the
constraint is nonholonomic ... we can still proceed"); PHYS0500 – Advanced Classical
Mechanics, §2.5 and §3.4 (Euler–Lagrange equations with undetermined multipliers). The
documents give the method and no such system; the sled is the standard example (Neimark and
Fufaev, Dynamics of Nonholonomic Systems, ch. I; Bloch, Nonholonomic Mechanics and Control,
§1.7).

Conventions: SI. The plane is the x–y plane of the static frame ``plane``, tilted about the
world y axis by the inclination α, so that +x points down the slope and gravity's component in
the plane is g sin α along +x (V = −m g sin α x; α = 0: a horizontal plane, z up). Coordinates:
the centre of mass (x, y) and the heading θ of the blade from +x. The blade touches the plane
at P, a distance a (``offset``) behind the centre of mass along the blade, and P cannot move
sideways:

    c = −ẋ sin θ + ẏ cos θ − a θ̇ = 0          (A = (−sin θ, cos θ, −a), b = 0),

which is not the time derivative of any relation among x, y, θ (x, y, θ all stay free: the
sled reaches every configuration). L = ½ m (ẋ² + ẏ²) + ½ I θ̇² + m g sin α x; the engine
derives M q̈ = f + Aᵀμ with μ from ċ = 0. μ is the force of the plane on the blade along
ê⊥ = (−sin θ, cos θ) (N: the generalized force Aᵀμ is μ ê⊥ on (x, y) and its moment −a μ on
θ), published as ``lateral_force``. With u = ẋ cos θ + ẏ sin θ (``forward_speed``) and
ω = θ̇ the equations reduce to the Chaplygin form

    u̇ = a ω² + g sin α cos θ,    (I + m a²) ω̇ = −m a (u ω + g sin α sin θ),
    μ = m (a ω̇ + u ω + g sin α sin θ).

The constraint is ideal and scleronomic (b = 0, no t): its force does no work, so
E = T + V is conserved. The momenta of the cyclic coordinates x and y are not (the blade
pushes sideways): the invariants Noether's theorem gives a holonomic system fail here. With
a = 0 the blade's force passes through the centre of mass and the ``spin`` I θ̇ is conserved;
with α = 0 and a = 0 the sled moves on a circle of radius u/ω at constant rates.

Initial conditions: position, heading, the forward speed u₀ and turn rate ω₀ (the rates
(ẋ, ẏ, θ̇) are made from them, so they satisfy c = 0).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.params import Parameter, nonnegative, number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class KnifeEdge(LagrangianModel):
    id = "knife_edge"
    title = "Knife edge or Chaplygin sled on an inclined plane (a velocity constraint)"
    source = ("“Dynamical Systems and Constraints: Part 1 – General Theory” (constraints in "
              "differential form and their multipliers); Lecture 10: The Methods of Lagrange "
              "Revisited, constraints and undetermined multipliers (eqs. 10.25–10.30); "
              "PHYS0500 – Advanced Classical Mechanics, §3.4 (E-L Equations with Undetermined "
              "Multipliers)")
    oracles = ("closed forms: a circle at constant rates (α = 0, a = 0), the drift on the "
               "slope (a = 0), tanh/sech speed and turn rate of the sled (α = 0); an "
               "independent integration of the Chaplygin equations; lateral force μ; energy "
               "conserved, momenta of the cyclic x, y not; constraint residual at round-off")
    parameters = (
        positive("mass", 1.0, "kg", "mass m of the sled"),
        positive("inertia", 0.05, "kg*m^2", "moment of inertia I about the vertical axis "
                 "through the centre of mass"),
        nonnegative("offset", 0.0, "m", "distance a of the contact point behind the centre of "
                    "mass along the blade (0: a knife edge, > 0: a Chaplygin sled)"),
        nonnegative("gravity", 9.81, "m/s^2", "gravitational acceleration g"),
        Parameter("inclination", 0.2, "rad", "inclination α of the plane (+x down the slope)",
                  minimum=0.0, maximum=math.pi / 2, exclusive_maximum=True),
        number("initial.x", 0.0, "m", "initial x of the centre of mass (down the slope)"),
        number("initial.y", 0.0, "m", "initial y of the centre of mass (across the slope)"),
        number("initial.heading", 0.0, "rad", "initial heading θ of the blade from +x"),
        number("initial.speed", 0.5, "m/s", "initial forward speed u₀ along the blade"),
        number("initial_rate.heading", 2.0, "rad/s", "initial turn rate ω₀ = θ̇"),
    )

    def declare(self, b: LagrangianBuilder) -> None:
        m, I, a = b.param("mass"), b.param("inertia"), b.param("offset")
        g, alpha = b.param("gravity"), b.param("inclination")
        x, dx = b.coordinate("x", "m")
        y, dy = b.coordinate("y", "m")
        th, w = b.coordinate("heading", "rad")
        c, s = sp.cos(th), sp.sin(th)
        b.kinetic = m * (dx**2 + dy**2) / 2 + I * w**2 / 2
        b.potential = -m * g * sp.sin(alpha) * x
        mu = b.velocity_constraint("no_side_slip", -dx * s + dy * c - a * w)
        b.observable("lateral_force", "N", mu)
        b.observable("forward_speed", "m/s", dx * c + dy * s)
        b.observable("momentum_x", "kg*m/s", m * dx)
        b.observable("momentum_y", "kg*m/s", m * dy)
        if self.value("offset") == 0:
            b.invariant("spin", "kg*m^2/s", I * w)
        b.frame("plane", "world", (0, 0, 0),
                (sp.Integer(0), sp.sin(alpha / 2), sp.Integer(0), sp.cos(alpha / 2)))
        b.frame("sled", "plane", (x, y, 0), (0, 0, sp.sin(th / 2), sp.cos(th / 2)))
        b.frame("contact", "plane", (x - a * c, y - a * s, 0))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        th, u = self.value("initial.heading"), self.value("initial.speed")
        w, a = self.value("initial_rate.heading"), self.value("offset")
        q = np.array([self.value("initial.x"), self.value("initial.y"), th])
        v = np.array([u * math.cos(th) - a * w * math.sin(th),
                      u * math.sin(th) + a * w * math.cos(th), w])
        return q, v

    def time_scale(self) -> float:
        w = abs(self.value("initial_rate.heading"))
        return 2 * math.pi / w if w > 0 else 1.0

    def visuals(self) -> tuple[Visual, ...]:
        return (Visual("box", "sled", size=(0.15, 0.01, 0.03), color=(200, 200, 220)),
                Visual("trail", "contact", color=(255, 170, 60)),
                Visual("trail", "sled", color=(120, 170, 255)))


MODEL = KnifeEdge
