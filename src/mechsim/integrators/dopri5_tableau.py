"""The DOPRI5 tableau: Dormand and Prince's explicit Runge–Kutta pair of order 5(4), FSAL, with
its 4th-order continuous extension.

Sources: J. R. Dormand, P. J. Prince, "A family of embedded Runge–Kutta formulae", J. Comput.
Appl. Math. 6 (1980) 19–26 (the pair, "RK5(4)7M"); E. Hairer, S. P. Nørsett, G. Wanner,
*Solving Ordinary Differential Equations I: Nonstiff Problems*, 2nd ed., Springer 1993, §II.5
(Table 5.2) and §II.6 (the dense output of order 4), with the coefficients of the authors'
code ``dopri5.f`` (E. Hairer, G. Wanner, version of 2004). Stages 1 … 6 make the step (stage 6
at t + h), stage 7 is f at the new point — the first stage of the next step (FSAL) — and
enters the error estimate and the dense output. ``tests/test_dopri5.py`` checks the order
conditions and the orders of a plain step built from these numbers.

Error estimate: err = ‖h Σ E_i k_i‖ (scaled RMS norm), E = b − b̂ (5th minus 4th order).
Dense output on the step, θ = (s − t)/h, in the form of DOP853's with three terms fewer: from
F₁ = y₁ − y₀, F₂ = h k₁ − F₁, F₃ = 2F₁ − h (k₁ + k₇) and F₄ = h Σ_i D_i k_i,
y(θ) = y₀ + θ(F₁ + (1−θ)(F₂ + θ(F₃ + (1−θ)F₄))).
"""

from __future__ import annotations

from fractions import Fraction as Fr

import numpy as np

from mechsim.integrators.dop853_tableau import stage_sum, stages_source

C = (Fr(0), Fr(1, 5), Fr(3, 10), Fr(4, 5), Fr(8, 9), Fr(1), Fr(1))

# a_ij, i = 2 … 7 (row 7 = the weights b: the FSAL stage is f at the new point).
A = {
    2: {1: Fr(1, 5)},
    3: {1: Fr(3, 40), 2: Fr(9, 40)},
    4: {1: Fr(44, 45), 2: Fr(-56, 15), 3: Fr(32, 9)},
    5: {1: Fr(19372, 6561), 2: Fr(-25360, 2187), 3: Fr(64448, 6561), 4: Fr(-212, 729)},
    6: {1: Fr(9017, 3168), 2: Fr(-355, 33), 3: Fr(46732, 5247), 4: Fr(49, 176),
        5: Fr(-5103, 18656)},
    7: {1: Fr(35, 384), 3: Fr(500, 1113), 4: Fr(125, 192), 5: Fr(-2187, 6784),
        6: Fr(11, 84)},
}

# Weights b_i of the 5th-order solution, i = 1 … 6.
B = A[7]

# E_i = b_i − b̂_i, i = 1 … 7 (the 4th-order solution uses the FSAL stage too).
E = {1: Fr(71, 57600), 3: Fr(-71, 16695), 4: Fr(71, 1920), 5: Fr(-17253, 339200),
     6: Fr(22, 525), 7: Fr(-1, 40)}

# Dense output: F₄ = h Σ_i D_i k_i, i = 1 … 7 (``dopri5.f``).
D = {1: Fr(-12715105075, 11282082432), 3: Fr(87487479700, 32700410799),
     4: Fr(-10690763975, 1880347072), 5: Fr(701980252875, 199316789632),
     6: Fr(-1453857185, 822651844), 7: Fr(69997945, 29380423)}

N_STAGES = 6  # stages of one step
N_STAGES_FSAL = 7  # with f at the new point


def _vector(table: dict[int, Fr], size: int) -> np.ndarray:
    out = np.zeros(size)
    for i, value in table.items():
        out[i - 1] = float(value)
    return out


#: The same numbers as zero-based arrays of doubles (what the compiled loops read).
NODES = np.array([float(c) for c in C])
STAGES = np.ascontiguousarray(np.vstack(
    [np.zeros(N_STAGES_FSAL)] + [_vector(A[i], N_STAGES_FSAL) for i in range(2, 8)]))
WEIGHTS = _vector(B, N_STAGES)
ERROR = _vector(E, N_STAGES_FSAL)
DENSE = _vector(D, N_STAGES_FSAL)


def loop_source() -> str:
    """The step's stage sums as straight-line numba source, as ``dop853_tableau``'s: the
    shared loops module is built with this text after DOP853's."""
    out = stages_source("_dopri5_stages",
                        "Stages 2 … 6 from (t0, y0) into K[1 … 5]; ytmp ends as stage 6's y.",
                        NODES, STAGES, range(1, N_STAGES))
    # As DOP853's increment: (Σ b_j k_j, Σ E_j k_j, 0), the error sum without the FSAL stage
    # (not there yet: the loop adds it, ``_dopri5_error_fsal``). The third sum is DOP853's
    # 3rd-order estimate, absent here: with it zero, DOP853's error norm
    # e₅² / √(e₅² + 0.01 e₃²) is the plain norm e₅ of DOPRI5.
    out += ["@njit(inline=\"always\")", "def _dopri5_increment(K, i):",
            '    """(Σ b_j k_j, Σ_{j<7} E_j k_j, 0) of component i."""',
            f"    return ({stage_sum(WEIGHTS, range(N_STAGES))}, "
            f"{stage_sum(ERROR, range(N_STAGES))}, 0.0)", "", "",
            "@njit(inline=\"always\")", "def _dopri5_error_fsal(K, i):",
            '    """E_7 k_7 of component i (k_7: f at the new point)."""',
            f"    return {stage_sum(ERROR, range(N_STAGES, N_STAGES_FSAL))}"]
    out += ["", "", "@njit(inline=\"always\")", "def _dopri5_dense_sum(K, i):",
            '    """Σ_j D_j k_j of component i."""',
            f"    return {stage_sum(DENSE, range(N_STAGES_FSAL))}"]
    return "\n".join(out) + "\n"
