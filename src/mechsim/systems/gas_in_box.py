"""A gas in a container: N point particles in a rectangular box with elastic walls.

Source: Introduction to analytical mechanics, "Classification of constraints" (L159–167):
constraints "expressed as inequalities. Gas molecules contained in container" — the non-holonomic
(one-sided) example. Each coordinate obeys −ℓₐ/2 ≤ xₐ ≤ ℓₐ/2; inside, the particles are free (L = Σ
½ m |ṙᵢ|², no potential: an ideal gas of point particles, which never meet one another). The
inequality acts only at contact, as an impulse: a state event where a particle reaches a wall while
moving outward, handled by reversing that velocity component (an elastic, frictionless wall). So the
kinetic energy, the kinetic energy of each axis and every |vₐ| of every particle are
conserved, and the wall ⟂ axis a receives the impulse 2m|vₐ| per hit.

Pressure (kinetic theory; catalog 001 §1.1 lists the container but gives no formula, the
oracle is a supplement): a particle bouncing between the walls ⟂ a hits each every 2ℓₐ/|vₐ|,
so the time-averaged force on one wall is Σ m vₐ²/ℓₐ and the pressure
P_a = (1/V) Σᵢ m vᵢₐ², V = ℓ_x ℓ_y ℓ_z; for an isotropic gas P = 2E/(3V). The impulses
delivered to each wall are summed in a discrete mode entry of the state (``impulse_x_low`` …,
changed only by the event handler); the observable ``pressure_<axis>_<side>`` is that impulse
over t × wall area, the time-averaged pressure since t = 0, which converges to the kinetic
pressure ``kinetic_pressure_<axis>`` (published beside it; an invariant in disguise) as
O(ℓ/(|v| t)).

Initial state (``initial.*``, taking effect at start or reset): positions uniform in the box
(1% from the walls), velocities Gaussian from ``initial.seed``, scaled so that the mean
square speed is exactly ``initial.rms_speed``² (E = ½ N m v_rms²); with ``initial.isotropic``
each axis gets exactly a third of it (then every wall sees P = 2E/(3V)).

Conventions: REP-103 world axes, the box centred on the origin of its static frame ``box``,
edges along x, y, z; particle i at frame ``particle_<i>`` (child of ``box``). Coordinates
``x_i``, ``y_i``, ``z_i``. Events ``wall_<axis>_<low|high>_<i>``: the wall at −ℓ/2 or +ℓ/2.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from mechsim.params import Parameter, positive
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

MAX_COUNT = 32
AXES = ("x", "y", "z")
SIDES = ("low", "high")


class GasInBox(LagrangianModel):
    id = "gas_in_box"
    title = "Gas in a container: point particles in a box with elastic walls"
    source = ("Introduction to analytical mechanics, “Classification of constraints” "
              "(non-holonomic inequality constraints: gas molecules contained in a container)")
    oracles = ("kinetic energy, energy of each axis and every speed component conserved "
               "through the wall events; positions, hit times and impulses of the folded free "
               "flight; time-averaged impulse pressure on each wall → (1/V)Σmvₐ² within one hit "
               "per particle, 2E/(3V) isotropic")
    parameters = (
        Parameter("count", 8, "", "number N of particles", minimum=1, maximum=MAX_COUNT),
        positive("mass", 1.0, "kg", "mass m of each particle"),
        positive("box_length_x", 2.0, "m", "inner length ℓ_x of the box along x"),
        positive("box_length_y", 1.5, "m", "inner length ℓ_y of the box along y"),
        positive("box_length_z", 1.0, "m", "inner length ℓ_z of the box along z"),
        positive("initial.rms_speed", 1.0, "m/s", "root-mean-square speed v_rms of the "
                 "particles (E = ½Nm v_rms²)"),
        Parameter("initial.seed", 1, "", "seed of the random initial positions and velocities",
                  minimum=0, maximum=2**31 - 1),
        Parameter("initial.isotropic", True, "", "give each axis exactly a third of the "
                  "kinetic energy"),
    )

    @property
    def count(self) -> int:
        return int(self.values["count"])

    def lengths(self) -> np.ndarray:
        return np.array([self.value(f"box_length_{a}") for a in AXES])

    def volume(self) -> float:
        return float(np.prod(self.lengths()))

    def declare(self, b: LagrangianBuilder) -> None:
        m = b.param("mass")
        ell = [b.param(f"box_length_{a}") for a in AXES]
        q, v = [], []
        for i in range(1, self.count + 1):
            for a in AXES:
                qa, va = b.coordinate(f"{a}_{i}", "m")
                q.append(qa)
                v.append(va)
        b.kinetic = m * sum(c**2 for c in v) / 2
        b.potential = sp.Integer(0)
        for i in range(self.count):
            for k, a in enumerate(AXES):
                x = q[3 * i + k]
                b.event(f"wall_{a}_low_{i + 1}", x + ell[k] / 2, -1,
                        f"particle {i + 1} reaches the wall {a} = −ℓ_{a}/2 moving outward")
                b.event(f"wall_{a}_high_{i + 1}", ell[k] / 2 - x, -1,
                        f"particle {i + 1} reaches the wall {a} = +ℓ_{a}/2 moving outward")
        impulses = {(a, s): b.mode(f"impulse_{a}_{s}") for a in AXES for s in SIDES}
        volume = ell[0] * ell[1] * ell[2]
        for k, a in enumerate(AXES):
            axis_sq = sum(v[3 * i + k] ** 2 for i in range(self.count))
            b.invariant(f"kinetic_energy_{a}", "J", m * axis_sq / 2)
            b.observable(f"kinetic_pressure_{a}", "Pa", m * axis_sq / volume)
            area = volume / ell[k]
            for s in SIDES:
                # 0 at t = 0 (no impulse yet); max() keeps the division defined there
                b.observable(f"pressure_{a}_{s}", "Pa", impulses[(a, s)] / (
                    area * sp.Max(b.t, sp.Float(1e-300))))
        b.observable("ideal_gas_pressure", "Pa", 2 * b.kinetic / (3 * volume))
        b.frame("box", "world", (0, 0, 0))
        for i in range(self.count):
            b.frame(f"particle_{i + 1}", "box", tuple(q[3 * i:3 * i + 3]))

    # --- state and events ---------------------------------------------------------------
    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        n, ell = self.count, self.lengths()
        rng = np.random.default_rng(int(self.values["initial.seed"]))
        pos = (rng.random((n, 3)) - 0.5) * 0.98 * ell
        vel = rng.standard_normal((n, 3))
        # Σ|v|² = N v_rms² (a third on each axis if isotropic); v_rms outside the root
        v_rms = self.value("initial.rms_speed")
        if bool(self.values["initial.isotropic"]):
            vel *= v_rms * np.sqrt(n / 3 / np.sum(vel**2, axis=0))
        else:
            vel *= v_rms * math.sqrt(n / float(np.sum(vel**2)))
        return pos.reshape(-1), vel.reshape(-1)

    @functools.cached_property
    def _walls(self) -> tuple[tuple[float, float, float], float]:
        """(ℓₐ/2 for each axis, m): what a wall event reads (a model's values never change)."""
        half = 0.5 * self.lengths()
        return (float(half[0]), float(half[1]), float(half[2])), self.value("mass")

    def handle_event(self, index: int, t: float, y: np.ndarray) -> np.ndarray:
        """Elastic wall: reverse the outward velocity component of the particle at the wall
        and book the impulse 2m|vₐ| to that wall. Every component of that particle that is at
        or past a wall and moving outward is reversed (a corner reached within the event
        location's tolerance), the one whose event fired in any case."""
        n = 3 * self.count
        i, rest = divmod(index, 6)
        fired = divmod(rest, 2)  # (axis, side) of the event
        half, m = self._walls
        for k in range(3):
            j = 3 * i + k
            x, v = float(y[j]), float(y[n + j])
            if v < 0.0:
                side, at_wall = 0, x <= -half[k]
            elif v > 0.0:
                side, at_wall = 1, x >= half[k]
            else:
                continue  # not moving outward: no wall acts
            if at_wall or fired == (k, side):
                y[2 * n + 2 + 2 * k + side] += 2.0 * m * abs(v)
                y[n + j] = -v
        return y

    def visuals(self) -> tuple[Visual, ...]:
        ell = self.lengths()
        r = 0.02 * float(ell.min())
        half = (float(ell[0]) / 2, float(ell[1]) / 2, float(ell[2]) / 2)
        out = [Visual("box", "box", size=half, color=(90, 90, 110))]
        out += [Visual("sphere", f"particle_{i + 1}", radius=r, color=(120, 200, 255))
                for i in range(self.count)]
        out.append(Visual("trail", "particle_1", color=(255, 200, 80)))
        return tuple(out)

    def time_scale(self) -> float:
        """Crossing time of the shortest box edge at the rms speed."""
        return float(self.lengths().min()) / self.value("initial.rms_speed")

    # --- analytic oracles ------------------------------------------------------------------
    def kinetic_pressure(self) -> np.ndarray:
        """(P_x, P_y, P_z) = (1/V) Σᵢ m vᵢₐ² (constant)."""
        _, v = self.initial_state()
        return self.value("mass") * np.sum(v.reshape(-1, 3) ** 2, axis=0) / self.volume()

    def ideal_gas_pressure(self) -> float:
        """2E/(3V) = N m v_rms² / (3V) (the pressure of every wall for an isotropic gas)."""
        return self.count * self.value("mass") * self.value("initial.rms_speed") ** 2 / (
            3 * self.volume())


MODEL = GasInBox
