"""Free particle constrained to a surface: geodesics on a sphere, a cylinder or a cone.

Source: PHYS0500 ch. 2 (§2.2, line 393: the geodesic, "the shortest path on a given surface"),
made simulable as the catalog suggests (003 §10): a free particle held on the surface by a
holonomic constraint with a Lagrange multiplier (§3.4) moves along geodesics at constant speed.

Conventions: Cartesian (x, y, z) in the ``surface`` frame, z along the symmetry axis (REP-103).
Surfaces, each written as g = 0 with |∇g| = 1 so that λ is the normal force (outward positive):
sphere |r| − R, cylinder ρ − R, cone ρ cos α − z sin α (apex at the origin, half-angle α,
opening upward; ρ = √(x² + y²)). No gravity, V = 0. Initial conditions: a point at height
``initial.height`` and azimuth ``initial.azimuth`` on the surface, speed ``initial.speed`` and
heading ψ (``initial.heading``) measured from the parallel (increasing φ) towards increasing
z along the surface.

Invariants: Clairaut's ρ²φ̇ = x ẏ − y ẋ (ρ cos ψ · speed: every surface of revolution); the
sphere's whole angular momentum (x, y components too: the path is a great circle); the
cylinder's axial velocity ż (a helix). The speed is conserved through the energy law (T only).
Oracles: great circle in the plane ⟂ L, normal force −m v²/R on the sphere; helix on the
cylinder with normal force −m (v cos ψ)²/R; on the cone the distance from the apex obeys
|r|² = |r₀|² + 2 r₀·v₀ t + v² t² (a straight line on the unrolled cone).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

SURFACES = ("sphere", "cylinder", "cone")


class Geodesic(LagrangianModel):
    id = "geodesic"
    title = "Geodesics: free particle on a sphere, cylinder or cone (Lagrange multiplier)"
    source = ("PHYS0500 – Advanced Classical Mechanics, §2.2 (Euler's Equation: geodesics), with "
              "the multipliers of §3.4")
    oracles = ("constant speed, great circle (L fixed), helix, cone |r|² quadratic in t, "
               "Clairaut ρ²φ̇, normal force −mv²/R, constraint residual at round-off")
    parameters = (
        Parameter("surface", "sphere", "", "surface the particle is held on", choices=SURFACES),
        positive("mass", 1.0, "kg", "particle mass m"),
        positive("radius", 1.0, "m", "radius R of the sphere or cylinder"),
        Parameter("half_angle", 0.5, "rad", "cone half-angle α", minimum=0.0,
                  maximum=math.pi / 2, exclusive_minimum=True, exclusive_maximum=True),
        number("initial.height", 0.3, "m", "initial height z on the surface (cone: > 0)"),
        number("initial.azimuth", 0.0, "rad", "initial azimuth φ"),
        positive("initial.speed", 1.0, "m/s", "speed v (conserved)"),
        number("initial.heading", 0.6, "rad", "heading ψ from the parallel towards +z"),
    )

    @property
    def surface(self) -> str:
        return str(self.values["surface"])

    def check(self) -> None:
        z0, R = self.value("initial.height"), self.value("radius")
        if self.surface == "sphere" and not abs(z0) < R:
            raise ParameterError("initial.height", f"must be inside (−R, R) = ({-R:g}, {R:g}) "
                                 f"on the sphere (got {z0:g})")
        if self.surface == "cone":
            if not z0 > 0:
                raise ParameterError("initial.height", f"must be > 0 on the cone (got {z0:g})")
            psi = self.value("initial.heading")
            if abs(math.cos(psi)) < 1e-9 and math.sin(psi) < 0:
                raise ParameterError("initial.heading", "straight down a generator runs into "
                                     "the apex: tilt the heading")

    def declare(self, b: LagrangianBuilder) -> None:
        m = b.param("mass")
        x, dx = b.coordinate("x", "m")
        y, dy = b.coordinate("y", "m")
        z, dz = b.coordinate("z", "m")
        b.kinetic = m * (dx**2 + dy**2 + dz**2) / 2
        rho = sp.sqrt(x**2 + y**2)
        if self.surface == "sphere":
            b.constraint("surface", sp.sqrt(x**2 + y**2 + z**2) - b.param("radius"))
        elif self.surface == "cylinder":
            b.constraint("surface", rho - b.param("radius"))
        else:
            al = b.param("half_angle")
            b.constraint("surface", rho * sp.cos(al) - z * sp.sin(al))
        b.invariant("clairaut", "m^2/s", x * dy - y * dx)
        if self.surface == "sphere":
            b.invariant("angular_momentum_x", "kg m^2/s", m * (y * dz - z * dy))
            b.invariant("angular_momentum_y", "kg m^2/s", m * (z * dx - x * dz))
        elif self.surface == "cylinder":
            b.invariant("axial_velocity", "m/s", dz)
        b.observable("normal_force", "N", b.multiplier(0))
        b.observable("speed", "m/s", sp.sqrt(dx**2 + dy**2 + dz**2))
        b.observable("axis_distance", "m", rho)
        b.frame("surface", "world", (0, 0, 0))
        b.frame("particle", "surface", (x, y, z))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        z0, phi = self.value("initial.height"), self.value("initial.azimuth")
        v, psi = self.value("initial.speed"), self.value("initial.heading")
        R = self.value("radius")
        if self.surface == "sphere":
            rho = math.sqrt(R * R - z0 * z0)
            up = np.array([-z0 / R * math.cos(phi), -z0 / R * math.sin(phi), rho / R])
        elif self.surface == "cylinder":
            rho = R
            up = np.array([0.0, 0.0, 1.0])
        else:
            al = self.value("half_angle")
            rho = z0 * math.tan(al)
            up = np.array([math.sin(al) * math.cos(phi), math.sin(al) * math.sin(phi),
                           math.cos(al)])
        along = np.array([-math.sin(phi), math.cos(phi), 0.0])
        q = np.array([rho * math.cos(phi), rho * math.sin(phi), z0])
        return q, v * (math.cos(psi) * along + math.sin(psi) * up)

    def time_scale(self) -> float:
        R = self.value("radius") if self.surface != "cone" else (
            self.value("initial.height") * math.tan(self.value("half_angle")))
        return 2 * math.pi * R / self.value("initial.speed")

    def visuals(self) -> tuple[Visual, ...]:
        R = self.value("radius")
        ts = np.linspace(0, 2 * math.pi, 73)
        lines: list[tuple[tuple[float, float, float], ...]] = []
        if self.surface == "sphere":
            for k in range(6):
                a = k * math.pi / 6
                lines.append(tuple((R * math.sin(t) * math.cos(a), R * math.sin(t) * math.sin(a),
                                    R * math.cos(t)) for t in ts))
            lines.append(tuple((R * math.cos(t), R * math.sin(t), 0.0) for t in ts))
        else:
            h = 2 * abs(self.value("initial.height")) + 1.0
            if self.surface == "cylinder":
                levels = [(-h, R), (0.0, R), (h, R)]
            else:
                ta = math.tan(self.value("half_angle"))
                levels = [(z, z * ta) for z in (h / 3, 2 * h / 3, h)]
            for z, r in levels:
                lines.append(tuple((r * math.cos(t), r * math.sin(t), z) for t in ts))
            for k in range(8):
                a = k * math.pi / 4
                z_lo, r_lo = levels[0] if self.surface == "cylinder" else (0.0, 0.0)
                z_hi, r_hi = levels[-1]
                lines.append(((r_lo * math.cos(a), r_lo * math.sin(a), z_lo),
                              (r_hi * math.cos(a), r_hi * math.sin(a), z_hi)))
        out = [Visual("polyline", "surface", points=p, radius=0.005, color=(170, 170, 180))
               for p in lines]
        return (*out, Visual("sphere", "particle", radius=0.04, color=(230, 120, 60)),
                Visual("trail", "particle", color=(120, 170, 255)))


MODEL = Geodesic
