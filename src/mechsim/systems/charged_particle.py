"""Charged particle in uniform static electric and magnetic fields, from the potential Lagrangian.

Sources: Lecture 10 ("Maxwell's equations and potentials", "charged particle
in an external field", "uniform magnetic field", "gauge transformation", eqs. 10.51–10.67) and
Introduction to analytical mechanics, “Lagrange's equation of motion velocity dependent potentials”
(velocity-dependent generalized potential); the two moving charges of “Action and Reaction”, Case 3
(L827–891) as module functions.

L = ½ m ṙ² − q φ + q ṙ·A (eq. 10.53), with B = B ẑ (B > 0 along +z) and a uniform E, so
φ = −E·r. The q ṙ·A term goes in the engine's ``linear`` slot: it shapes the equations and the
energy function but not E = ½ m v² + q φ, which is conserved (static fields; the magnetic force
does no work, so the speed is constant when E = 0).

Formulations (same physics, different gauge or coordinates; trajectories must agree):
- ``cylindrical``: the document's symmetric gauge A = ½ B × r in (ρ, φ, z), eq. 10.60;
  L = ½ m (ρ̇² + ρ² φ̇² + ż²) + ½ q B ρ² φ̇ − q φ. Its canonical momentum
  p_φ = m ρ² φ̇ + ½ q B ρ² (not the mechanical m ρ² φ̇) is conserved when E has no component
  in the x–y plane (then φ is cyclic).
- ``symmetric``: the same gauge in Cartesian (x, y, z), A = ½ B (−y, x, 0).
- ``landau``: A = (0, B x, 0), so A' = A − ∇Λ with Λ = −½ B x y (eq. 10.63 convention);
  there the canonical p_y = m ẏ + q B x is conserved when E_y = 0.
In every gauge the pseudo-momentum K = m v − q r × B − q E t is conserved (gauge invariant).

Oracles: cyclotron angular frequency ω_c = |q| B / m, gyration sense φ̇ = −q B / m (clockwise
about +z for q B > 0, eq. 10.62); Larmor radius m |u⊥| / (|q| B) with u = v − v_d; pitch
2π m v_z / (|q| B); E × B drift v_d = E × B / B² (Introduction to analytical mechanics, “Lagrange's
equation of motion velocity dependent potentials”). The text garbles p_φ (L433–436, "2 2 2p m qBj r
j r= +"); it is restored as above. Initial conditions are Cartesian for every formulation.

Two moving charges (“Action and Reaction”, Case 3): ``two_charge_forces`` gives the instantaneous
Coulomb + Biot–Savart forces F₁₂ (on 1 due to 2) and F₂₁. Document errors fixed: the magnetic term
carries v² (L859–863 drop it), v̂ × (v̂ × ĵ) = sin α cos α î − cos² α ĵ (L863 prints −sin² α), and
the Coulomb force between like charges is repulsive (+ĵ on charge 1, not −ĵ). F₁₂ ≠ −F₂₁ in general
("cross the T": F₁₂ = 0, |F₂₁| = μ₀ q² v² / (4π ρ²)). The missing mechanical momentum is
carried by the field: ``interaction_field_momentum`` (ε₀ ∫ E × B dV of the pair, to order
v²/c², = q₁ A₂(r₁) + q₂ A₁(r₂) with the Darwin / Coulomb-gauge vector potential) changes at
exactly −(F₁₂ + F₂₁ + induction forces), the induction (−∂A/∂t) forces being the part of the
field the instantaneous Biot–Savart picture leaves out (``induction_forces``).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit
from scipy.constants import epsilon_0, mu_0

from mechsim.codegen.contract import CLOSED_FORM_SIGNATURE
from mechsim.errors import ParameterError
from mechsim.params import number, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


@njit(cache=True)
def _gyrate(x0: float, y0: float, z0: float, ux: float, uy: float, vz: float, vdx: float,
            vdy: float, az: float, om: float, t: np.ndarray, r: np.ndarray,
            v: np.ndarray) -> None:
    """Rows of r(t), v(t) (see ``ChargedParticle.cartesian_motion``), one loop over t."""
    for i in range(t.size):
        ti = t[i]
        c, s = math.cos(om * ti), math.sin(om * ti)
        h = math.sin(0.5 * om * ti)
        S, C = s / om, 2.0 * h * h / om  # ∫ cos, ∫ sin
        r[i, 0] = x0 + vdx * ti + ux * S - uy * C
        r[i, 1] = y0 + vdy * ti + ux * C + uy * S
        r[i, 2] = z0 + vz * ti + 0.5 * az * ti * ti
        v[i, 0] = vdx + ux * c - uy * s
        v[i, 1] = vdy + ux * s + uy * c
        v[i, 2] = vz + az * ti

@njit(CLOSED_FORM_SIGNATURE, cache=True)
def _cartesian_rows(t0: float, y0: np.ndarray, t: np.ndarray, c: np.ndarray,
                    rows: np.ndarray) -> bool:
    """The Cartesian formulations' closed form (``ChargedParticle.propagate``): rows [r, v,
    rest of y0] at the times t from y0 at t0; c = [q E_z / m, v_d (x, y), Ω]."""
    _gyrate(y0[0], y0[1], y0[2], y0[3] - c[1], y0[4] - c[2], y0[5], c[1], c[2], c[0], c[3],
            t - t0, rows[:, 0:3], rows[:, 3:6])
    for i in range(t.size):
        for j in range(6, y0.size):
            rows[i, j] = y0[j]
    return True


class ChargedParticle(LagrangianModel):
    id = "charged_particle"
    title = "Charged particle in uniform E and B (symmetric and Landau gauges)"
    source = ("Lecture 10: The Methods of Lagrange Revisited, charged particle in an "
              "electromagnetic field, uniform B, gauge transformation (eqs. 10.51–10.67); "
              "Introduction to analytical mechanics, “Lagrange's equation of motion velocity "
              "dependent potentials”; “Action and Reaction” (blog post), Case 3 (two moving "
              "charges)")
    formulations = ("cylindrical", "symmetric", "landau", "hamiltonian")
    oracles = ("exact helix/cycloid (cyclotron ω_c = |q|B/m, Larmor radius, pitch, E×B drift); "
               "p_φ = mρ²φ̇ + ½qBρ² conserved; gauges agree; two-charge F₁₂ ≠ −F₂₁ balanced by "
               "field momentum")
    parameters = (
        positive("mass", 1.0, "kg", "particle mass m"),
        number("charge", 1.0, "C", "particle charge q (nonzero)"),
        positive("magnetic_field", 2.0, "T", "magnetic flux density B along +z"),
        number("electric_field.x", 0.0, "V/m", "uniform electric field, x component"),
        number("electric_field.y", 0.0, "V/m", "uniform electric field, y component"),
        number("electric_field.z", 0.0, "V/m", "uniform electric field, z component"),
        number("initial.x", 1.0, "m", "initial x"),
        number("initial.y", 0.0, "m", "initial y"),
        number("initial.z", 0.0, "m", "initial z"),
        number("initial_rate.x", 0.0, "m/s", "initial ẋ"),
        number("initial_rate.y", -1.5, "m/s", "initial ẏ"),
        number("initial_rate.z", 0.2, "m/s", "initial ż"),
    )

    def check(self) -> None:
        if self.value("charge") == 0.0:
            raise ParameterError("charge", "must be nonzero (a neutral particle feels no field)")
        if self.formulation == "cylindrical" and math.hypot(
                self.value("initial.x"), self.value("initial.y")) == 0.0:
            raise ParameterError("initial.x", "the cylindrical formulation cannot start on the "
                                 "axis ρ = 0; use formulation symmetric")

    def _in_plane_field(self) -> bool:
        return self.value("electric_field.x") != 0.0 or self.value("electric_field.y") != 0.0

    def declare(self, b: LagrangianBuilder) -> None:
        m, q, B = b.param("mass"), b.param("charge"), b.param("magnetic_field")
        Ex, Ey, Ez = (b.param("electric_field.x"), b.param("electric_field.y"),
                      b.param("electric_field.z"))
        t = b.t
        if self.formulation == "cylindrical":
            rho, drho = b.coordinate("rho", "m")
            phi, dphi = b.coordinate("phi", "rad")
            z, dz = b.coordinate("z", "m")
            x, y = rho * sp.cos(phi), rho * sp.sin(phi)
            dx = drho * sp.cos(phi) - rho * sp.sin(phi) * dphi
            dy = drho * sp.sin(phi) + rho * sp.cos(phi) * dphi
            b.kinetic = m * (drho**2 + rho**2 * dphi**2 + dz**2) / 2
            b.linear = q * B * rho**2 * dphi / 2  # q ṙ·A with A_φ = ½ B ρ
        else:
            x, dx = b.coordinate("x", "m")
            y, dy = b.coordinate("y", "m")
            z, dz = b.coordinate("z", "m")
            b.kinetic = m * (dx**2 + dy**2 + dz**2) / 2
            A = (-B * y / 2, B * x / 2) if self.formulation == "symmetric" else (0, B * x)
            b.linear = q * (dx * A[0] + dy * A[1])
        b.potential = -q * (Ex * x + Ey * y + Ez * z)  # q φ with φ = −E·r

        # pseudo-momentum K = m v − q r × B − q E t (conserved in every gauge)
        b.invariant("pseudo_momentum_x", "kg m/s", m * dx - q * B * y - q * Ex * t)
        b.invariant("pseudo_momentum_y", "kg m/s", m * dy + q * B * x - q * Ey * t)
        b.invariant("pseudo_momentum_z", "kg m/s", m * dz - q * Ez * t)
        Lz = m * (x * dy - y * dx)
        if self.formulation == "landau":
            p_can, name, unit, cyclic = (m * dy + q * B * x, "canonical_momentum_y", "kg m/s",
                                         self.value("electric_field.y") == 0.0)
        else:
            p_can, name, unit, cyclic = (Lz + q * B * (x**2 + y**2) / 2,
                                         "canonical_angular_momentum", "kg m^2/s",
                                         not self._in_plane_field())
        (b.invariant if cyclic else b.observable)(name, unit, p_can)
        b.observable("mechanical_angular_momentum", "kg m^2/s", Lz)
        b.observable("speed", "m/s", sp.sqrt(dx**2 + dy**2 + dz**2))
        # guiding centre r_c = r − (m/(qB)) ẑ × (v − v_d), v_d = E × B / B² = (E_y, −E_x, 0)/B
        ux, uy = dx - Ey / B, dy + Ex / B
        xc, yc = x + m * uy / (q * B), y - m * ux / (q * B)
        b.observable("guiding_centre_x", "m", xc)
        b.observable("guiding_centre_y", "m", yc)
        b.observable("radius", "m", sp.sqrt(x**2 + y**2))
        b.frame("field", "world", (0, 0, 0))
        b.frame("particle", "world", (x, y, z))
        b.frame("guiding_centre", "world", (xc, yc, z))

    def visuals(self) -> tuple[Visual, ...]:
        r = max(self.larmor_radius(), 1e-3)
        return (Visual("arrow", "field", points=((0.0, 0.0, 2 * r),), radius=0.02 * r,
                       color=(255, 120, 120)),
                Visual("sphere", "particle", radius=0.06 * r),
                Visual("trail", "particle", color=(120, 170, 255)),
                Visual("sphere", "guiding_centre", radius=0.03 * r, color=(255, 200, 80)),
                Visual("trail", "guiding_centre", color=(255, 200, 80)))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        r = np.array([self.value(f"initial.{c}") for c in "xyz"])
        v = np.array([self.value(f"initial_rate.{c}") for c in "xyz"])
        if self.formulation != "cylindrical":
            return r, v
        rho = math.hypot(r[0], r[1])
        phi = math.atan2(r[1], r[0])
        return (np.array([rho, phi, r[2]]),
                np.array([(r[0] * v[0] + r[1] * v[1]) / rho,
                          (r[0] * v[1] - r[1] * v[0]) / rho**2, v[2]]))

    def time_scale(self) -> float:
        return 2 * math.pi / self.cyclotron_frequency()

    # --- closed form -------------------------------------------------------------------------
    def cartesian_motion(self, r0: np.ndarray, v0: np.ndarray, t: np.ndarray
                         ) -> tuple[np.ndarray, np.ndarray]:
        """r(t), v(t) (rows) from r(0) = r0, v(0) = v0: free acceleration q E_z/m along B, and
        across it the E × B drift v_d plus the gyration velocity u = v⊥ − v_d turning at
        Ω = −qB/m: u(t) = R_z(Ωt) u₀, r⊥(t) = r⊥₀ + v_d t + ∫₀ᵗ u (sin Ωt/Ω and 2 sin²(Ωt/2)/Ω,
        no cancellation at small Ωt)."""
        t = np.asarray(t, dtype=float)
        az, vdx, vdy, om = self._motion_constants()
        r, v = np.empty((t.size, 3)), np.empty((t.size, 3))
        _gyrate(float(r0[0]), float(r0[1]), float(r0[2]), float(v0[0] - vdx),
                float(v0[1] - vdy), float(v0[2]), float(vdx), float(vdy), float(az), float(om),
                t, r, v)
        return r, v

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray,
                  work_terms: bool = True) -> np.ndarray | None:
        """Closed form in every formulation (``cartesian_motion``; static fields: the work
        terms stay as they are). Cylindrical: φ continues φ(t₀) through the angle swept about
        the axis, summed over intervals short enough to be unambiguous (the path over an
        interval stays within |v|max·h of its start; where that ball reaches the axis the
        interval is halved); None if the path meets the axis (where φ is undefined)."""
        t = np.asarray(t, dtype=float)
        if self.formulation != "cylindrical":
            rows = np.empty((t.size, len(y0)))
            _cartesian_rows(float(t0), np.ascontiguousarray(y0, dtype=float),
                            np.ascontiguousarray(t), self._motion_constants(), rows)
            return rows
        rho0, phi0, z0, drho0, dphi0, dz0 = (float(x) for x in y0[:6])
        c0, s0 = math.cos(phi0), math.sin(phi0)
        r0 = np.array([rho0 * c0, rho0 * s0, z0])
        v0 = np.array([drho0 * c0 - rho0 * s0 * dphi0, drho0 * s0 + rho0 * c0 * dphi0, dz0])
        r, v = self.cartesian_motion(r0, v0, t - t0)
        phi = self._swept_angle(r0, v0, t - t0)
        if phi is None:
            return None
        rho = np.hypot(r[:, 0], r[:, 1])
        rows = np.repeat(np.asarray(y0, dtype=float)[None, :], t.size, axis=0)
        rows[:, 0], rows[:, 1], rows[:, 2] = rho, phi0 + phi, r[:, 2]
        rows[:, 3] = (r[:, 0] * v[:, 0] + r[:, 1] * v[:, 1]) / rho
        rows[:, 4] = (r[:, 0] * v[:, 1] - r[:, 1] * v[:, 0]) / rho**2
        rows[:, 5] = v[:, 2]
        return rows

    def closed_form_kernel(self, y0: np.ndarray) -> tuple[Any, np.ndarray] | None:
        """``_cartesian_rows`` in the Cartesian formulations (cylindrical: ``propagate``)."""
        if self.formulation == "cylindrical":
            return None
        return _cartesian_rows, self._motion_constants()

    def _motion_constants(self) -> np.ndarray:
        """[q E_z / m, v_d (x, y), Ω]: the constants of ``cartesian_motion`` and
        ``_cartesian_rows``."""
        vd = self.drift_velocity()
        return np.array([self.value("charge") * self.value("electric_field.z")
                         / self.value("mass"), vd[0], vd[1], self.gyration_rate()])

    def _swept_angle(self, r0: np.ndarray, v0: np.ndarray, t: np.ndarray) -> np.ndarray | None:
        """Angle swept about the z axis by the path from time 0 to each t (increasing, ≥ 0)."""
        speed = float(np.hypot(*self.drift_velocity()[:2])
                      + np.hypot(*(v0[:2] - self.drift_velocity()[:2])))
        edges = np.concatenate([[0.0], t])
        out = np.zeros(t.size)
        total = 0.0
        for k in range(t.size):
            pending = [(edges[k], edges[k + 1])]
            swept = 0.0
            while pending:
                a, b = pending.pop()
                if b <= a:
                    continue
                r, _ = self.cartesian_motion(r0, v0, np.array([a, b]))
                if math.hypot(r[0, 0], r[0, 1]) > speed * (b - a) * (1.0 + 1e-9):
                    # the path stays in a disc not containing the axis: |swept| < π
                    swept += math.atan2(r[0, 0] * r[1, 1] - r[0, 1] * r[1, 0],
                                        r[0, 0] * r[1, 0] + r[0, 1] * r[1, 1])
                elif b - a <= 1e-12 * max(1.0, b):
                    return None  # through the axis
                else:
                    mid = 0.5 * (a + b)
                    pending += [(mid, b), (a, mid)]
            total += swept
            out[k] = total
        return out

    # --- analytic results (Lecture 10, uniform B (eqs. 10.51–10.67), Introduction to analytical
    # mechanics, “Lagrange's equation of motion velocity dependent potentials”)
    def cyclotron_frequency(self) -> float:
        """ω_c = |q| B / m."""
        return abs(self.value("charge")) * self.value("magnetic_field") / self.value("mass")

    def gyration_rate(self) -> float:
        """Signed φ̇ of the gyration about its centre: −q B / m (eq. 10.62)."""
        return -self.value("charge") * self.value("magnetic_field") / self.value("mass")

    def drift_velocity(self) -> np.ndarray:
        """v_d = E × B / B² (with B = B ẑ: (E_y, −E_x, 0) / B)."""
        B = self.value("magnetic_field")
        return np.array([self.value("electric_field.y") / B,
                         -self.value("electric_field.x") / B, 0.0])

    def larmor_radius(self) -> float:
        """m |u⊥| / (|q| B), u = v₀ − v_d the gyration velocity."""
        u = np.array([self.value("initial_rate.x"), self.value("initial_rate.y")]) \
            - self.drift_velocity()[:2]
        return self.value("mass") * float(np.hypot(*u)) / (
            abs(self.value("charge")) * self.value("magnetic_field"))

    def pitch(self) -> float:
        """Advance along B per gyration, 2π m v_z / (|q| B) (for E_z = 0)."""
        return 2 * math.pi * self.value("initial_rate.z") / self.cyclotron_frequency()


MODEL = ChargedParticle


# --- two moving point charges (“Action and Reaction”, Case 3) -------------------------------------
def _vec(a: np.ndarray | tuple[float, ...]) -> np.ndarray:
    return np.asarray(a, dtype=float)


def two_charge_forces(q1: float, q2: float, r1: np.ndarray, r2: np.ndarray, v1: np.ndarray,
                      v2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Instantaneous Coulomb + Biot–Savart forces (F₁₂ on charge 1 due to 2, F₂₁ on 2 due to 1).

    E_j(r) = q_j R / (4π ε₀ R³), B_j(r) = μ₀ q_j v_j × R / (4π R³), R = r − r_j; F = q (E + v × B).
    """
    r1, r2, v1, v2 = _vec(r1), _vec(r2), _vec(v1), _vec(v2)

    def force(qa: float, ra: np.ndarray, va: np.ndarray, qb: float, rb: np.ndarray,
              vb: np.ndarray) -> np.ndarray:
        R = ra - rb
        d3 = float(np.linalg.norm(R)) ** 3
        E = qb * R / (4 * math.pi * epsilon_0 * d3)
        B = mu_0 * qb * np.cross(vb, R) / (4 * math.pi * d3)
        return qa * (E + np.cross(va, B))

    return force(q1, r1, v1, q2, r2, v2), force(q2, r2, v2, q1, r1, v1)


def darwin_vector_potential(q: float, r_source: np.ndarray, v_source: np.ndarray,
                            r: np.ndarray) -> np.ndarray:
    """A(r) of a slow charge in the Coulomb gauge to order v/c²:
    μ₀ q [v + (v·R̂) R̂] / (8π R), R = r − r_source (its curl is the Biot–Savart B)."""
    R = _vec(r) - _vec(r_source)
    d = float(np.linalg.norm(R))
    n = R / d
    v = _vec(v_source)
    return mu_0 * q * (v + np.dot(v, n) * n) / (8 * math.pi * d)


def induction_forces(q1: float, q2: float, r1: np.ndarray, r2: np.ndarray, v1: np.ndarray,
                     v2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Forces of the induced electric fields −∂A/∂t for uniformly moving charges: on 1,
    q₁ (v₂·∇_R) A₂ = q₁ μ₀ q₂ R [v₂² − 3 (v₂·R̂)²] / (8π R³), R = r₁ − r₂; likewise on 2."""
    def one(qa: float, ra: np.ndarray, qb: float, rb: np.ndarray, vb: np.ndarray) -> np.ndarray:
        R = _vec(ra) - _vec(rb)
        d = float(np.linalg.norm(R))
        vb = _vec(vb)
        return qa * mu_0 * qb * R * (vb @ vb - 3 * (vb @ R / d) ** 2) / (8 * math.pi * d**3)

    return one(q1, r1, q2, r2, v2), one(q2, r2, q1, r1, v1)


def interaction_field_momentum(q1: float, q2: float, r1: np.ndarray, r2: np.ndarray,
                               v1: np.ndarray, v2: np.ndarray) -> np.ndarray:
    """Momentum of the pair's interaction field, ε₀ ∫ (E₁ × B₂ + E₂ × B₁) dV = q₁ A₂(r₁) +
    q₂ A₁(r₂) (Coulomb-gauge identity; the Darwin Lagrangian's interaction momentum)."""
    return (q1 * darwin_vector_potential(q2, r2, v2, r1)
            + q2 * darwin_vector_potential(q1, r1, v1, r2))
