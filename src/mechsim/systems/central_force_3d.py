"""Central-force motion of a particle in three dimensions, in spherical coordinates.

Source: Lecture 10, "central force potential in spherical coordinates" (L121–124, eq. 10.19,
reconstructed in the catalog) on the spherical-coordinate Lagrangian of §2 (L102–106):
T = ½ m (ṙ² + r²θ̇² + r² sin²θ φ̇²), V = Ṽ(r), so that
m(r̈ − rθ̇² − r sin²θ φ̇²) = −dṼ/dr, d/dt(mr²θ̇) − mr² sinθ cosθ φ̇² = 0 and
d/dt(mr² sin²θ φ̇) = 0 — "the conservation of the z component of angular momentum" (L124).
The whole vector L = m r × ṙ is conserved, so the orbit lies in the fixed plane normal to L
(catalog [DERIVED]); for Ṽ = −k/r the Laplace–Runge–Lenz vector A = m ṙ × L − m k r̂ is
conserved too (it points to the periapsis; catalog supplement). In that plane the motion is the
planar problem of ``central_force`` (PHYS0500 ch. 4) turned by a rotation.

``potential``: ``kepler`` Ṽ = −k/r (``force_constant``) or ``harmonic`` Ṽ = ½ k r²
(``spring_constant``; then each Cartesian energy ½mẋᵢ² + ½kxᵢ² is conserved as well).

Formulations: ``spherical`` (r, θ, φ), the document's; ``cartesian`` (x, y, z), the same motion
without the coordinate singularity. Spherical coordinates are singular on the z axis
(sin θ = 0): an orbit whose plane is inclined by i reaches θ = 90° ± i, so the spherical form
refuses orbits that come within 5° of a pole (use the cartesian form there).

Conventions: REP-103 world axes, z up, the force centre at the origin of the static frame
``centre``; θ is the polar angle from +z, φ the azimuth from +x toward +y (right-handed),
x = r sinθ cosφ, y = r sinθ sinφ, z = r cosθ (Introduction to analytical mechanics L73–77). Frames:
``particle`` (position; axes of the local basis: x = θ̂, y = φ̂, z = r̂, i.e. R_z(φ)R_y(θ), catalog
002 §2) and ``orbit`` (z along L, x toward periapsis along A for −k/r, along the ascending node
otherwise).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, number, positive
from mechsim.systems._central import (
    declare_orbit_vectors,
    kepler_elements,
    orbit_quaternion,
    pericentre_time,
    vector_law_scales,
)
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

POTENTIALS = ("kepler", "harmonic")
POLE_MARGIN = math.radians(5.0)


class CentralForce3D(LagrangianModel):
    id = "central_force_3d"
    title = "Central-force motion in three dimensions (spherical coordinates)"
    source = ("Lecture 10: The Methods of Lagrange Revisited, central force in spherical "
              "coordinates (eqs. 10.14–10.19); Introduction to analytical mechanics, “Generalized "
              "coordinates” (spherical polar coordinates)")
    formulations = ("spherical", "cartesian")
    oracles = ("orbit in the plane ⟂ L; vector L (p_φ = mr²sin²θφ̇ = L_z) and LRL A conserved; "
               "apsides a(1 ± e), period 2π√(ma³/k); equals the planar central_force turned by "
               "a rotation; harmonic: SHM per axis at √(k/m); forms agree")
    parameters = (
        Parameter("potential", "kepler", "", "central potential Ṽ(r)", choices=POTENTIALS),
        positive("mass", 1.0, "kg", "mass m of the particle"),
        positive("force_constant", 1.0, "N m^2", "k of Ṽ = −k/r (kepler)"),
        positive("spring_constant", 1.0, "N/m", "k of Ṽ = ½kr² (harmonic)"),
        positive("initial.r", 1.0, "m", "initial distance r from the centre"),
        Parameter("initial.theta", math.pi / 2, "rad", "initial polar angle θ from +z",
                  minimum=0.0, maximum=math.pi, exclusive_minimum=True,
                  exclusive_maximum=True),
        number("initial.phi", 0.0, "rad", "initial azimuth φ from +x"),
        number("initial_rate.r", 0.0, "m/s", "initial ṙ"),
        number("initial_rate.theta", 0.5, "rad/s", "initial θ̇"),
        number("initial_rate.phi", 1.0, "rad/s", "initial φ̇"),
    )

    @property
    def potential_name(self) -> str:
        return str(self.values["potential"])

    def check(self) -> None:
        r, v = self.cartesian_state()
        if not np.any(np.cross(r, v)):
            raise ParameterError("initial_rate.theta", "the velocity is radial (L = 0): the "
                                 "particle falls through the centre; give it angular momentum")
        if self.formulation == "spherical" and self.pole_distance() < POLE_MARGIN:
            raise ParameterError(
                "formulation", f"the orbit passes within {math.degrees(self.pole_distance()):.3g}"
                f"° of the z axis, where spherical coordinates are singular (limit "
                f"{math.degrees(POLE_MARGIN):g}°): use formulation: cartesian")

    def _V(self, b: LagrangianBuilder, r: sp.Expr) -> sp.Expr:
        if self.potential_name == "kepler":
            return -b.param("force_constant") / r
        return b.param("spring_constant") * r**2 / 2

    def declare(self, b: LagrangianBuilder) -> None:
        m = b.param("mass")
        if self.formulation == "spherical":
            r, dr = b.coordinate("r", "m")
            th, dth = b.coordinate("theta", "rad")
            ph, dph = b.coordinate("phi", "rad")
            b.kinetic = m * (dr**2 + r**2 * dth**2 + r**2 * sp.sin(th) ** 2 * dph**2) / 2
            pos = (r * sp.sin(th) * sp.cos(ph), r * sp.sin(th) * sp.sin(ph), r * sp.cos(th))
            vel = tuple(sum(sp.diff(c, q) * dq for q, dq in ((r, dr), (th, dth), (ph, dph)))
                        for c in pos)
            radius = r
            b.observable("p_phi", "kg m^2/s", m * r**2 * sp.sin(th) ** 2 * dph)
        else:
            pos, vel = zip(*(b.coordinate(c, "m") for c in "xyz"), strict=True)
            b.kinetic = m * sum(c**2 for c in vel) / 2
            radius = sp.sqrt(sum(c**2 for c in pos))
            th = sp.acos(pos[2] / radius)
            ph = sp.atan2(pos[1], pos[0])
        b.potential = self._V(b, radius)
        k = b.param("force_constant") if self.potential_name == "kepler" else None
        L, A = declare_orbit_vectors(b, m, pos, vel, k)
        if self.potential_name == "harmonic":
            ks = b.param("spring_constant")
            for axis, x, v in zip("xyz", pos, vel, strict=True):
                b.invariant(f"energy_{axis}", "J", m * v**2 / 2 + ks * x**2 / 2)
        b.observable("radius", "m", radius)
        b.observable("inclination", "rad",
                     sp.atan2(sp.sqrt(L[0] ** 2 + L[1] ** 2), L[2]))
        b.frame("centre", "world", (0, 0, 0))
        sth, cth = sp.sin(th / 2), sp.cos(th / 2)
        sph, cph = sp.sin(ph / 2), sp.cos(ph / 2)
        b.frame("particle", "centre", pos, (-sph * sth, cph * sth, sph * cth, cph * cth))
        b.frame("orbit", "centre", (0, 0, 0), orbit_quaternion(L, A))

    # --- state ----------------------------------------------------------------------------
    def spherical_state(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.array([self.value("initial.r"), self.value("initial.theta"),
                          self.value("initial.phi")]),
                np.array([self.value("initial_rate.r"), self.value("initial_rate.theta"),
                          self.value("initial_rate.phi")]))

    def cartesian_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Initial position and velocity in the ``centre`` frame."""
        (r, th, ph), (dr, dth, dph) = self.spherical_state()
        st, ct, sp_, cp = math.sin(th), math.cos(th), math.sin(ph), math.cos(ph)
        rhat = np.array([st * cp, st * sp_, ct])
        that = np.array([ct * cp, ct * sp_, -st])
        phat = np.array([-sp_, cp, 0.0])
        return r * rhat, dr * rhat + r * dth * that + r * st * dph * phat

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.spherical_state() if self.formulation == "spherical" \
            else self.cartesian_state()

    def visuals(self) -> tuple[Visual, ...]:
        r0 = self.value("initial.r")
        return (Visual("sphere", "centre", radius=0.08 * r0, color=(255, 200, 80)),
                Visual("sphere", "particle", radius=0.04 * r0, color=(120, 170, 255)),
                Visual("trail", "particle", color=(120, 170, 255)),
                Visual("axes", "particle", radius=0.15 * r0),
                Visual("axes", "orbit", radius=0.4 * r0))

    def law_scales(self) -> dict[str, float]:
        """Components of L against |L|, of A against mk, per-axis energies against
        |T₀| + |V₀|."""
        return vector_law_scales(super().law_scales(),
                                 float(np.linalg.norm(self.angular_momentum())),
                                 self.value("mass") * self.value("force_constant"),
                                 self.energy_scale())

    def time_scale(self) -> float:
        m = self.value("mass")
        if self.potential_name == "harmonic":
            return 2 * math.pi * math.sqrt(m / self.value("spring_constant"))
        r, v = self.cartesian_state()
        return pericentre_time(self.value("force_constant") / m, r, v)

    # --- analytic oracles ------------------------------------------------------------------
    def angular_momentum(self) -> np.ndarray:
        """L = m r × ṙ (constant)."""
        r, v = self.cartesian_state()
        return self.value("mass") * np.cross(r, v)

    def inclination(self) -> float:
        """Angle of L from +z: the orbit plane's tilt from the x–y plane."""
        L = self.angular_momentum()
        return math.atan2(math.hypot(L[0], L[1]), L[2])

    def pole_distance(self) -> float:
        """Smallest polar distance min(θ, π − θ) on the orbit: 90° − i for i ≤ 90°."""
        return abs(math.pi / 2 - self.inclination())

    def potential_function(self) -> Callable[[float], float]:
        if self.potential_name == "kepler":
            k = self.value("force_constant")
            return lambda r: -k / r
        ks = self.value("spring_constant")
        return lambda r: 0.5 * ks * r * r

    def energy(self) -> float:
        r, v = self.cartesian_state()
        return 0.5 * self.value("mass") * float(v @ v) + self.potential_function()(
            float(np.linalg.norm(r)))

    def kepler_elements(self) -> dict[str, float]:
        """−k/r: ε, semi-latus rectum, r_min, r_max, a, period (see ``_central``)."""
        return kepler_elements(self.value("mass"), self.value("force_constant"), self.energy(),
                               float(np.linalg.norm(self.angular_momentum())))


MODEL = CentralForce3D
