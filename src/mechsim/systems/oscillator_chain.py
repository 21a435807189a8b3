"""A chain of n identical masses joined by identical springs, between two walls, one wall or
none: its normal modes, and where the document's n/2 claim holds.

Source: PHYS0500 – Advanced Classical Mechanics, §8.1 (Two Coupled Harmonic Oscillators): with
one mass held, the other oscillates at ω₀; "the effect of the coupling is to split this natural
frequency into a higher and a lower frequency", and "for a system of n identical coupled
oscillators, there will be n/2 characteristic frequencies greater than ω₀ and n/2 lesser than
ω₀; for odd n, ω₀ itself is one of the characteristic frequencies"; §8.3–8.4 (the general
problem, |A − ω²M| = 0, normal coordinates).

The system: masses m at rest at x = j·spacing (j = 1 … n), displacements x_j along the chain,
neighbours joined by springs κ, and with ``walls`` = "both" the first and the last mass tied to
fixed walls by the same spring κ (n + 1 springs), with "left" only the first, with "none"
neither (a free chain). V = ½κ Σ (x_{j+1} − x_j)² + ½κ x₁² (left, both) + ½κ x_n² (both).
ω₀ = √(2κ/m) is the frequency of one mass with both neighbours held, as in §8.1 (κ + κ₁₂ with
κ₁₂ = κ). Closed-form modes, ascending (u_r orthonormal, x = Σ η_r u_r):
- both: ω_r = 2√(κ/m) sin(rπ/2(n+1)), u_r,j ∝ sin(jrπ/(n+1)): below ω₀ exactly when
  r < (n+1)/2, so n/2 below and n/2 above, and ω₀ itself for odd n (r = (n+1)/2). The claim
  holds for every n.
- left: ω_r = 2√(κ/m) sin((2r−1)π/2(2n+1)), u_r,j ∝ sin(j(2r−1)π/(2n+1)): ω₀ is never a
  frequency, so the claim fails for every odd n (⌈n/2⌉ lie below).
- none: ω_r = 2√(κ/m) sin((r−1)π/2n), u_r,j ∝ cos((j−½)(r−1)π/n), ω₁ = 0 (the chain
  translates): for even n, ω₀ is a frequency and only n/2 − 1 lie above; for odd n, (n+1)/2
  lie below. The claim fails for every n.
So the n/2 claim is a property of the chain with walls at both ends (``document_claim_holds``).
Each mode energy ½m(u_r·ẋ)² + ½mω_r²(u_r·x)² is conserved (invariants ``mode_energy_<r>``);
the free chain also keeps its momentum. Initial conditions: ``initial.mode`` = 0 displaces
mass 1 by ``initial.amplitude`` D, all else at rest; r ≥ 1 starts pure mode r (largest
displacement D).
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.errors import ParameterError
from mechsim.params import Parameter, positive
from mechsim.systems._oscillator import normal_mode_rows
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

MAX_COUNT = 12
WALLS = ("both", "left", "none")


def chain_modes(n: int, walls: str) -> tuple[np.ndarray, np.ndarray]:
    """(s_r, u): ω_r = 2√(κ/m) s_r, ascending, and the orthonormal mode shapes u (rows) of the
    chain (see the module docstring)."""
    j = np.arange(1, n + 1)
    r = np.arange(1, n + 1)
    if walls == "both":
        s = np.sin(r * math.pi / (2 * (n + 1)))
        u = np.sin(np.outer(r, j) * math.pi / (n + 1))
    elif walls == "left":
        s = np.sin((2 * r - 1) * math.pi / (2 * (2 * n + 1)))
        u = np.sin(np.outer(2 * r - 1, j) * math.pi / (2 * n + 1))
    else:
        s = np.sin((r - 1) * math.pi / (2 * n))
        u = np.cos(np.outer(r - 1, j - 0.5) * math.pi / n)
    return s, u / np.linalg.norm(u, axis=1)[:, None]


class OscillatorChain(LagrangianModel):
    id = "oscillator_chain"
    title = "Chain of identical oscillators between walls (normal modes, the n/2 claim)"
    source = ("PHYS0500 – Advanced Classical Mechanics, §8.1 (n identical coupled oscillators: "
              "n/2 frequencies above ω₀, n/2 below) and §8.3–8.4 (General Problem, Normal "
              "Coordinates)")
    energy_parts = ("mode_energy_",)
    oracles = ("ω_r and modes from scipy's eigh of the stiffness matrix; n/2 claim holds with "
               "both walls for every n, fails with one or none; exact modal motion; conserved "
               "mode energies; FFT peaks of the motion at ω_r")
    parameters = (
        Parameter("count", 5, "", "number n of masses", minimum=1, maximum=MAX_COUNT),
        Parameter("walls", "both", "", "which ends are tied to a fixed wall", choices=WALLS),
        positive("mass", 1.0, "kg", "mass m of each oscillator"),
        positive("spring_constant", 4.0, "N/m", "every spring's constant κ"),
        positive("spacing", 0.5, "m", "equilibrium distance between neighbours (display)"),
        Parameter("initial.mode", 0, "", "0: only mass 1 displaced (x₁ = D); r ≥ 1: pure "
                  "normal mode r (ascending frequency)", minimum=0, maximum=MAX_COUNT),
        Parameter("initial.amplitude", 0.1, "m", "initial displacement D"),
    )

    @property
    def count(self) -> int:
        return int(self.values["count"])

    @property
    def walls(self) -> str:
        return str(self.values["walls"])

    def check(self) -> None:
        if int(self.values["initial.mode"]) > self.count:
            raise ParameterError("initial.mode", f"must be ≤ count = {self.count} "
                                 f"(got {self.values['initial.mode']})")

    def declare(self, b: LagrangianBuilder) -> None:
        n, walls = self.count, self.walls
        m, k, a = b.param("mass"), b.param("spring_constant"), b.param("spacing")
        xs, vs = zip(*(b.coordinate(f"x_{j + 1}", "m") for j in range(n)), strict=True)
        b.kinetic = m * sum(v**2 for v in vs) / 2
        stretch = [xs[j + 1] - xs[j] for j in range(n - 1)]
        if walls in ("both", "left"):
            stretch.insert(0, xs[0])
        if walls == "both":
            stretch.append(-xs[-1])
        b.potential = k * sum(e**2 for e in stretch) / 2
        s, u = chain_modes(n, walls)
        for r in range(n):
            eta = sum(sp.Float(u[r, j], 17) * xs[j] for j in range(n))
            deta = sum(sp.Float(u[r, j], 17) * vs[j] for j in range(n))
            b.invariant(f"mode_energy_{r + 1}", "J",
                        m * deta**2 / 2 + 2 * k * sp.Float(s[r] ** 2, 17) * eta**2)
        if walls == "none":
            b.invariant("momentum", "kg m/s", m * sum(vs))
        b.frame("chain", "world", (0, 0, 0))
        if walls in ("both", "left"):
            b.frame("left_wall", "chain", (0, 0, 0))
        if walls == "both":
            b.frame("right_wall", "chain", ((n + 1) * a, 0, 0))
        for j in range(n):
            b.frame(f"mass_{j + 1}", "chain", ((j + 1) * a + xs[j], 0, 0))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        n, D = self.count, self.value("initial.amplitude")
        r = int(self.values["initial.mode"])
        x = np.zeros(n)
        if r == 0:
            x[0] = D
        else:
            u = chain_modes(n, self.walls)[1][r - 1]
            x = D * u / np.max(np.abs(u))
        return x, np.zeros(n)

    def visuals(self) -> tuple[Visual, ...]:
        n = self.count
        out = [Visual("box", w, size=(0.02, 0.15, 0.15), color=(150, 150, 150))
               for w in ("left_wall", "right_wall")[:{"both": 2, "left": 1, "none": 0}[self.walls]]]
        out += [Visual("sphere", f"mass_{j}", radius=0.06) for j in range(1, n + 1)]
        out += [Visual("link", f"mass_{j}", to_frame=f"mass_{j + 1}", radius=0.008,
                       color=(230, 120, 90)) for j in range(1, n)]
        if self.walls in ("both", "left"):
            out.append(Visual("link", "left_wall", to_frame="mass_1", radius=0.008,
                              color=(230, 120, 90)))
        if self.walls == "both":
            out.append(Visual("link", f"mass_{n}", to_frame="right_wall", radius=0.008,
                              color=(230, 120, 90)))
        return tuple(out)

    def time_scale(self) -> float:
        fastest = float(self.mode_frequencies()[-1])
        return 2 * math.pi / fastest if fastest > 0 else 1.0

    def law_scales(self) -> dict[str, float]:
        """The free chain's momentum often starts at 0 (a chain at rest): its drift is
        measured against √(2 n m E), the momentum the chain's energy could give it."""
        scales = super().law_scales()
        if "invariant:momentum" in scales:
            scales["invariant:momentum"] = math.sqrt(
                2 * self.count * self.value("mass") * self.energy_scale())
        return scales

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray,
                  work_terms: bool = True) -> np.ndarray:
        """The superposition of the free normal modes (``normal_mode_rows``)."""
        return normal_mode_rows(chain_modes(self.count, self.walls)[1], self.mode_frequencies(),
                                y0, np.asarray(t, dtype=float) - t0)

    # --- analytic oracles (PHYS0500 §8.1, §8.4) ---------------------------------------------
    def mode_frequencies(self) -> np.ndarray:
        """ω_r, ascending (closed forms of the module docstring)."""
        s = chain_modes(self.count, self.walls)[0]
        return 2 * math.sqrt(self.value("spring_constant") / self.value("mass")) * s

    def held_frequency(self) -> float:
        """ω₀ = √(2κ/m): one mass oscillating between its two held neighbours (§8.1)."""
        return math.sqrt(2 * self.value("spring_constant") / self.value("mass"))

    def frequencies_about_held(self, rtol: float = 1e-12) -> tuple[int, int, int]:
        """How many ω_r lie below, at and above ω₀."""
        w, w0 = self.mode_frequencies(), self.held_frequency()
        at = np.abs(w - w0) <= rtol * w0
        return int(np.sum((w < w0) & ~at)), int(np.sum(at)), int(np.sum((w > w0) & ~at))

    def document_claim_holds(self) -> bool:
        """n/2 frequencies above ω₀ and n/2 below, ω₀ itself one of them for odd n."""
        below, at, above = self.frequencies_about_held()
        n = self.count
        return below == above == n // 2 and at == n % 2


MODEL = OscillatorChain
