"""Planar isotropic harmonic oscillator, Cartesian and polar formulations.

Sources: PHYS0500 §1.2 "Harmonic Oscillations in Two Dimensions" (lines 67–85) and “Energy and
Hamiltonians: Part 3 – Examples”, Case 3 "Energy and Hamiltonians, Case 3 – E = h, both conserved:
Planar SHO" (L416–470):
V = ½ k (x² + y²), m r̈ = −k r, L = ½ m (ṙ² + r²θ̇²) − ½ k r² in polar coordinates.

Conventions: motion in the x–y plane of the ``center`` frame (world z up, right-handed, θ
counter-clockwise from +x). Both formulations take Cartesian initial conditions
(``initial.x`` …); the polar one converts them (r, θ, ṙ, θ̇) and needs an orbit that avoids
r = 0 (nonzero angular momentum). The document's initial state S̄₀ = (R, 0, 0, Rω₀) is the
circular orbit ``initial.x = R``, ``initial_rate.y = R√(k/m)``.

Document typos corrected (catalog 000 S6, 003 §1.2): the point transformation is printed as
x = r cos ω₀t, y = r sin ω₀t (L434–437) but the Lagrangian that follows uses x = r cos θ,
y = r sin θ, which is what is used here; the radial Euler–Lagrange equation m r̈ + k r = 0
(L445) misses the centrifugal term −m r θ̇² (the engine derives it from L; the numerical form
at L452 has it); the "energy" printed at L463–468 is kinetic energy only; PHYS0500 line 83
uses one amplitude A for both axes (they are independent in general).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import number, positive
from mechsim.systems._oscillator import free_solution, state_rows
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class PlanarOscillator(LagrangianModel):
    id = "planar_oscillator"
    title = "Planar isotropic harmonic oscillator (Cartesian and polar)"
    source = ("PHYS0500 – Advanced Classical Mechanics, §1.2 (Harmonic Oscillations in Two "
              "Dimensions); “Energy and Hamiltonians: Part 3 – Examples” (blog post), Case 3")
    formulations = ("cartesian", "polar")
    oracles = ("exact elliptic orbit x, y = x₀cos ω₀t + (v₀/ω₀)sin ω₀t, period 2π/ω₀; "
               "E = h, L_z, E_x, E_y conserved; both forms agree; r ≡ R on the circular orbit")
    parameters = (
        positive("mass", 1.0, "kg", "mass m"),
        positive("spring_constant", 4.0, "N/m", "spring constant k of V = ½k(x² + y²)"),
        number("initial.x", 1.0, "m", "initial x"),
        number("initial.y", 0.0, "m", "initial y"),
        number("initial_rate.x", 0.0, "m/s", "initial ẋ"),
        number("initial_rate.y", 1.0, "m/s", "initial ẏ"),
    )

    def check(self) -> None:
        if self.formulation == "polar":
            x, y = self.value("initial.x"), self.value("initial.y")
            lz = x * self.value("initial_rate.y") - y * self.value("initial_rate.x")
            if lz == 0.0:
                raise ParameterError("formulation", "polar needs an orbit that avoids r = 0: "
                                     "the initial angular momentum x ẏ − y ẋ must be nonzero")

    def declare(self, b: LagrangianBuilder) -> None:
        m, k = b.param("mass"), b.param("spring_constant")
        if self.formulation == "cartesian":
            x, dx = b.coordinate("x", "m")
            y, dy = b.coordinate("y", "m")
            b.kinetic = m * (dx**2 + dy**2) / 2
            b.potential = k * (x**2 + y**2) / 2
            r, theta = sp.sqrt(x**2 + y**2), sp.atan2(y, x)
        else:
            r, dr = b.coordinate("r", "m")
            theta, dth = b.coordinate("theta", "rad")
            b.kinetic = m * (dr**2 + r**2 * dth**2) / 2
            b.potential = k * r**2 / 2
            x, y = r * sp.cos(theta), r * sp.sin(theta)
            dx = dr * sp.cos(theta) - r * dth * sp.sin(theta)
            dy = dr * sp.sin(theta) + r * dth * sp.cos(theta)
            b.observable("x", "m", x)
            b.observable("y", "m", y)
        b.invariant("angular_momentum", "kg m^2/s", m * (x * dy - y * dx))
        b.invariant("energy_x", "J", m * dx**2 / 2 + k * x**2 / 2)
        b.invariant("energy_y", "J", m * dy**2 / 2 + k * y**2 / 2)
        b.observable("radius", "m", r)
        b.observable("polar_angle", "rad", theta)
        b.frame("center", "world", (0, 0, 0))
        b.frame("polar", "center", (0, 0, 0), (0, 0, sp.sin(theta / 2), sp.cos(theta / 2)))
        b.frame("mass", "center", (x, y, 0))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        x, y = self.value("initial.x"), self.value("initial.y")
        vx, vy = self.value("initial_rate.x"), self.value("initial_rate.y")
        if self.formulation == "cartesian":
            return np.array([x, y]), np.array([vx, vy])
        r, th = math.hypot(x, y), math.atan2(y, x)
        return (np.array([r, th]),
                np.array([(x * vx + y * vy) / r, (x * vy - y * vx) / (r * r)]))

    def visuals(self) -> tuple[Visual, ...]:
        return (Visual("sphere", "center", radius=0.03, color=(150, 150, 150)),
                Visual("link", "center", to_frame="mass", radius=0.01, color=(200, 200, 90)),
                Visual("sphere", "mass", radius=0.08),
                Visual("trail", "mass", color=(120, 170, 255)),
                Visual("axes", "polar", radius=0.3))

    def time_scale(self) -> float:
        return 2 * math.pi / self.natural_frequency()

    # --- analytic oracles (PHYS0500 §1.2, “Energy and Hamiltonians: Part 3 – Examples”, Case 3) ---
    def natural_frequency(self) -> float:
        """ω₀ = √(k/m)."""
        return math.sqrt(self.value("spring_constant") / self.value("mass"))

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray,
                  work_terms: bool = True) -> np.ndarray | None:
        """Cartesian form: each axis a free oscillator from the state at t₀ (no work terms)."""
        if self.formulation != "cartesian":
            return None
        w = self.natural_frequency()
        x, vx = free_solution(np.asarray(t) - t0, y0[0], y0[2], w)
        y, vy = free_solution(np.asarray(t) - t0, y0[1], y0[3], w)
        return state_rows(y0, [x, y, vx, vy])

    def exact_position(self, t: np.ndarray) -> np.ndarray:
        """(x, y)(t): each axis a 1-D oscillator with frequency ω₀ (PHYS0500 line 83)."""
        w = self.natural_frequency()
        x, _ = free_solution(t, self.value("initial.x"), self.value("initial_rate.x"), w)
        y, _ = free_solution(t, self.value("initial.y"), self.value("initial_rate.y"), w)
        return np.stack([x, y], axis=-1)


MODEL = PlanarOscillator
