"""A particle in a power-law central force F = −K rⁿ: open and closed orbits, the apsidal angle,
Bertrand's closed cases, small radial oscillations, and the orbit equation in u = 1/r.

Sources: PHYS0500 – Advanced Classical Mechanics, §4.2–4.5.1 (first integrals, the orbit
equation d²u/dθ² + u = −(μ/l²u²) F(1/u) (eq. at line 897, boxed), turning points, the angle
Δθ between successive pericentres and the closed-orbit condition Δθ = 2π a/b, U ∝ r^{n+1}
closed only for n = −2 and 1, F ∝ rⁿ solvable in circular functions for n = 1, −2, −3, the
effective potential and the small oscillations about a circular orbit of §4.5.1); the
analytical-mechanics notes' “Two body problem equation – power law potentials” and “Closed
orbits of the two body problem”.

The documents' n is the force's exponent: F(r) ∝ rⁿ and U(r) ∝ r^{n+1}. Here F(r) = −K rⁿ with
K > 0 (``force_constant``, attractive), so U(r) = K r^{n+1}/(n + 1) (the brief form k r^{n+1}
with k = K/(n + 1)); U = K ln(r / 1 m) for n = −1. Motion in the plane z = 0 of REP-103 axes,
θ counter-clockwise about +z, μ the mass of the particle about a fixed centre (or the reduced
mass of a pair). SI units.

Formulations:
- ``polar``: time t independent, coordinates (r, θ), L = ½μ(ṙ² + r²θ̇²) − U(r) (eq. 4.2).
- ``binet``: the polar angle is the independent variable (the simulation's clock counts θ − θ₀
  in rad), the coordinate u = 1/r (1/m). L = (l²/μ)(½u′² − ½u²) − U(1/u) gives the document's
  orbit equation u″ + u = −(μ/l²u²) F(1/u) and its first integral
  (l²/2μ)(u′² + u²) + U(1/u) = E, the orbit's energy (ṙ = −(l/μ)u′). The physical time rides
  along as a second coordinate τ with the term ½κ(τ′ − μ/(l u²))², κ = l⁴/(μ³r₀⁶) (units):
  τ is cyclic, its momentum p_τ = κ(τ′ − μ/(lu²)) is conserved and starts at 0, so
  τ′ = dt/dθ = μ/(l u²) = 1/θ̇ along the motion and the term adds nothing to the orbit
  (p_τ, ``time_momentum``, is a checked invariant). Only bound orbits (E below U at infinity,
  not falling) are accepted: u = 0 is r = ∞.

Quantities that are not functions of the state are analyses (methods here, from the conserved E
and l): ``apsidal_angle`` is the quadrature ∫_{r_min}^{r_max} (l/r²) dr / √(2μ(E − U_eff)) from
one apsis to the next (Gauss–Chebyshev, ``_central.orbit_integral``; the document's Δθ is twice
it), ``precession_per_orbit`` = Δθ − 2π per radial period, ``near_circular_apsidal_angle`` =
π/√(n + 3) (PHYS0500 catalog's near-circular limit, F = −K rⁿ), ``radial_frequency`` =
√(U_eff″(r₀)/μ) about the circular orbit of the same l (§4.5.1: ½U_eff″(r − r₀)² as ½kx²),
equal to √(n + 3) θ̇₀.

n ≤ −3: the centrifugal barrier no longer holds the particle off the centre when μK > l² (or
falling inward with too little energy): the event ``fall`` at ``capture_radius`` stops it
there (mode ``fallen`` switches U off; the energy it had goes into work_dissipated, so the work
balance still closes), and ``laws`` drops the energy and l for an orbit that falls.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, number, positive
from mechsim.systems._central import (
    apsidal_angle,
    declare_orbit_quantities,
    effective_potential,
    merge_at_capture,
    nearest_turning_points,
    orbit_integral,
)
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Law, Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

if TYPE_CHECKING:
    from mechsim.systems.curves import Curve


class PowerLawOrbit(LagrangianModel):
    id = "power_law_orbit"
    title = "Orbit in a power-law central force F = −K rⁿ (apsidal angle, Bertrand, Binet form)"
    source = ("PHYS0500 – Advanced Classical Mechanics, §4.2–4.5.1 (orbit equation, orbits in "
              "a central field, effective potential, small oscillations); Introduction to "
              "analytical mechanics, “Two body problem equation – power law potentials” and "
              "“Closed orbits of the two body problem”")
    formulations = ("polar", "binet")
    oracles = ("closed orbits for n = −2, 1 (apsidal angle π, π/2 by quadrature and by the "
               "integrated apsides); near-circular apsidal angle π/√(n+3); radial frequency "
               "√((n+3))θ̇₀ = √(U_eff″/μ); conic, centred-ellipse and Cotes-spiral r(θ) for "
               "n = −2, 1, −3; binet u(θ), t(θ) = time form; scipy orbit")
    parameters = (
        positive("mass", 1.0, "kg", "mass μ of the particle (reduced mass of a pair)"),
        Parameter("exponent", -2.5, "", "exponent n of the force F = −K rⁿ (U ∝ r^(n+1))",
                  minimum=-5.0, maximum=5.0),
        positive("force_constant", 1.0, "N m^-n", "K of F = −K rⁿ (attractive)"),
        positive("capture_radius", 0.02, "m", "radius at which a falling particle (n ≤ −3) "
                 "is stopped"),
        positive("initial.r", 1.0, "m", "initial distance r from the centre"),
        number("initial.theta", 0.0, "rad", "initial polar angle θ"),
        number("initial_rate.r", 0.0, "m/s", "initial ṙ"),
        number("initial_rate.theta", 0.8, "rad/s", "initial θ̇ (nonzero: l = μr²θ̇)"),
    )

    # --- parameters --------------------------------------------------------------------------
    @property
    def exponent(self) -> float:
        return self.value("exponent")

    def check(self) -> None:
        if self.value("initial_rate.theta") == 0.0:
            raise ParameterError("initial_rate.theta", "must be nonzero (with l = 0 the "
                                 "particle falls through the centre, where θ is undefined)")
        if self.value("initial.r") <= self.value("capture_radius"):
            raise ParameterError("initial.r", "must be > capture_radius")
        if self.formulation == "binet":
            lo, hi = self.radial_range()
            if not math.isfinite(hi) or lo <= self.value("capture_radius"):
                what = "escapes to infinity (u reaches 0)" if not math.isfinite(hi) \
                    else "falls to the centre"
                raise ParameterError("formulation", f"binet takes bound orbits only: this "
                                     f"orbit {what}; use the polar formulation")

    # --- declaration -------------------------------------------------------------------------
    def _U(self, b: LagrangianBuilder, r: sp.Expr) -> sp.Expr:
        n, K = b.param("exponent"), b.param("force_constant")
        if self.exponent == -1.0:
            return K * sp.log(r)
        return K * r ** (n + 1) / (n + 1)

    def declare(self, b: LagrangianBuilder) -> None:
        mu = b.param("mass")
        r0, w0 = b.param("initial.r"), b.param("initial_rate.theta")
        l = mu * r0**2 * w0
        if self.formulation == "polar":
            r, dr = b.coordinate("r", "m")
            theta, dth = b.coordinate("theta", "rad")
            b.kinetic = mu * (dr**2 + r**2 * dth**2) / 2
            U = self._U(b, r)
            rdot, Lz = dr, mu * r**2 * dth
        else:
            u, du = b.coordinate("u", "1/m")
            tau, dtau = b.coordinate("time", "s")
            r = 1 / u
            theta = b.param("initial.theta") + b.t
            kappa = l**4 / (mu**3 * r0**6)
            drift = dtau - mu / (l * u**2)
            b.kinetic = l**2 * du**2 / (2 * mu) + kappa * drift**2 / 2
            U = self._U(b, r)
            b.invariant("time_momentum", "J s", kappa * drift)
            b.observable("theta", "rad", theta)
            rdot, Lz = -(l / mu) * du, l
            dth = l / (mu * r**2)
        x, y = r * sp.cos(theta), r * sp.sin(theta)
        dx = rdot * sp.cos(theta) - r * sp.sin(theta) * dth
        dy = rdot * sp.sin(theta) + r * sp.cos(theta) * dth
        centrifugal = l**2 / (2 * mu) * (1 / r**2 if self.formulation == "polar" else u**2)
        if self.exponent <= -3.0 and self.formulation == "polar":
            fallen = b.mode("fallen")
            b.potential = U * (1 - fallen)
            b.event("fall", r - b.param("capture_radius") + fallen, -1,
                    "the particle reaches the capture radius")
        else:
            b.potential = U + (centrifugal if self.formulation == "binet" else 0)
        k = b.param("force_constant") if self.exponent == -2.0 else None
        declare_orbit_quantities(b, mu, x, y, dx, dy, k=k, radius=r, angular_momentum=Lz,
                                 conserved=self.formulation == "polar")
        b.observable("radial_velocity", "m/s", rdot)
        b.observable("effective_potential", "J", U + Lz**2 / (2 * mu * r**2))
        b.frame("particle", "world", (x, y, 0))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        r, th = self.value("initial.r"), self.value("initial.theta")
        dr, dth = self.value("initial_rate.r"), self.value("initial_rate.theta")
        if self.formulation == "polar":
            return np.array([r, th]), np.array([dr, dth])
        mu, l = self.value("mass"), self.angular_momentum()
        return np.array([1.0 / r, 0.0]), np.array([-mu * dr / l, 1.0 / dth])

    def on_fall(self, t: float, y: np.ndarray) -> np.ndarray:
        """Stop at the capture radius: ṙ = θ̇ = 0, U off, its energy booked as dissipated."""
        n = len(self.coordinates)
        return merge_at_capture(self, t, y, rates=(n, n + 1), mode=2 * n + 2)

    def laws(self) -> tuple[Law, ...]:
        laws = super().laws()
        if self.falls_to_centre():
            laws = tuple(law for law in laws if law.kind not in ("energy", "energy_function")
                         and law.key != "invariant:angular_momentum")
        return laws

    def visuals(self) -> tuple[Visual, ...]:
        s = 0.04 * self.value("initial.r")
        return (Visual("sphere", "particle", radius=s, color=(255, 200, 80)),
                Visual("trail", "particle", color=(255, 200, 80)),
                Visual("axes", "world", radius=3 * s))

    def time_scale(self) -> float:
        """polar: the shortest of a revolution, the radial period about the circular orbit
        and the pericentre passage; binet: one revolution of θ (its clock is θ)."""
        if self.formulation == "binet":
            return 2 * math.pi
        dth = self.value("initial_rate.theta")
        scales = [2 * math.pi / abs(dth)]
        lo = self.radial_range()[0]
        if lo > 0.0:
            scales.append(2 * math.pi * self.value("mass") * lo**2 / abs(self.angular_momentum()))
        if self.exponent > -3.0:
            scales.append(2 * math.pi / self.radial_frequency())
        return min(scales)

    # --- first integrals and the potential ----------------------------------------------------
    def potential_function(self) -> Callable[[float], float]:
        """U(r) = K r^{n+1}/(n + 1) (K ln r for n = −1), r in m."""
        n, K = self.exponent, self.value("force_constant")
        if n == -1.0:
            return lambda r: K * math.log(r)
        return lambda r: K * r ** (n + 1) / (n + 1)

    def angular_momentum(self) -> float:
        """l = μ r₀² θ̇₀ (PHYS0500 line 839)."""
        return self.value("mass") * self.value("initial.r") ** 2 * self.value(
            "initial_rate.theta")

    def orbit_energy(self) -> float:
        """E = ½μ(ṙ² + r²θ̇²) + U(r) (line 847)."""
        r, dr, dth = (self.value("initial.r"), self.value("initial_rate.r"),
                      self.value("initial_rate.theta"))
        return 0.5 * self.value("mass") * (dr**2 + r**2 * dth**2) + self.potential_function()(r)

    def effective_potential(self, r: float) -> float:
        """U_eff = U + l²/(2μr²) (§4.5)."""
        return effective_potential(self.potential_function(), self.value("mass"),
                                   self.angular_momentum())(r)

    def radial_range(self) -> tuple[float, float]:
        """(r_min, r_max) of the motion (r_max = ∞ unbound, r_min = 0 falling)."""
        r0 = self.value("initial.r")
        return nearest_turning_points(self.energy_gap, r0, self.value("initial_rate.r"),
                                      r_min=0.5 * self.value("capture_radius"), r_max=1e6 * r0)

    def energy_gap(self, r: np.ndarray | float) -> np.ndarray | float:
        """E − U_eff(r) = ½μṙ₀² − [U_eff(r) − U_eff(r₀)], the difference in closed form
        (expm1 and log1p of ln(r/r₀)), so that it keeps its digits at every r, however close
        to r₀ (E − U_eff(r) would lose them to cancellation near the apsides of a nearly
        circular orbit, where the quadratures need them)."""
        r0, n, K = self.value("initial.r"), self.exponent, self.value("force_constant")
        mu, l = self.value("mass"), self.angular_momentum()
        x = np.log1p((np.asarray(r, dtype=float) - r0) / r0)  # ln(r/r₀)
        dU = K * x if n == -1.0 else K * r0 ** (n + 1) * np.expm1((n + 1) * x) / (n + 1)
        dC = l * l / (2 * mu * r0 * r0) * np.expm1(-2 * x)
        gap = 0.5 * mu * self.value("initial_rate.r") ** 2 - dU - dC
        return float(gap) if np.ndim(gap) == 0 else gap

    def falls_to_centre(self) -> bool:
        """True when nothing stops the particle before the capture radius (n ≤ −3 only)."""
        return self.exponent <= -3.0 and self.radial_range()[0] <= self.value("capture_radius")

    # --- analyses (functions of E and l, not of one state) ------------------------------------
    def _bound(self) -> tuple[float, float]:
        lo, hi = self.radial_range()
        if not (math.isfinite(hi) and lo > 0.0):
            raise ValueError("the orbit is not bound: no apsides")
        return lo, hi

    def apsidal_angle(self) -> float:
        """The angle from one apsis to the next (``_central.apsidal_angle``); π/√(n+3) in the
        limit of a circular orbit (returned there)."""
        lo, hi = self._bound()
        if hi - lo <= 1e-9 * hi:
            return self.near_circular_apsidal_angle()
        return apsidal_angle(self.energy_gap, self.value("mass"), self.angular_momentum(), lo,
                             hi)

    def precession_per_orbit(self) -> float:
        """How far the pericentre advances per radial period: Δθ − 2π = 2·apsidal − 2π
        (negative: it regresses; 0 for Bertrand's n = −2 and 1)."""
        return 2.0 * self.apsidal_angle() - 2.0 * math.pi

    def radial_period(self) -> float:
        """Time from pericentre to pericentre: 2 ∫ dr/ṙ between the apsides (eq. 4.3)."""
        lo, hi = self._bound()
        if hi - lo <= 1e-9 * hi:
            return 2 * math.pi / self.radial_frequency()
        return 2.0 * orbit_integral(self.energy_gap, self.value("mass"), lo, hi)

    def near_circular_apsidal_angle(self) -> float:
        """π/√(n + 3): the apsidal angle of orbits close to circular (n > −3)."""
        if self.exponent <= -3.0:
            raise ValueError("no stable circular orbit for n ≤ −3")
        return math.pi / math.sqrt(self.exponent + 3.0)

    def circular_radius(self) -> float:
        """r₀ of the circular orbit with this l: K r₀ⁿ = l²/(μ r₀³), r₀ = (l²/μK)^{1/(n+3)}."""
        if self.exponent == -3.0:
            raise ValueError("n = −3 has a circular orbit only for l² = μK, at any radius")
        mu, K, l = self.value("mass"), self.value("force_constant"), self.angular_momentum()
        return (l * l / (mu * K)) ** (1.0 / (self.exponent + 3.0))

    def radial_frequency(self) -> float:
        """Small radial oscillations about the circular orbit of the same l (§4.5.1):
        ω_r = √(U_eff″(r₀)/μ), U_eff″(r₀) = (n + 3) K r₀^{n−1}, i.e. √(n + 3) θ̇₀."""
        if self.exponent <= -3.0:
            raise ValueError("no stable circular orbit for n ≤ −3")
        r0, K = self.circular_radius(), self.value("force_constant")
        return math.sqrt((self.exponent + 3.0) * K * r0 ** (self.exponent - 1.0)
                         / self.value("mass"))

    def curves(self) -> tuple[Curve, ...]:
        """U_eff(r) with the orbit's energy and its turning points (none where the orbit's
        radial range cannot be found: a fall to the centre)."""
        from mechsim.systems.curves import orbit_curves

        return orbit_curves(self)


MODEL = PowerLawOrbit
