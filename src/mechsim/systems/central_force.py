"""Two bodies in a central potential: centre of mass, relative orbit, reduced mass.

Sources: PHYS0500 ch. 4 ("Central Force Motion": §4.1 reduced mass, §4.2–4.4 first
integrals and turning points, §4.5 effective potential, §4.6 Kepler and the conic table),
Introduction to analytical mechanics, “Central force problem – with two body” to “Closed orbits of
the two body problem” (two-body problem, Kepler, effective potential, −a/r³, isotropic harmonic and
the spring V ∝ (r − l)²), Lecture 10, central force in spherical coordinates (eq. 10.19)
(central-force particle).

Coordinates: the centre of mass R = (m₁r₁ + m₂r₂)/M in ``world`` (``cm_x``, ``cm_y``) and the
relative position r = r₁ − r₂ (of body 1 from body 2, PHYS0500 line 819) in the orbital plane,
z along the angular momentum: Cartesian (x, y) or polar (r, θ), the two formulations.
L = ½ M Ṙ² + ½ μ ṙ² − U(r), μ = m₁m₂/M; body 1 sits at +(m₂/M) r and body 2 at −(m₁/M) r
from the CM (eq. 4.1).

``potential`` (U(r), zero at r → ∞ except for the oscillators):
- ``kepler``: −k/r (``force_constant`` k). The ``kepler`` system is this case with the CM at
  rest and the orbit given by its elements. The Laplace–Runge–Lenz vector is an invariant here.
- ``inverse_cube``: −a/r³ (``inverse_cube_strength`` a, Introduction to analytical mechanics,
  “Closed orbits of the two body problem”). The effective potential has a barrier at r* = 3aμ/l²;
  inside it (or above it) the bodies fall to the centre in finite time. The event ``fall`` at
  r = ``capture_radius`` merges them: the relative motion stops (mode ``fallen`` = 1 switches U off,
  ṙ = 0) and the relative energy it had goes into work_dissipated, so the work balance still closes.
  Energy and angular momentum are then not conserved: for an orbit that falls (decided from the
  initial state by the turning-point analysis) ``laws()`` drops them (l stays published; it holds
  until the fall).
- ``harmonic``: ½ k r² (``spring_constant`` k, Introduction to analytical mechanics, “Closed orbits
  of the two body problem”): centred ellipses, period 2π√(μ/k) for every energy.
- ``spring``: ½ k (r − l₀)² (``rest_length`` l₀, Introduction to analytical mechanics L1408): a
  vibrating rotor.

Typos fixed (see the catalog): ε = √(1 + 2El²/(μk²)) (PHYS0500 line 988 prints √(2 + 2El²/(μk)));
rθ̇² = (l²/μ²)u³ (line 893 prints u²); E = ½μ(ṙ² + r²θ̇²) + U (line 843 is truncated); V = −k/r
(Introduction to analytical mechanics L1898 prints −k/2); the conic equation carries e²x²
(Introduction to analytical mechanics L1896). Orbit classes follow the conic table (PHYS0500 line
996) for −k/r; for the other potentials ``orbit_class`` reports
circle / bounded / unbounded / falls.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, number, positive
from mechsim.systems._central import (
    conic_class,
    declare_orbit_quantities,
    effective_potential,
    kepler_elements,
    merge_at_capture,
    orbit_integral,
    radial_range,
    turning_points,
)
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

if TYPE_CHECKING:
    from mechsim.systems.curves import Curve

POTENTIALS = ("kepler", "inverse_cube", "harmonic", "spring")


class CentralForce(LagrangianModel):
    id = "central_force"
    title = "Two-body central-force problem (Kepler, −a/r³, harmonic, spring)"
    source = ("PHYS0500 – Advanced Classical Mechanics, ch. 4 (Central Force Motion, §4.1–4.6); "
              "Introduction to analytical mechanics, “Central force problem – with two body” and "
              "“Classification of the orbits”; Lecture 10: The Methods of Lagrange Revisited, "
              "central force (eq. 10.19)")
    formulations = ("cartesian", "polar")
    oracles = ("turning points E = V_eff(r); Kepler ε, r_min/r_max, period, conic class, LRL "
               "|A| = μkε; harmonic period 2π√(μ/k); CM uniform; −a/r³ barrier r* and fall time")
    parameters = (
        Parameter("potential", "kepler", "", "central potential U(r)", choices=POTENTIALS),
        positive("mass_1", 1.0, "kg", "mass m₁ of body 1"),
        positive("mass_2", 0.5, "kg", "mass m₂ of body 2"),
        positive("force_constant", 1.0, "N m^2", "k of U = −k/r (kepler)"),
        positive("inverse_cube_strength", 0.1, "N m^4", "a of U = −a/r³ (inverse_cube)"),
        positive("spring_constant", 1.0, "N/m", "k of U = ½kr² (harmonic) or ½k(r − l₀)² "
                 "(spring)"),
        positive("rest_length", 1.0, "m", "rest length l₀ of the spring (spring)"),
        positive("capture_radius", 0.02, "m", "separation at which the bodies merge "
                 "(inverse_cube fall to the centre)"),
        positive("initial.r", 1.0, "m", "initial separation r = |r₁ − r₂|"),
        number("initial.theta", 0.0, "rad", "initial polar angle θ of r₁ − r₂"),
        number("initial_rate.r", -0.3, "m/s", "initial ṙ"),
        number("initial_rate.theta", 1.2, "rad/s", "initial θ̇"),
        number("initial.cm_x", 0.0, "m", "initial centre-of-mass x"),
        number("initial.cm_y", 0.0, "m", "initial centre-of-mass y"),
        number("initial_rate.cm_x", 0.1, "m/s", "centre-of-mass velocity x"),
        number("initial_rate.cm_y", 0.0, "m/s", "centre-of-mass velocity y"),
    )

    @property
    def potential_name(self) -> str:
        return str(self.values["potential"])

    def check(self) -> None:
        if self.value("initial.r") <= self.value("capture_radius") \
                and self.potential_name == "inverse_cube":
            raise ParameterError("initial.r", "must be > capture_radius")

    # --- the potential ------------------------------------------------------------------------
    def potential_function(self) -> Callable[[float], float]:
        """U(r) as a Python function of the current parameters."""
        name = self.potential_name
        if name == "kepler":
            k = self.value("force_constant")
            return lambda r: -k / r
        if name == "inverse_cube":
            a = self.value("inverse_cube_strength")
            return lambda r: -a / r**3
        ks = self.value("spring_constant")
        if name == "harmonic":
            return lambda r: 0.5 * ks * r * r
        l0 = self.value("rest_length")
        return lambda r: 0.5 * ks * (r - l0) ** 2

    def _U(self, b: LagrangianBuilder, r: sp.Expr) -> sp.Expr:
        name = self.potential_name
        if name == "kepler":
            return -b.param("force_constant") / r
        if name == "inverse_cube":
            return -b.param("inverse_cube_strength") / r**3
        if name == "harmonic":
            return b.param("spring_constant") * r**2 / 2
        return b.param("spring_constant") * (r - b.param("rest_length")) ** 2 / 2

    def declare(self, b: LagrangianBuilder) -> None:
        m1, m2 = b.param("mass_1"), b.param("mass_2")
        M, mu = m1 + m2, m1 * m2 / (m1 + m2)
        X, dX = b.coordinate("cm_x", "m")
        Y, dY = b.coordinate("cm_y", "m")
        if self.formulation == "cartesian":
            x, dx = b.coordinate("x", "m")
            y, dy = b.coordinate("y", "m")
            r = sp.sqrt(x**2 + y**2)
            theta = sp.atan2(y, x)
            b.kinetic = M * (dX**2 + dY**2) / 2 + mu * (dx**2 + dy**2) / 2
            Lz = mu * (x * dy - y * dx)
            rdot = (x * dx + y * dy) / r
        else:
            r, dr = b.coordinate("r", "m")
            theta, dth = b.coordinate("theta", "rad")
            x, y = r * sp.cos(theta), r * sp.sin(theta)
            dx = dr * sp.cos(theta) - r * sp.sin(theta) * dth
            dy = dr * sp.sin(theta) + r * sp.cos(theta) * dth
            b.kinetic = M * (dX**2 + dY**2) / 2 + mu * (dr**2 + r**2 * dth**2) / 2
            Lz = mu * r**2 * dth
            rdot = dr
        U = self._U(b, r)
        if self.potential_name == "inverse_cube":
            fallen = b.mode("fallen")
            b.potential = U * (1 - fallen)
            b.event("fall", r - b.param("capture_radius") + fallen, -1,
                    "the bodies reach the capture radius and merge")
        else:
            b.potential = U
        b.invariant("momentum_x", "kg m/s", M * dX)
        b.invariant("momentum_y", "kg m/s", M * dY)
        k = b.param("force_constant") if self.potential_name == "kepler" else None
        declare_orbit_quantities(b, mu, x, y, dx, dy, k=k, radius=r, angular_momentum=Lz)
        E_rel = mu * (dx**2 + dy**2) / 2 + U
        b.observable("relative_energy", "J", E_rel)
        b.observable("radial_velocity", "m/s", rdot)
        b.observable("effective_potential", "J", U + Lz**2 / (2 * mu * r**2))
        if k is not None:
            Ax = mu * Lz * dy - mu * k * x / r
            Ay = -mu * Lz * dx - mu * k * y / r
            b.observable("eccentricity", "", sp.sqrt(Ax**2 + Ay**2) / (mu * k))
            b.observable("true_anomaly", "rad", theta - sp.atan2(Ay, Ax))
            w = sp.atan2(Ay, Ax)
        b.frame("cm", "world", (X, Y, 0))
        b.frame("body_1", "cm", (m2 / M * x, m2 / M * y, 0))
        b.frame("body_2", "cm", (-m1 / M * x, -m1 / M * y, 0))
        if k is not None:
            # perifocal frame: x toward periapsis (along A), z along L; fixed for −k/r
            b.frame("perifocal", "cm", (0, 0, 0), (0, 0, sp.sin(w / 2), sp.cos(w / 2)))

    def visuals(self) -> tuple[Visual, ...]:
        m1, m2 = self.value("mass_1"), self.value("mass_2")
        s = 0.06 * self.value("initial.r") / max(m1, m2) ** (1 / 3)
        out = [Visual("sphere", "body_1", radius=s * m1 ** (1 / 3), color=(255, 200, 80)),
               Visual("sphere", "body_2", radius=s * m2 ** (1 / 3), color=(120, 170, 255)),
               Visual("trail", "body_1", color=(255, 200, 80)),
               Visual("trail", "body_2", color=(120, 170, 255)),
               Visual("sphere", "cm", radius=0.01, color=(255, 255, 255)),
               Visual("link", "body_1", to_frame="body_2", radius=0.005,
                      color=(160, 160, 160))]
        if self.potential_name == "kepler":
            out.append(Visual("axes", "perifocal", radius=0.3 * self.value("initial.r")))
        return tuple(out)

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        r, th = self.value("initial.r"), self.value("initial.theta")
        dr, dth = self.value("initial_rate.r"), self.value("initial_rate.theta")
        cm = [self.value("initial.cm_x"), self.value("initial.cm_y")]
        dcm = [self.value("initial_rate.cm_x"), self.value("initial_rate.cm_y")]
        if self.formulation == "polar":
            return np.array([*cm, r, th]), np.array([*dcm, dr, dth])
        c, s = math.cos(th), math.sin(th)
        return (np.array([*cm, r * c, r * s]),
                np.array([*dcm, dr * c - r * s * dth, dr * s + r * c * dth]))

    def on_fall(self, t: float, y: np.ndarray) -> np.ndarray:
        """Merge: stop the relative motion, switch U off, book the lost relative energy."""
        n = len(self.coordinates)
        return merge_at_capture(self, t, y, rates=(n + 2, n + 3), mode=2 * n + 2)

    def laws(self):  # type: ignore[no-untyped-def]
        laws = super().laws()
        if self.potential_name == "inverse_cube" and self.falls_to_centre():
            laws = tuple(law for law in laws if law.kind not in ("energy", "energy_function")
                         and law.key != "invariant:angular_momentum")
        return laws

    def time_scale(self) -> float:
        r, dth = self.value("initial.r"), self.value("initial_rate.theta")
        mu = self.reduced_mass()
        U = self.potential_function()
        h = 1e-4 * r
        curv = abs(U(r + h) - 2 * U(r) + U(r - h)) / h**2
        scales = [2 * math.pi / abs(dth)] if dth != 0 else []
        if curv > 0:
            scales.append(2 * math.pi * math.sqrt(mu / curv))
        # The pericentre passage limits a fixed step: 2π/θ̇ at the inner turning point.
        l = self.angular_momentum()
        if l != 0.0:
            inner = self.radial_range()[0]
            if inner > 0.0:
                scales.append(2 * math.pi * mu * inner**2 / abs(l))
        return min(scales) if scales else 1.0

    # --- analytic oracles ---------------------------------------------------------------------
    def reduced_mass(self) -> float:
        """μ = m₁m₂/(m₁ + m₂) (PHYS0500 line 815)."""
        m1, m2 = self.value("mass_1"), self.value("mass_2")
        return m1 * m2 / (m1 + m2)

    def angular_momentum(self) -> float:
        """l = μ r² θ̇ (constant)."""
        return self.reduced_mass() * self.value("initial.r") ** 2 * self.value(
            "initial_rate.theta")

    def relative_energy(self) -> float:
        """E = ½ μ (ṙ² + r² θ̇²) + U(r) of the relative motion (PHYS0500 line 847)."""
        r, dr, dth = (self.value("initial.r"), self.value("initial_rate.r"),
                      self.value("initial_rate.theta"))
        return 0.5 * self.reduced_mass() * (dr**2 + r**2 * dth**2) + \
            self.potential_function()(r)

    def effective_potential(self, r: float) -> float:
        """V_eff = U + l²/(2μr²) (PHYS0500 line 960)."""
        return effective_potential(self.potential_function(), self.reduced_mass(),
                                   self.angular_momentum())(r)

    def turning_points(self) -> list[float]:
        """All radii with E = V_eff(r) (PHYS0500 line 913), ascending."""
        return turning_points(self.potential_function(), self.reduced_mass(),
                              self.relative_energy(), self.angular_momentum(),
                              r_min=min(1e-4, self.value("capture_radius")) *
                              self.value("initial.r"), r_max=1e4 * self.value("initial.r"))

    def radial_range(self) -> tuple[float, float]:
        """(r_min, r_max) of the motion: the turning points around the initial radius
        (r_max = ∞ when unbound; r_min = 0 when nothing stops an inward motion)."""
        r0 = self.value("initial.r")
        return radial_range(self.potential_function(), self.reduced_mass(),
                            self.relative_energy(), self.angular_momentum(), r0,
                            self.value("initial_rate.r"),
                            r_min=min(1e-4, self.value("capture_radius")) * r0, r_max=1e4 * r0)

    def falls_to_centre(self) -> bool:
        """True when nothing stops the bodies before r = 0 (only −a/r³ here)."""
        if self.potential_name != "inverse_cube":
            return False
        lo, _ = self.radial_range()
        return lo <= self.value("capture_radius")

    def barrier(self) -> tuple[float, float]:
        """−a/r³: maximum of V_eff at r* = 3aμ/l², V_eff(r*) = l⁶/(54a²μ³) (catalog, derived)."""
        a, mu, l = (self.value("inverse_cube_strength"), self.reduced_mass(),
                    self.angular_momentum())
        return 3 * a * mu / l**2, l**6 / (54 * a * a * mu**3)

    def kepler_elements(self) -> dict[str, float]:
        """For −k/r: ε, α, r_min, r_max, a, b, period (PHYS0500 §4.6, ε typo fixed)."""
        return kepler_elements(self.reduced_mass(), self.value("force_constant"),
                               self.relative_energy(), self.angular_momentum())

    def orbit_class(self) -> str:
        """−k/r: the conic table (circle, ellipse, parabola, hyperbola); others: circle,
        bounded, unbounded or falls (to the centre)."""
        if self.potential_name == "kepler":
            return conic_class(self.kepler_elements()["eccentricity"])
        if self.falls_to_centre():
            return "falls"
        lo, hi = self.radial_range()
        if hi - lo < 1e-9 * self.value("initial.r"):
            return "circle"
        return "bounded" if math.isfinite(hi) else "unbounded"

    def radial_period(self) -> float:
        """Time from r_min to r_max and back: 2 ∫ dr / √((2/μ)(E − V_eff)) (the analytical-
        mechanics notes' “Central force problem – with two body”; ``orbit_integral``)."""
        lo, hi = self.radial_range()
        if not (math.isfinite(hi) and lo > 0 and hi > lo):
            raise ValueError("no radial oscillation")
        E, V = self.relative_energy(), self.effective_potential
        return 2 * orbit_integral(lambda r: np.array([E - V(x) for x in r]), self.reduced_mass(),
                                  lo, hi, nodes=4000)

    def harmonic_period(self) -> float:
        """Isotropic oscillator: 2π√(μ/k), the same for every orbit (Introduction to analytical
        mechanics, “Closed orbits of the two body problem”)."""
        return 2 * math.pi * math.sqrt(self.reduced_mass() / self.value("spring_constant"))

    def curves(self) -> tuple[Curve, ...]:
        """U_eff(r) with the orbit's energy and its turning points (none where the orbit's
        radial range cannot be found: a fall to the centre)."""
        from mechsim.systems.curves import orbit_curves

        return orbit_curves(self)


MODEL = CentralForce
