"""Kepler problem: relative motion of two bodies under U = −k/r, in the orbital plane.

Source: PHYS0500 ch. 4 ("Central Force Motion", §4.1 reduced mass, §4.6 planetary
motion; conic table line 996). The Laplace–Runge–Lenz vector is not in the document (catalog:
[SUPPLEMENT]); it is used here as an invariant because it is conserved only for 1/r.

Conventions: Cartesian coordinates (x, y) of the relative position r = r₁ − r₂ in the orbital
plane, z along the angular momentum (right-handed, counter-clockwise orbit). The orbit is given
by its elements: ``semi_major_axis`` a and ``eccentricity`` e (0 ≤ e < 1), starting at
pericentre on +x. k = μ GM with ``reduced_mass`` μ and ``gravitational_parameter`` GM = G(m₁+m₂);
the document's ε = √(1 + 2El²/(μk²)) (its line 988 has √(2 + 2El²/(μk)), a typo).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.params import Parameter, positive
from mechsim.systems._central import (
    declare_orbit_quantities,
    eccentric_anomaly,
    kepler_propagate,
)
from mechsim.systems._oscillator import state_rows
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class Kepler(LagrangianModel):
    id = "kepler"
    title = "Kepler problem (two-body relative orbit)"
    source = ("PHYS0500 – Advanced Classical Mechanics, §4.1 (Reduced Mass) and §4.6 (Planetary "
              "Motion, Kepler's laws)")
    oracles = "Kepler equation position, period 2π√(a³/GM), apsides a(1±e), |A| = μke"
    parameters = (
        positive("gravitational_parameter", 1.0, "m^3/s^2", "GM = G (m₁ + m₂)"),
        positive("reduced_mass", 1.0, "kg", "reduced mass μ = m₁m₂/(m₁+m₂)"),
        positive("semi_major_axis", 1.0, "m", "semi-major axis a"),
        Parameter("eccentricity", 0.5, "", "eccentricity e of the ellipse", minimum=0.0,
                  maximum=1.0, exclusive_maximum=True),
    )

    def declare(self, b: LagrangianBuilder) -> None:
        x, dx = b.coordinate("x", "m")
        y, dy = b.coordinate("y", "m")
        GM, mu = b.param("gravitational_parameter"), b.param("reduced_mass")
        r = sp.sqrt(x**2 + y**2)
        k = mu * GM
        b.kinetic = mu * (dx**2 + dy**2) / 2
        b.potential = -k / r
        declare_orbit_quantities(b, mu, x, y, dx, dy, k=k, radius=r)
        b.observable("true_anomaly", "rad", sp.atan2(y, x))
        b.frame("perifocal", "world", (0, 0, 0))
        b.frame("body", "perifocal", (x, y, 0))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        a, e, GM = self.value("semi_major_axis"), self.value("eccentricity"), \
            self.value("gravitational_parameter")
        rp = a * (1 - e)
        return np.array([rp, 0.0]), np.array([0.0, math.sqrt(GM * (1 + e) / rp)])

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray,
                  work_terms: bool = True) -> np.ndarray | None:
        """Exact orbit from any elliptic state (f and g functions, Kepler's equation)."""
        out = kepler_propagate(self.value("gravitational_parameter"), y0[:2], y0[2:4],
                               np.asarray(t) - t0)
        if out is None:
            return None
        pos, vel = out
        return state_rows(y0, [pos[:, 0], pos[:, 1], vel[:, 0], vel[:, 1]])

    def time_scale(self) -> float:
        """Pericentre passage time 2π √(r_p³ / (GM (1 + e))): what limits a fixed step."""
        a, e = self.value("semi_major_axis"), self.value("eccentricity")
        return 2 * math.pi * math.sqrt((a * (1 - e)) ** 3 /
                                       (self.value("gravitational_parameter") * (1 + e)))

    # --- analytic oracles (PHYS0500 §4.6; Kepler's equation is a catalog supplement) -------
    def period(self) -> float:
        """τ = 2π √(a³ / GM) (Kepler III, line 1042 with k = μ GM)."""
        return 2 * math.pi * math.sqrt(self.value("semi_major_axis") ** 3
                                       / self.value("gravitational_parameter"))

    def apsides(self) -> tuple[float, float]:
        """r_min = a(1 − e), r_max = a(1 + e) (lines 1014–1016)."""
        a, e = self.value("semi_major_axis"), self.value("eccentricity")
        return a * (1 - e), a * (1 + e)

    def position_at(self, t: np.ndarray) -> np.ndarray:
        """Exact (x, y) at times t from Kepler's equation M = E − e sin E (Newton iteration)."""
        a, e = self.value("semi_major_axis"), self.value("eccentricity")
        E = eccentric_anomaly(2 * math.pi * np.asarray(t, dtype=float) / self.period(), e)
        return np.stack([a * (np.cos(E) - e), a * math.sqrt(1 - e * e) * np.sin(E)], axis=-1)

MODEL = Kepler
