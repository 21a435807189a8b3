"""N identical coupled oscillators: normal modes, beats and energy transfer.

Sources: PHYS0500 ch. 8 "Coupled Oscillations" — §8.1 two identical coupled oscillators
(lines 1986–2088), §8.2 weak coupling and beats (2090–2139), §8.3–8.4 general small-oscillation
theory and normal coordinates (2141–2281); Introduction to analytical mechanics, “Small
Oscillations” (small oscillations, |V − ω²T| = 0).

The system: N masses m moving along x, each tied to its own anchor by a spring κ
(``spring_constant``), neighbours joined by coupling springs κ₁₂ (``coupling_constant``).
For N = 2 this is exactly the document's system (walls κ, coupling κ₁₂, eq. at line 1992).
(Small-angle pendulums of length l coupled by springs are the same system with κ = mg/l.)
V = ½ κ Σ x_j² + ½ κ₁₂ Σ (x_{j+1} − x_j)², T = ½ m Σ ẋ_j², so A = κ I + κ₁₂ L with L the
path-graph Laplacian. Its eigenvectors do not depend on m, κ, κ₁₂:
u_r,j ∝ cos((j − ½)(r − 1)π/N), ω_r² = (κ + 4 κ₁₂ sin²((r − 1)π/2N)) / m, r = 1 … N
(ascending; r = 1 is the in-phase mode). N = 2: ω² = κ/m (symmetric, the document's ω₂) and
(κ + 2κ₁₂)/m (antisymmetric, its ω₁), eq. 8.2. Each mode energy
E_r = ½ m (u_r·ẋ)² + ½ m ω_r² (u_r·x)² is conserved (invariants ``mode_energy_<r>``); the
oscillators' own energies ½ m ẋ_j² + ½ κ x_j² (observables ``oscillator_energy_<j>``) exchange
energy in beats. The document's claim (line 2088) that n/2 frequencies lie above
ω₀ = √((κ + κ₁₂)/m) belongs to a chain with walls at both ends, not to this one.

Initial conditions: ``initial.mode`` = 0 gives the document's x₁(0) = D = ``initial.amplitude``,
all other x and ẋ zero (line 2121); ``initial.mode`` = r starts in pure mode r with the largest
displacement D.

Document typos corrected (catalog 003 §8.1–8.4): e^{±iωt} for e^{−ωt} (2028–2050); the η₁
equation M η̈₁ + (κ + 2κ₁₂) η₁ = 0 (2046 keeps a spurious +κη₂, and the equations are added and
subtracted); the example matrix A has off-diagonals −κ₁₂, not −κ (2227); ω₁ → ω_r (2270); the
modes are M-orthogonal (2281), not merely orthogonal (2215); the weak-coupling results
ω ≈ ω₀(1 ± ε) and t = π/(2εω₀) are first order in ε = κ₁₂/2κ (the exact transfer time is
π/(ω₁ − ω₂)).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, nonnegative, positive
from mechsim.systems._oscillator import normal_mode_rows
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

MAX_COUNT = 12


@functools.lru_cache(maxsize=MAX_COUNT)
def mode_shapes(n: int) -> np.ndarray:
    """Orthonormal eigenvectors of the path-graph Laplacian, one per row, ascending
    (read-only: made once per n)."""
    j = np.arange(1, n + 1)
    u = np.cos(np.outer(np.arange(n), j - 0.5) * math.pi / n)
    u /= np.linalg.norm(u, axis=1)[:, None]
    u.flags.writeable = False
    return u


@functools.lru_cache(maxsize=MAX_COUNT)
def laplacian_eigenvalues(n: int) -> np.ndarray:
    """4 sin²(rπ/2n), r = 0 … n − 1 (read-only: made once per n)."""
    lam = 4 * np.sin(np.arange(n) * math.pi / (2 * n)) ** 2
    lam.flags.writeable = False
    return lam


class CoupledOscillators(LagrangianModel):
    id = "coupled_oscillators"
    title = "N identical coupled oscillators (normal modes, beats)"
    source = ("PHYS0500 – Advanced Classical Mechanics, ch. 8 (Coupled Oscillations, §8.1–8.4); "
              "Introduction to analytical mechanics, “Small Oscillations”")
    energy_parts = ("mode_energy_",)
    oracles = ("ω_r² from |A − ω²M| = 0 (closed form), exact modal solution, conserved mode "
               "energies, beat transfer time π/(ω₁ − ω₂) ≈ π/(2εω₀)")
    parameters = (
        Parameter("count", 2, "", "number N of masses", minimum=1, maximum=MAX_COUNT),
        positive("mass", 1.0, "kg", "mass m of each oscillator"),
        positive("spring_constant", 4.0, "N/m", "spring κ tying each mass to its anchor"),
        nonnegative("coupling_constant", 0.4, "N/m", "spring κ₁₂ between neighbours"),
        positive("spacing", 1.0, "m", "equilibrium distance between neighbours (display)"),
        Parameter("initial.mode", 0, "", "0: only mass 1 displaced (x₁ = D); r ≥ 1: pure "
                  "normal mode r (ascending frequency)", minimum=0, maximum=MAX_COUNT),
        Parameter("initial.amplitude", 0.2, "m", "initial displacement D"),
    )

    @property
    def count(self) -> int:
        return int(self.values["count"])

    def check(self) -> None:
        if int(self.values["initial.mode"]) > self.count:
            raise ParameterError("initial.mode", f"must be ≤ count = {self.count} "
                                 f"(got {self.values['initial.mode']})")

    def declare(self, b: LagrangianBuilder) -> None:
        n = self.count
        m, k, kc = b.param("mass"), b.param("spring_constant"), b.param("coupling_constant")
        s = b.param("spacing")
        xs, vs = zip(*(b.coordinate(f"x_{j + 1}", "m") for j in range(n)), strict=True)
        b.kinetic = m * sum(v**2 for v in vs) / 2
        b.potential = (k * sum(x**2 for x in xs) / 2
                       + kc * sum((xs[j + 1] - xs[j]) ** 2 for j in range(n - 1)) / 2)
        u, lam = mode_shapes(n), laplacian_eigenvalues(n)
        for r in range(n):
            eta = sum(sp.Float(u[r, j], 17) * xs[j] for j in range(n))
            deta = sum(sp.Float(u[r, j], 17) * vs[j] for j in range(n))
            b.invariant(f"mode_energy_{r + 1}", "J",
                        m * deta**2 / 2 + (k + kc * sp.Float(lam[r], 17)) * eta**2 / 2)
        for j in range(n):
            b.observable(f"oscillator_energy_{j + 1}", "J", m * vs[j] ** 2 / 2 + k * xs[j] ** 2 / 2)
        b.observable("coupling_energy", "J",
                     kc * sum((xs[j + 1] - xs[j]) ** 2 for j in range(n - 1)) / 2)
        b.frame("chain", "world", (0, 0, 0))
        for j in range(n):
            b.frame(f"anchor_{j + 1}", "chain", (j * s, 0, s / 2))
        for j in range(n):
            b.frame(f"mass_{j + 1}", "chain", (j * s + xs[j], 0, 0))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        n, D = self.count, self.value("initial.amplitude")
        r = int(self.values["initial.mode"])
        x = np.zeros(n)
        if r == 0:
            x[0] = D
        else:
            u = mode_shapes(n)[r - 1]
            x = D * u / np.max(np.abs(u))
        return x, np.zeros(n)

    def visuals(self) -> tuple[Visual, ...]:
        n = self.count
        out = []
        for j in range(1, n + 1):
            out += [Visual("box", f"anchor_{j}", size=(0.1, 0.1, 0.02), color=(150, 150, 150)),
                    Visual("link", f"anchor_{j}", to_frame=f"mass_{j}", radius=0.008,
                           color=(200, 200, 90)),
                    Visual("sphere", f"mass_{j}", radius=0.1)]
        out += [Visual("link", f"mass_{j}", to_frame=f"mass_{j + 1}", radius=0.008,
                       color=(230, 120, 90)) for j in range(1, n)]
        return tuple(out)

    def time_scale(self) -> float:
        return 2 * math.pi / float(self.mode_frequencies()[-1])

    # --- analytic oracles (PHYS0500 ch. 8) ---------------------------------------------------
    def mode_frequencies(self) -> np.ndarray:
        """ω_r, ascending."""
        lam = laplacian_eigenvalues(self.count)
        return np.sqrt((self.value("spring_constant") + self.value("coupling_constant") * lam)
                       / self.value("mass"))

    def mode_shapes(self) -> np.ndarray:
        """Euclidean-orthonormal mode vectors u_r (rows); M-orthonormal a_r = u_r/√m."""
        return mode_shapes(self.count)

    def exact_solution(self, t: np.ndarray) -> np.ndarray:
        """x_j(t), shape (len(t), N), from the initial state (``propagate``)."""
        t = np.asarray(t, dtype=float)
        rows = self.propagate(0.0, self.initial_y(), t.ravel())
        return rows[:, : self.count].reshape(t.shape + (self.count,))

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray,
                  work_terms: bool = True) -> np.ndarray:
        """Superposition of the normal modes, each η_r = u_r·x a free oscillator at ω_r from
        its state at t₀ (ω_r > 0: every mass has its anchor spring κ > 0), all modes at once:
        η_r = η_r(t₀) cos ω_r τ + η̇_r(t₀)/ω_r sin ω_r τ, x = Σ η_r u_r. Nothing drives or
        dissipates: the work terms stay as they are."""
        return normal_mode_rows(self.mode_shapes(), self.mode_frequencies(), y0,
                                np.asarray(t, dtype=float) - t0)

    def weak_coupling_ratio(self) -> float:
        """ε = κ₁₂ / 2κ (line 2094)."""
        return self.value("coupling_constant") / (2 * self.value("spring_constant"))

    def transfer_time(self, approximate: bool = False) -> float:
        """Two oscillators: time for complete transfer from mass 1 to mass 2, π/(ω₁ − ω₂)
        exactly, or the document's first-order π/(2εω₀), ω₀ = √((κ + κ₁₂)/m) (line 2139)."""
        if self.count != 2:
            raise ValueError("the transfer time is defined for two oscillators")
        if approximate:
            w0 = math.sqrt((self.value("spring_constant") + self.value("coupling_constant"))
                           / self.value("mass"))
            return math.pi / (2 * self.weak_coupling_ratio() * w0)
        w = self.mode_frequencies()
        return math.pi / float(w[1] - w[0])


MODEL = CoupledOscillators
