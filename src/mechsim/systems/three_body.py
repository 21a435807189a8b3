"""The planar three-body problem, unrestricted: the circular restricted problem's third body given
a mass, so that it pulls the primaries back, and its Jacobi "constant" is no longer constant.

Source: “Action and Reaction” (blog post), Case 2 – Driving forces: the restricted model
conserves the Jacobi constant only because the primaries are driven along their circles,
"the conservation of the Jacobi constant is a useful tool but it does not actually occur in
nature. Rather a close approximation results". This system is that nature: three bodies under
their mutual gravity, L = Σ ½ m_i |ṙ_i|² + G m₁m₂/r₁₂ + G m₁m₃/r₁₃ + G m₂m₃/r₂₃, nothing
driven, so the total energy, momentum and angular momentum are conserved (checked laws).

Set-up (the ``cr3bp`` system's, so that the two can be compared): the primaries m₁, m₂ start on
the circular orbit of separation L about their barycentre, rate ω = √(G(m₁ + m₂)/L³), m₁ at
+(m₂/M)L x̂, m₂ at −(m₁/M)L x̂; the third body m₃ starts at ``initial.x``, ``initial.y`` with
velocity ``initial_rate.x``, ``initial_rate.y``; then the centre of mass of all three and its
velocity are removed from every body (the world origin is the fixed barycentre). As m₃ → 0
this is the restricted problem exactly.

Published for the third body (per unit mass, J/kg): ``jacobi`` J = ½|ṙ₃|² − G m₁/|r₃ − r₁|
− G m₂/|r₃ − r₂| − ω (x₃ẏ₃ − y₃ẋ₃), the restricted problem's integral evaluated on the real
motion, with the positions of the primaries as they are and ω of their initial orbit; and
``jacobi_rate``, its time derivative along the motion,

    dJ/dt = −Σ_k G m_k (r₃ − r_k)·(ṙ_k − ω ẑ × r_k)/|r₃ − r_k|³,

which shows why J drifts: it vanishes when each primary moves exactly as a rigid rotation
about the origin at ω (the restricted problem), and here the third body's pull makes the
primaries depart from that rotation (their barycentre wobbles about the fixed one, their orbit
is no longer a circle at ω) by O(m₃/(m₁ + m₂)). The drift of J is therefore first order in
m₃ (the tests measure it so) and is not a numerical error: the diagnostics node checks E, P and
L, not J. C_J = −2J is published as ``jacobi_constant``.
Conventions: REP-103 axes, motion in the plane z = 0, SI units (G in m³/(kg s²)).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class ThreeBody(LagrangianModel):
    id = "three_body"
    title = "Planar three-body problem (the CR3BP's third body given a mass; Jacobi drift)"
    source = ("“Action and Reaction” (blog post), Case 2 – Driving forces (the Jacobi "
              "constant is only approximately conserved in nature)")
    oracles = ("E, P, L conserved; m₃ → 0: the third body follows the restricted problem "
               "(scipy); Jacobi drift first order in m₃, dJ/dt formula = d/dt of J; scipy "
               "three-body integration")
    parameters = (
        positive("gravitational_constant", 1.0, "m^3/(kg s^2)", "gravitational constant G"),
        positive("primary_mass", 0.9, "kg", "mass m₁ of the first primary"),
        positive("secondary_mass", 0.1, "kg", "mass m₂ of the second primary"),
        positive("third_mass", 0.01, "kg", "mass m₃ of the third body (0 would be the CR3BP)"),
        positive("separation", 1.0, "m", "initial distance L between the primaries"),
        number("initial.x", 0.5, "m", "initial x of the third body (before the barycentre "
               "shift)"),
        number("initial.y", 0.0, "m", "initial y of the third body"),
        number("initial_rate.x", 0.0, "m/s", "initial ẋ of the third body"),
        number("initial_rate.y", 0.9, "m/s", "initial ẏ of the third body"),
    )

    def check(self) -> None:
        r = np.array([self.value("initial.x"), self.value("initial.y")])
        L = self.value("separation")
        m1, m2 = self.value("primary_mass"), self.value("secondary_mass")
        for name, p in (("primary", m2 / (m1 + m2) * L), ("secondary", -m1 / (m1 + m2) * L)):
            if math.hypot(r[0] - p, r[1]) < 1e-6 * L:
                raise ParameterError("initial.x", f"the third body starts on the {name}")

    def rotation_rate(self) -> float:
        """ω = √(G(m₁ + m₂)/L³) of the primaries' initial circular orbit."""
        return math.sqrt(self.value("gravitational_constant") * (
            self.value("primary_mass") + self.value("secondary_mass"))
            / self.value("separation") ** 3)

    def declare(self, b: LagrangianBuilder) -> None:
        G = b.param("gravitational_constant")
        m = (b.param("primary_mass"), b.param("secondary_mass"), b.param("third_mass"))
        w = sp.sqrt(G * (m[0] + m[1]) / b.param("separation") ** 3)
        pos, vel = [], []
        for i in range(3):
            x, dx = b.coordinate(f"x_{i + 1}", "m")
            y, dy = b.coordinate(f"y_{i + 1}", "m")
            pos.append((x, y))
            vel.append((dx, dy))
        dist = {}
        for i, j in ((0, 1), (0, 2), (1, 2)):
            dist[i, j] = sp.sqrt((pos[i][0] - pos[j][0]) ** 2 + (pos[i][1] - pos[j][1]) ** 2)
        b.kinetic = sum(m[i] * (vel[i][0] ** 2 + vel[i][1] ** 2) for i in range(3)) / 2
        b.potential = -G * sum(m[i] * m[j] / d for (i, j), d in dist.items())
        b.invariant("momentum_x", "kg m/s", sum(m[i] * vel[i][0] for i in range(3)))
        b.invariant("momentum_y", "kg m/s", sum(m[i] * vel[i][1] for i in range(3)))
        b.invariant("angular_momentum", "kg m^2/s", sum(
            m[i] * (pos[i][0] * vel[i][1] - pos[i][1] * vel[i][0]) for i in range(3)))
        (x3, y3), (vx3, vy3) = pos[2], vel[2]
        J = (vx3**2 + vy3**2) / 2 - G * m[0] / dist[0, 2] - G * m[1] / dist[1, 2] \
            - w * (x3 * vy3 - y3 * vx3)
        rate = -sum(G * m[k] * ((x3 - pos[k][0]) * (vel[k][0] + w * pos[k][1])
                               + (y3 - pos[k][1]) * (vel[k][1] - w * pos[k][0]))
                   / dist[k, 2] ** 3 for k in (0, 1))
        b.observable("jacobi", "J/kg", J)
        b.observable("jacobi_constant", "m^2/s^2", -2 * J)
        b.observable("jacobi_rate", "W/kg", rate)
        b.observable("primary_separation", "m", dist[0, 1])
        for i in range(3):
            b.frame(f"body_{i + 1}", "world", (pos[i][0], pos[i][1], 0))
        b.frame("synodic", "world", (0, 0, 0), (0, 0, sp.sin(w * b.t / 2), sp.cos(w * b.t / 2)))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        L = self.value("separation")
        m = np.array([self.value("primary_mass"), self.value("secondary_mass"),
                      self.value("third_mass")])
        w = self.rotation_rate()
        M12 = m[0] + m[1]
        r = np.array([[m[1] / M12 * L, 0.0], [-m[0] / M12 * L, 0.0],
                      [self.value("initial.x"), self.value("initial.y")]])
        v = np.array([[0.0, w * r[0, 0]], [0.0, w * r[1, 0]],
                      [self.value("initial_rate.x"), self.value("initial_rate.y")]])
        r -= (m @ r) / m.sum()
        v -= (m @ v) / m.sum()
        return r.ravel(), v.ravel()

    def time_scale(self) -> float:
        return 2 * math.pi / self.rotation_rate()

    def law_scales(self) -> dict[str, float]:
        """The total momentum and angular momentum start at zero up to round-off (the
        barycentre is removed): their drifts are measured against the sums of the bodies'
        own magnitudes, Σ m|v| and Σ m|r × v|, not against that round-off."""
        scales = super().law_scales()
        r, v = (a.reshape(3, 2) for a in self.initial_state())
        m = np.array([self.value("primary_mass"), self.value("secondary_mass"),
                      self.value("third_mass")])
        p = float(m @ np.hypot(v[:, 0], v[:, 1]))
        lz = float(m @ np.abs(r[:, 0] * v[:, 1] - r[:, 1] * v[:, 0]))
        scales.update({"invariant:momentum_x": p, "invariant:momentum_y": p,
                       "invariant:angular_momentum": lz})
        return scales

    def visuals(self) -> tuple[Visual, ...]:
        L = self.value("separation")
        return (Visual("axes", "synodic", radius=0.3 * L),
                Visual("sphere", "body_1", radius=0.06 * L, color=(255, 200, 80)),
                Visual("sphere", "body_2", radius=0.035 * L, color=(120, 170, 255)),
                Visual("sphere", "body_3", radius=0.015 * L),
                Visual("trail", "body_1", color=(255, 200, 80)),
                Visual("trail", "body_2", color=(120, 170, 255)),
                Visual("trail", "body_3", color=(200, 200, 200)))


MODEL = ThreeBody
