"""Motion seen from a rotating frame: a particle and a Foucault pendulum on the rotating Earth.

Source: PHYS0500 ch. 6 ("Motion in Non-Inertial Reference Frames": eqs. 6.1–6.4, §6.1
centrifugal and Coriolis forces, §6.2 motion relative to the Earth). The document cites but
omits eq. (6.3), the transport theorem (dQ/dt)_fixed = (dQ/dt)_rot + ω × Q for any vector Q;
it is what the rotating-frame Lagrangian below encodes: the velocity seen from the fixed axes is
v_r + ω × r, so L = ½ m |v_r + ω × r|² − V gives m a_r = F − 2m ω × v_r − m ω × (ω × r).

Conventions:
- The local frame ``enu`` sits on the Earth's surface at ``latitude`` λ (longitude 0): x east,
  y north, z up along the plumb line. The Earth turns at ``rotation_rate`` Ω about its axis, so
  in ENU components ω = Ω (0, cos λ, sin λ). ``gravity`` g is the effective (plumb-line)
  gravity g = g₀ − ω × (ω × R) of eq. 1488, uniform and along −z: the centrifugal term of the
  origin's motion is inside g, the centrifugal term of the displacement r, −m ω × (ω × r), is
  kept (the document drops it for r ≪ R, line 1492; it is O(Ω² r)).
- Frames: ``world`` is the inertial frame at the Earth's centre with z along the Earth's axis;
  ``earth`` turns about it by Ω t; ``enu`` is fixed on the Earth at radius ``earth_radius``;
  the particle (or bob), the pendulum ``pivot`` and the ``swing_plane`` (x along the swing,
  z up) are posed in ``enu``. Positive angles are counter-clockwise seen from above (about up).
- Energy: ``kinetic`` is ½ m |v_r + ω × r|², the kinetic energy seen from non-rotating axes
  through the ENU origin, and V = m g z. In the rotating frame E = T + V is not conserved (the
  uniform gravity turns with the Earth); the Jacobi integral
  J = ½ m |v_r|² − ½ m |ω × r|² + m g z = E − ω·L is (``jacobi_integral``; it is the energy
  function h of the rotating-frame Lagrangian).

Formulations:
- ``rotating``: a particle, Cartesian ENU coordinates, rotating-frame Lagrangian (above).
- ``inertial``: the same particle in non-rotating axes that coincide with ENU at t = 0, where
  gravity turns: V = m g Û(t)·X with Û(t) the local up rotated by Ω t about ω; the ENU position
  is R(ω̂, −Ωt) X. A check of the transport theorem: both must give the same ENU path.
- ``foucault_pendulum``: a bob on a rod of ``length`` l from a pivot l above the ENU origin
  (Cartesian coordinates, rod as a holonomic constraint with multiplier λ = −tension), in the
  rotating frame. Its swing plane turns at −Ω sin λ (clockwise in the northern hemisphere).
  ``swing_plane_angle`` is the major-axis angle of the Fradkin tensor A = u uᵀ + w² ζ ζᵀ of the
  horizontal motion (ζ = (x, y), u = ζ̇ + Ω sin λ ẑ × ζ, w² = g/l + Ω² sin² λ): for the
  linearised pendulum it turns at exactly −Ω sin λ.
Initial conditions: ``initial.east/north/up`` and ``initial_rate.*`` are the position and the
velocity relative to the Earth (the pendulum takes east and north and hangs from the rod).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, nonnegative, number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Law, Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

EARTH_ROTATION = 7.2921159e-5  # rad/s, sidereal


def _cross(a: sp.Matrix, b: sp.Matrix) -> sp.Matrix:
    return a.cross(b)


class RotatingFrame(LagrangianModel):
    id = "rotating_frame"
    title = "Rotating frame: free fall and Foucault pendulum on the rotating Earth"
    source = ("PHYS0500 – Advanced Classical Mechanics, ch. 6 (Motion in Non-Inertial Reference "
              "Frames, §6.1–6.2)")
    formulations = ("rotating", "inertial", "foucault_pendulum")
    oracles = ("exact linear solution (matrix exponential); eastward deflection ⅓Ωg t³cosλ; "
               "Foucault plane rate −Ω sinλ; Jacobi integral; rotating = inertial form")
    parameters = (
        positive("mass", 1.0, "kg", "particle or bob mass m"),
        nonnegative("gravity", 9.81, "m/s^2", "effective (plumb-line) gravity g"),
        Parameter("latitude", math.radians(40.0), "rad", "geographic latitude λ",
                  minimum=-math.pi / 2, maximum=math.pi / 2),
        number("rotation_rate", EARTH_ROTATION, "rad/s",
               "Earth's rotation rate Ω (sidereal: 7.2921159e-5)"),
        positive("earth_radius", 6.371e6, "m", "distance of the ENU origin from the Earth's "
                 "centre (places the frames only)"),
        positive("length", 10.0, "m", "pendulum length l (foucault_pendulum)"),
        number("initial.east", 0.5, "m", "initial east position"),
        number("initial.north", 0.0, "m", "initial north position"),
        number("initial.up", 100.0, "m", "initial height (particle forms; the pendulum hangs)"),
        number("initial_rate.east", 0.0, "m/s", "initial east velocity relative to the Earth"),
        number("initial_rate.north", 0.0, "m/s", "initial north velocity relative to the Earth"),
        number("initial_rate.up", 0.0, "m/s", "initial up velocity relative to the Earth"),
    )

    def check(self) -> None:
        if self.formulation == "foucault_pendulum":
            l = self.value("length")
            if math.hypot(self.value("initial.east"), self.value("initial.north")) >= 0.99 * l:
                raise ParameterError("initial.east", f"the bob must start within 0.99 × length "
                                     f"({0.99 * l:g} m) of the vertical")

    # --- declaration -----------------------------------------------------------------------
    def declare(self, b: LagrangianBuilder) -> None:
        m, g, lat = b.param("mass"), b.param("gravity"), b.param("latitude")
        Om, Re = b.param("rotation_rate"), b.param("earth_radius")
        t = b.t
        axis = sp.Matrix([0, sp.cos(lat), sp.sin(lat)])  # ω̂ in ENU
        w = Om * axis
        if self.formulation == "inertial":
            X = [b.coordinate(n, "m") for n in ("inertial_x", "inertial_y", "inertial_z")]
            q = sp.Matrix([c[0] for c in X])
            v = sp.Matrix([c[1] for c in X])
            up = self._rodrigues(axis, Om * t, sp.Matrix([0, 0, 1]))
            b.kinetic = m * v.dot(v) / 2
            b.potential = m * g * up.dot(q)
            b.invariant("jacobi_integral", "J", b.kinetic + b.potential
                        - w.dot(_cross(q, m * v)))
            r = self._rodrigues(axis, -Om * t, q)
        else:
            names = ("east", "north", "up")
            C = [b.coordinate(n, "m") for n in names]
            r = sp.Matrix([c[0] for c in C])
            v = sp.Matrix([c[1] for c in C])
            vf = v + _cross(w, r)
            b.kinetic = m * vf.dot(vf) / 2
            b.potential = m * g * r[2]
            wr = _cross(w, r)
            b.invariant("jacobi_integral", "J", m * v.dot(v) / 2 - m * wr.dot(wr) / 2
                        + m * g * r[2])
            if self.formulation == "foucault_pendulum":
                l = b.param("length")
                b.constraint("rod_length", sp.sqrt(r[0]**2 + r[1]**2 + (r[2] - l)**2) - l)
                lam = b.multiplier(0)
                b.observable("tension", "N", -lam)
                wz = Om * sp.sin(lat)
                ux, uy = v[0] - wz * r[1], v[1] + wz * r[0]
                w2 = g / l + wz**2
                axx = ux * ux + w2 * r[0] ** 2
                ayy = uy * uy + w2 * r[1] ** 2
                axy = ux * uy + w2 * r[0] * r[1]
                plane = sp.atan2(2 * axy, axx - ayy) / 2
                b.observable("swing_plane_angle", "rad", plane)
        for name, e in zip(("east", "north", "up"), r, strict=True):
            b.observable(name, "m", e)
        # frames: the Earth turns about world z; ENU at latitude λ, longitude 0
        b.frame("earth", "world", (0, 0, 0), (0, 0, sp.sin(Om * t / 2), sp.cos(Om * t / 2)))
        half = (sp.pi / 2 - lat) / 2
        k = sp.sqrt(2) / 2
        b.frame("enu", "earth", (Re * sp.cos(lat), 0, Re * sp.sin(lat)),
                (k * sp.sin(half), k * sp.sin(half), k * sp.cos(half), k * sp.cos(half)))
        if self.formulation == "foucault_pendulum":
            b.frame("pivot", "enu", (0, 0, b.param("length")))
            b.frame("bob", "enu", tuple(r))
            b.frame("swing_plane", "enu", (0, 0, 0), (0, 0, sp.sin(plane / 2),
                                                      sp.cos(plane / 2)))
        else:
            b.frame("particle", "enu", tuple(r))

    @staticmethod
    def _rodrigues(axis: sp.Matrix, angle: sp.Expr, vec: sp.Matrix) -> sp.Matrix:
        """vec turned by ``angle`` about the unit ``axis`` (right-handed)."""
        c, s = sp.cos(angle), sp.sin(angle)
        return vec * c + _cross(axis, vec) * s + axis * axis.dot(vec) * (1 - c)

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        r = np.array([self.value("initial.east"), self.value("initial.north"),
                      self.value("initial.up")])
        v = np.array([self.value(f"initial_rate.{n}") for n in ("east", "north", "up")])
        if self.formulation == "foucault_pendulum":
            l = self.value("length")
            r[2] = l - math.sqrt(l * l - r[0] ** 2 - r[1] ** 2)
        if self.formulation == "inertial":
            v = v + np.cross(self.omega_enu(), r)  # transport theorem, eq. 6.2
        return r, v

    def laws(self) -> tuple[Law, ...]:
        # E = T + V is not conserved in the rotating frame (gravity turns with the Earth).
        return tuple(law for law in super().laws() if law.kind != "energy")

    def time_scale(self) -> float:
        g = self.value("gravity")
        if self.formulation == "foucault_pendulum" and g > 0:
            return 2 * math.pi * math.sqrt(self.value("length") / g)
        h = abs(self.value("initial.up"))
        return math.sqrt(2 * h / g) if g > 0 and h > 0 else 1.0

    def visuals(self) -> tuple[Visual, ...]:
        if self.formulation == "foucault_pendulum":
            return (Visual("link", "pivot", to_frame="bob", radius=0.01),
                    Visual("sphere", "bob", radius=0.15, color=(220, 170, 80)),
                    Visual("trail", "bob", color=(120, 170, 255)),
                    Visual("axes", "swing_plane", radius=1.0),
                    Visual("axes", "enu", radius=0.5))
        return (Visual("sphere", "particle", radius=0.2, color=(220, 170, 80)),
                Visual("trail", "particle", color=(120, 170, 255)),
                Visual("axes", "enu", radius=2.0),
                Visual("polyline", "enu", points=((0.0, 0.0, 0.0), (0.0, 0.0,
                       max(self.value("initial.up"), 1.0))), radius=0.01, color=(150, 150, 150)))

    # --- analytic oracles ------------------------------------------------------------------
    def omega_enu(self) -> np.ndarray:
        lat, Om = self.value("latitude"), self.value("rotation_rate")
        return Om * np.array([0.0, math.cos(lat), math.sin(lat)])

    def eastward_deflection(self, height: float | None = None) -> float:
        """Drop from rest at ``height``: x_E = ⅓ Ω g t³ cos λ, t = √(2h/g), to first order in
        Ω (catalog 003 §6.2 [SUPPLEMENT]; 1.6815 cm for h = 100 m at 40°)."""
        h = self.value("initial.up") if height is None else height
        g = self.value("gravity")
        return (self.value("rotation_rate") * math.cos(self.value("latitude"))
                * math.sqrt(8 * h**3 / g) / 3)

    def foucault_rate(self) -> float:
        """Swing-plane rate seen from above, counter-clockwise positive: −Ω sin λ."""
        return -self.value("rotation_rate") * math.sin(self.value("latitude"))


MODEL = RotatingFrame
