"""General small oscillations: n coordinates with arbitrary positive-definite mass and stiffness
matrices, normal modes from the generalized eigenproblem.

Sources: PHYS0500 §8.3 "General Small-Oscillation Theory" and §8.4 "Normal Coordinates"
(lines 2141–2281): near a stable equilibrium T = ½ Σ m_jk q̇_j q̇_k and U = ½ Σ A_jk q_j q_k,
so M q̈ = −A q (line 2223); q = a e^{i(ωt − δ)} gives (A − ω²M) a = 0 and |A − ω²M| = 0
(2205–2213); the normal coordinates η_r with q = Σ_r a_r η_r obey η̈_r + ω_r² η_r = 0 (2278)
and the modes are M-orthonormal, Σ m_jk a_jr a_ks = δ_rs (2281). Seed 001 §2.21 (L2040–2254)
writes the same with T and V matrices, |V − ω²T| = 0. Here the matrices are parameters
(``mass_matrix.m_jk`` = M_jk and ``stiffness_matrix.k_jk`` = A_jk, the stiffness K, for
j ≤ k; the lower triangle mirrors them), so
the system is the linearized motion of any assembly (molecule, circuit, structure); the
double pendulum of 001 §2.3 is M = ml²[[2, 1], [1, 1]], A = mgl[[2, 0], [0, 1]].

Conserved: E = ½ q̇ᵀMq̇ + ½ qᵀAq = Σ_r E_r with the mode energies
E_r = ½ η̇_r² + ½ ω_r² η_r², η_r = a_rᵀ M q (invariants ``mode_energy_<r>``, modes in ascending
frequency). The ω_r and a_r are computed from the parameter values (scipy.linalg.eigh) and
written into the mode-energy and ``normal_coordinate_<r>`` expressions as numbers, so each
parameter set has its own compiled kernel; the equations of motion themselves take M and A from
the parameter vector. ``propagate`` is the exact modal solution.

Conventions: coordinates ``q_1`` … ``q_n`` in m with M in kg and A in N/m (for angles read
rad, kg m², N m/rad); equilibrium at q = 0, the potential zero there. Display only: frame
``q_<j>`` is a bead displaced by q_j along x from the point (0, 0.5 (j − 1), 0) of the static
frame ``equilibrium``. Entries of rows and columns above ``dimension`` are not used and must
keep their defaults (otherwise the setting would be silently ignored).

Document typos corrected (catalog 003 §8.3–8.4): ∂T/∂q_k|₀ = 0 (line 2161 writes U); the
Taylor expansion's linear term lacks q_k (2169); "order of differentiation" (2179); the example
A has off-diagonals −κ₁₂ (2227); η_r = β_r e^{iω_r t} (2270 has ω₁); the modes are
M-orthogonal (2281), not merely orthogonal (2215).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg

from mechsim.errors import ParameterError
from mechsim.params import Parameter, number
from mechsim.systems._oscillator import free_solution, state_rows
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

MAX_DIMENSION = 4
_MASS = ((2.0, 0.5, 0.0, 0.1), (0.5, 1.5, 0.3, 0.0), (0.0, 0.3, 1.0, 0.2), (0.1, 0.0, 0.2, 1.2))
_STIFF = ((5.0, -2.0, 0.0, 0.0), (-2.0, 6.0, -1.5, 0.0), (0.0, -1.5, 4.0, -1.0),
          (0.0, 0.0, -1.0, 3.0))
_PAIRS = [(j, k) for j in range(MAX_DIMENSION) for k in range(j, MAX_DIMENSION)]


def _entry(matrix: str, j: int, k: int) -> str:
    """``mass_matrix.m_<j><k>`` or ``stiffness_matrix.k_<j><k>`` (1-based, j ≤ k; one digit
    each, so the names are strings in YAML too, where 1_2 would read as the integer 12)."""
    return f"{matrix}.{'m' if matrix == 'mass_matrix' else 'k'}_{j + 1}{k + 1}"


def _indices(name: str) -> tuple[int, ...]:
    """The 1-based coordinate indices a parameter refers to: (j, k) of ``mass_matrix.m_jk``,
    (j,) of ``initial.q_j``."""
    return tuple(int(c) for c in name.rsplit("_", 1)[1])


class SmallOscillations(LagrangianModel):
    id = "small_oscillations"
    title = "General small oscillations (normal modes of M q̈ = −A q)"
    source = ("PHYS0500 – Advanced Classical Mechanics, §8.3–8.4 (General Problem, Normal "
              "Coordinates); Introduction to analytical mechanics, “Small Oscillations” (det(V − "
              "ω²T) = 0)")
    energy_parts = ("mode_energy_",)
    oracles = ("ω_r², a_r from the generalized eigenproblem (scipy eigh; sympy for 2×2; double "
               "pendulum (2 ± √2)g/l); M-orthonormal modes; mode energies conserved; exact modal "
               "solution = matrix exponential; a pure mode stays pure")
    parameters = (
        Parameter("dimension", 3, "", "number n of coordinates", minimum=1,
                  maximum=MAX_DIMENSION),
        *(number(_entry("mass_matrix", j, k), _MASS[j][k], "kg",
                 f"mass (inertia) matrix entry M_{j + 1}{k + 1} = M_{k + 1}{j + 1}")
          for j, k in _PAIRS),
        *(number(_entry("stiffness_matrix", j, k), _STIFF[j][k], "N/m",
                 f"stiffness matrix entry A_{j + 1}{k + 1} = A_{k + 1}{j + 1}")
          for j, k in _PAIRS),
        *(number(f"initial.q_{j + 1}", 0.1 if j == 0 else 0.0, "m",
                 f"initial displacement q_{j + 1}") for j in range(MAX_DIMENSION)),
        *(number(f"initial_rate.q_{j + 1}", 0.0, "m/s", f"initial rate q̇_{j + 1}")
          for j in range(MAX_DIMENSION)),
    )

    @property
    def dimension(self) -> int:
        return int(self.values["dimension"])

    def matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(M, A), n × n, symmetric."""
        n = self.dimension
        out = []
        for name in ("mass_matrix", "stiffness_matrix"):
            m = np.zeros((n, n))
            for j, k in _PAIRS:
                if k < n:
                    m[j, k] = m[k, j] = self.value(_entry(name, j, k))
            out.append(m)
        return out[0], out[1]

    def check(self) -> None:
        n = self.dimension
        defaults = {p.name: p.default for p in self.parameters if "." in p.name}
        unused = [name for name, default in defaults.items()
                  if max(_indices(name)) > n and self.values[name] != default]
        if unused:
            raise ParameterError(unused[0], f"is beyond dimension = {n}: leave it at its "
                                 f"default ({defaults[unused[0]]:g}) or raise dimension")
        for name, m in zip(("mass_matrix", "stiffness_matrix"), self.matrices(), strict=True):
            try:
                eig = np.linalg.eigvalsh(m)
            except np.linalg.LinAlgError:
                raise ParameterError(name, "has no eigenvalues (entries too large?)") from None
            if not (np.all(np.isfinite(eig))
                    and eig[0] > 1e-12 * max(1.0, float(np.max(np.abs(m))))):
                raise ParameterError(name, f"must be positive definite (smallest eigenvalue "
                                     f"{eig[0]:.3g}; dimension {n})")

    def declare(self, b: LagrangianBuilder) -> None:
        n = self.dimension
        qs, vs = zip(*(b.coordinate(f"q_{j + 1}", "m") for j in range(n)), strict=True)
        M = sp.Matrix(n, n, lambda j, k: b.param(_entry("mass_matrix", min(j, k), max(j, k))))
        A = sp.Matrix(n, n, lambda j, k: b.param(_entry("stiffness_matrix", min(j, k),
                                                        max(j, k))))
        q, v = sp.Matrix(qs), sp.Matrix(vs)
        b.kinetic = (v.T * M * v)[0, 0] / 2
        b.potential = (q.T * A * q)[0, 0] / 2
        w2, modes = self._eig()
        weights = modes.T @ self.matrices()[0]  # row r: a_rᵀM, so η_r = (a_rᵀM) q
        for r in range(n):
            wr = [sp.Float(float(c), 17) for c in weights[r]]
            eta = sum(c * x for c, x in zip(wr, qs, strict=True))
            deta = sum(c * x for c, x in zip(wr, vs, strict=True))
            b.invariant(f"mode_energy_{r + 1}", "J",
                        deta**2 / 2 + sp.Float(float(w2[r]), 17) * eta**2 / 2)
            b.observable(f"normal_coordinate_{r + 1}", "kg^0.5 m", eta)
        b.frame("equilibrium", "world", (0, 0, 0))
        for j in range(n):
            b.frame(f"q_{j + 1}", "equilibrium", (qs[j], sp.Rational(j, 2), 0))

    def _eig(self) -> tuple[np.ndarray, np.ndarray]:
        M, A = self.matrices()
        return scipy.linalg.eigh(A, M)  # ascending ω², columns M-orthonormal

    # --- analytic oracles (PHYS0500 §8.3–8.4) -----------------------------------------------
    def frequencies(self) -> np.ndarray:
        """ω_r, ascending, from |A − ω²M| = 0."""
        return np.sqrt(self._eig()[0])

    def mode_shapes(self) -> np.ndarray:
        """a_r as columns, M-orthonormal (aᵀMa = I)."""
        return self._eig()[1]

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray,
                  work_terms: bool = True) -> np.ndarray | None:
        """Exact: η_r = a_rᵀM q evolves as a free oscillator at ω_r; q = Σ a_r η_r."""
        n = self.dimension
        M = self.matrices()[0]
        w2, a = self._eig()
        eta0, deta0 = a.T @ M @ y0[:n], a.T @ M @ y0[n:2 * n]
        dt = np.asarray(t, dtype=float) - t0
        q = np.zeros((dt.size, n))
        v = np.zeros((dt.size, n))
        for r in range(n):
            e, de = free_solution(dt, float(eta0[r]), float(deta0[r]), math.sqrt(w2[r]))
            q += e[:, None] * a[:, r]
            v += de[:, None] * a[:, r]
        return state_rows(y0, [*q.T, *v.T])

    def time_scale(self) -> float:
        """The shortest modal period (1 s if extreme entries leave it undefined)."""
        ts = 2 * math.pi / float(self.frequencies()[-1])
        return ts if math.isfinite(ts) and ts > 0 else 1.0

    def visuals(self) -> tuple[Visual, ...]:
        out = [Visual("sphere", f"q_{j + 1}", radius=0.08) for j in range(self.dimension)]
        out += [Visual("link", f"q_{j}", to_frame=f"q_{j + 1}", radius=0.01,
                       color=(200, 200, 90)) for j in range(1, self.dimension)]
        out += [Visual("trail", f"q_{j + 1}", color=(120, 170, 255))
                for j in range(self.dimension)]
        return tuple(out)


MODEL = SmallOscillations
