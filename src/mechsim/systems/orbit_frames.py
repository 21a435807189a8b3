"""The VBN and RIC frames on a dynamical orbit: a body about a fixed centre, Kepler by default,
with an optional oblateness (J₂) term that makes the force non-central.

Sources: “Minimal Frames” (the astrodynamics frames VBN and RIC "that help in understanding the
motion of heavenly and man-made satellites", and which of them is minimal) and “Moving Frames
and the Twisted Cubic” (their derivatives and angular velocities), here on an orbit instead of a
prescribed curve; the orbit is that of Introduction to analytical mechanics, “Central force
problem – with two body”, and PHYS0500 – Advanced Classical Mechanics, §4.6 (the Kepler
problem), in Cartesian coordinates (the ``cartesian`` form of ``central_force_3d``):
L = ½ m |ṙ|² − V(r).

``perturbation``:
- ``none``: V = −k/r (``force_constant``; μ = k/m). The force is central, L = m r × ṙ and the
  Laplace–Runge–Lenz vector A = m ṙ × L − m k r̂ are conserved, the orbit plane is fixed and
  VBN is minimal (its ω lies along N̂), as is RIC.
- ``oblateness``: V = −(k/r) [1 − J₂ (R/r)² P₂(z/r)], P₂(s) = (3s² − 1)/2, the potential of a
  body oblate about z with equatorial radius R (``equatorial_radius``) to the J₂ term of the
  zonal expansion (not in the documents; the geopotential's first zonal harmonic, Montenbruck
  and Gill, Satellite Orbits, §3.2). Axisymmetric: the energy and L_z are conserved, L and A
  are not; on an inclined orbit the force has a component along the orbit normal, the plane
  precesses, and VBN turns about all three of its axes (not minimal) while RIC stays minimal.

Frames (the conventions of ``_moving_frame``; ω along the frame's own axes, ė = ω × e,
computed from the state and the accelerations the equations of motion give, so an applied
effort counts): ``centre`` (static, the force centre at the origin of ``world``), ``vbn`` and
``ric`` (children of ``centre`` at the body's position; REP-103 axes, SI units). Their
quaternions come from the axes by Shepperd's method (``_moving_frame.quaternion_from_axes``:
no angle of the orbit plane is formed, so equatorial, retrograde and polar orbits are as
accurate as any); they are undefined where r × v = 0 (a radial fall, refused at the start).

Observables: the six ω components and the two |ω| (``_moving_frame.omega_quantities``), the
radius, and ``normal_acceleration`` a·N̂: VBN is minimal exactly where it is zero.
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, number, positive
from mechsim.systems._central import declare_orbit_vectors, pericentre_time, vector_law_scales
from mechsim.systems._moving_frame import (
    FRAME_COLORS,
    frame_axes,
    frame_rates,
    omega_quantities,
    quaternion_from_axes,
)
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.declaration import LagrangianBuilder
from mechsim.systems.lagrangian import LagrangianModel

PERTURBATIONS = ("none", "oblateness")
FRAME_NAMES = ("vbn", "ric")
#: Default initial velocity: 1.1 times the circular speed at r = 1 m (k = m = 1), inclined 30°.
_SPEED, _INCLINATION = 1.1, math.radians(30.0)


class OrbitFrames(LagrangianModel):
    id = "orbit_frames"
    title = "VBN and RIC frames on an orbit (Kepler, or with an oblate body's J₂)"
    source = ("“Minimal Frames” (VBN, RIC, minimal frames in astrodynamics) and “Moving Frames "
              "and the Twisted Cubic” (their angular velocities); Introduction to analytical "
              "mechanics, “Central force problem – with two body”; PHYS0500 §4.6")
    oracles = ("circular orbit: R̂, Î, Ĉ turn at the mean motion n, ω_RIC = n Ĉ, ω_VBN = n N̂; "
               "ω from central differences of the published frames; VBN minimal under a "
               "central force, not with J₂ on an inclined orbit; RIC ω_y ≡ 0; L and A "
               "(Kepler), E and L_z (J₂) conserved")
    parameters = (
        Parameter("perturbation", "none", "", "force besides −k/r: none (central) or "
                  "oblateness (J₂ of a body oblate about z)", choices=PERTURBATIONS),
        positive("mass", 1.0, "kg", "mass m of the body"),
        positive("force_constant", 1.0, "N m^2", "k of V = −k/r (k = G M m)"),
        Parameter("j2", 0.05, "", "oblateness coefficient J₂ (perturbation: oblateness; "
                  "the Earth's is 1.08e-3)", minimum=-1.0, maximum=1.0),
        positive("equatorial_radius", 0.8, "m", "equatorial radius R of the oblate body"),
        number("initial.x", 1.0, "m", "initial position x"),
        number("initial.y", 0.0, "m", "initial position y"),
        number("initial.z", 0.0, "m", "initial position z"),
        number("initial_rate.x", 0.0, "m/s", "initial velocity ẋ"),
        number("initial_rate.y", _SPEED * math.cos(_INCLINATION), "m/s", "initial velocity ẏ"),
        number("initial_rate.z", _SPEED * math.sin(_INCLINATION), "m/s", "initial velocity ż"),
    )

    @property
    def perturbation(self) -> str:
        return str(self.values["perturbation"])

    def check(self) -> None:
        r, v = self.cartesian_state()
        if not np.any(r):
            raise ParameterError("initial.x", "the body starts at the force centre")
        if not np.any(np.cross(r, v)):
            raise ParameterError("initial_rate.x", "the velocity is radial (r × v = 0): the "
                                 "body falls through the centre and its frames are undefined; "
                                 "give it angular momentum")

    def declare(self, b: LagrangianBuilder) -> None:
        m, k = b.param("mass"), b.param("force_constant")
        pos, vel = zip(*(b.coordinate(c, "m") for c in "xyz"), strict=True)
        b.kinetic = m * sum(c**2 for c in vel) / 2
        radius = sp.sqrt(sum(c**2 for c in pos))
        if self.perturbation == "none":
            b.potential = -k / radius
            L, _ = declare_orbit_vectors(b, m, pos, vel, k)
        else:
            j2, R = b.param("j2"), b.param("equatorial_radius")
            p2 = (3 * pos[2] ** 2 / radius**2 - 1) / 2
            b.potential = -k / radius * (1 - j2 * (R / radius) ** 2 * p2)
            x, y, _ = pos
            vx, vy, _ = vel
            L = (m * (y * vel[2] - pos[2] * vy), m * (pos[2] * vx - x * vel[2]),
                 m * (x * vy - y * vx))
            b.invariant("angular_momentum_z", "kg m^2/s", L[2])
        b.observable("radius", "m", radius)
        acc = tuple(b.acceleration(q) for q in b.q)
        rates = frame_rates(pos, vel, acc, sp.sqrt)
        values = [w for name in FRAME_NAMES for w in rates[name]]
        values += [sp.sqrt(sum(w**2 for w in rates[name])) for name in FRAME_NAMES]
        for q, value in zip(omega_quantities(FRAME_NAMES), values, strict=True):
            b.observable(q.name, q.unit, value)
        l_norm = sp.sqrt(sum(c**2 for c in L))
        b.observable("normal_acceleration", "m/s^2",
                     sum(a * c for a, c in zip(acc, L, strict=True)) / l_norm)
        b.frame("centre", "world", (0, 0, 0))
        axes = frame_axes(pos, vel)
        for name in FRAME_NAMES:
            b.frame(name, "centre", pos, quaternion_from_axes(axes[name]))

    # --- state ----------------------------------------------------------------------------
    def cartesian_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Initial position and velocity in the ``centre`` frame."""
        return (np.array([self.value(f"initial.{c}") for c in "xyz"]),
                np.array([self.value(f"initial_rate.{c}") for c in "xyz"]))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.cartesian_state()

    def visuals(self) -> tuple[Visual, ...]:
        r0 = float(np.linalg.norm(self.cartesian_state()[0]))
        centre = (self.value("equatorial_radius") if self.perturbation == "oblateness"
                  else 0.08 * r0)
        return (Visual("sphere", "centre", radius=centre, color=(255, 200, 80)),
                Visual("sphere", "vbn", radius=0.04 * r0, color=(120, 170, 255)),
                Visual("trail", "vbn", color=(120, 170, 255)),
                *(Visual("axes", f, radius=0.25 * r0, color=FRAME_COLORS[f])
                  for f in FRAME_NAMES))

    def law_scales(self) -> dict[str, float]:
        """Components of L against |L|, of A against mk (a component may start at zero)."""
        return vector_law_scales(super().law_scales(),
                                 float(np.linalg.norm(self.angular_momentum())),
                                 self.value("mass") * self.value("force_constant"))

    def time_scale(self) -> float:
        r, v = self.cartesian_state()
        return pericentre_time(self.value("force_constant") / self.value("mass"), r, v)

    # --- analytic oracles ------------------------------------------------------------------
    def angular_momentum(self) -> np.ndarray:
        """L = m r × ṙ at the start."""
        r, v = self.cartesian_state()
        return self.value("mass") * np.cross(r, v)



MODEL = OrbitFrames
