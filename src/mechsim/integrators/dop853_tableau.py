"""The DOP853 tableau: Dormand and Prince's explicit Runge–Kutta pair of order 8(5,3) with its
7th-order dense output, as published by Hairer, Nørsett and Wanner.

Source: E. Hairer, S. P. Nørsett, G. Wanner, *Solving Ordinary Differential Equations I:
Nonstiff Problems*, 2nd ed., Springer 1993, §II.5 and §II.10 (the method of Dormand & Prince,
"DOP853"); coefficients as listed in the authors' code ``dop853.f`` (E. Hairer, G. Wanner,
version of 2004), rounded to double precision. Numbering follows the book: stages 1 … 12 make
the step (stage 12 at t + h), stage 13 is f at the new point (first stage of the next step),
stages 14 … 16 serve the dense output only. ``tests/test_dop853_tableau.py`` checks the order
conditions.

Error estimate (``dop853.f``): with e₅ = ‖h Σ E5_i k_i‖ and e₃ = ‖h Σ E3_i k_i‖ (scaled RMS
norms), err = e₅² / √(e₅² + 0.01 e₃²). Dense output on the step, θ = (s − t)/h: from
F₁ = y₁ − y₀, F₂ = h k₁ − F₁, F₃ = 2F₁ − h (k₁ + k₁₃) and F₄ … F₇ = h Σ_i D[r][i] k_i,
y(θ) = y₀ + θ(F₁ + (1−θ)(F₂ + θ(F₃ + (1−θ)(F₄ + θ(F₅ + (1−θ)(F₆ + θF₇)))))).
"""

from __future__ import annotations

import numpy as np

# Nodes c_i, i = 1 … 16 (stage i is evaluated at t + c_i h).
C = (
    0.0, 0.05260015195876773, 0.0789002279381516, 0.1183503419072274, 0.2816496580927726,
    0.3333333333333333, 0.25, 0.3076923076923077, 0.6512820512820513, 0.6, 0.8571428571428571,
    1.0, 1.0, 0.1, 0.2, 0.7777777777777778)

# Stage coefficients a_ij, i = 2 … 16: {i: {j: a_ij}} of the nonzero entries.
A = {
    2: {1: 0.05260015195876773},
    3: {1: 0.0197250569845379, 2: 0.0591751709536137},
    4: {1: 0.02958758547680685, 3: 0.08876275643042054},
    5: {1: 0.2413651341592667, 3: -0.8845494793282861, 4: 0.924834003261792},
    6: {1: 0.037037037037037035, 4: 0.17082860872947386, 5: 0.12546768756682242},
    7: {1: 0.037109375, 4: 0.17025221101954405, 5: 0.06021653898045596, 6: -0.017578125},
    8: {
        1: 0.03709200011850479, 4: 0.17038392571223998, 5: 0.10726203044637328,
        6: -0.015319437748624402, 7: 0.008273789163814023},
    9: {
        1: 0.6241109587160757, 4: -3.3608926294469414, 5: -0.868219346841726,
        6: 27.59209969944671, 7: 20.154067550477894, 8: -43.48988418106996},
    10: {
        1: 0.47766253643826434, 4: -2.4881146199716677, 5: -0.590290826836843,
        6: 21.230051448181193, 7: 15.279233632882423, 8: -33.28821096898486,
        9: -0.020331201708508627},
    11: {
        1: -0.9371424300859873, 4: 5.186372428844064, 5: 1.0914373489967295,
        6: -8.149787010746927, 7: -18.52006565999696, 8: 22.739487099350505,
        9: 2.4936055526796523, 10: -3.0467644718982196},
    12: {
        1: 2.273310147516538, 4: -10.53449546673725, 5: -2.0008720582248625, 6: -17.9589318631188,
        7: 27.94888452941996, 8: -2.8589982771350235, 9: -8.87285693353063,
        10: 12.360567175794303, 11: 0.6433927460157636},
    13: {
        1: 0.054293734116568765, 6: 4.450312892752409, 7: 1.8915178993145003,
        8: -5.801203960010585, 9: 0.3111643669578199, 10: -0.1521609496625161,
        11: 0.20136540080403034, 12: 0.04471061572777259},
    14: {
        1: 0.056167502283047954, 7: 0.25350021021662483, 8: -0.2462390374708025,
        9: -0.12419142326381637, 10: 0.15329179827876568, 11: 0.00820105229563469,
        12: 0.007567897660545699, 13: -0.008298},
    15: {
        1: 0.03183464816350214, 6: 0.028300909672366776, 7: 0.053541988307438566,
        8: -0.05492374857139099, 11: -0.00010834732869724932, 12: 0.0003825710908356584,
        13: -0.00034046500868740456, 14: 0.1413124436746325},
    16: {
        1: -0.42889630158379194, 6: -4.697621415361164, 7: 7.683421196062599, 8: 4.06898981839711,
        9: 0.3567271874552811, 13: -0.0013990241651590145, 14: 2.9475147891527724,
        15: -9.15095847217987},
}

# Weights b_i of the 8th-order solution, i = 1 … 12 (zero where not listed).
B = {
    1: 0.054293734116568765, 6: 4.450312892752409, 7: 1.8915178993145003, 8: -5.801203960010585,
    9: 0.3111643669578199, 10: -0.1521609496625161, 11: 0.20136540080403034,
    12: 0.04471061572777259}

# Embedded error coefficients, i = 1 … 13 (zero where not listed).
E5 = {
    1: 0.01312004499419488, 6: -1.2251564463762044, 7: -0.4957589496572502, 8: 1.6643771824549864,
    9: -0.35032884874997366, 10: 0.3341791187130175, 11: 0.08192320648511571,
    12: -0.022355307863886294}
E3 = {
    1: -0.18980075407240762, 6: 4.450312892752409, 7: 1.8915178993145003, 8: -5.801203960010585,
    9: -0.4226823213237919, 10: -0.1521609496625161, 11: 0.20136540080403034,
    12: 0.02265179219836082}

# Dense output: F₄ … F₇ = h Σ_i D[r][i] k_i, i = 1 … 16.
D = (
    {
        1: -8.428938276109013, 6: 0.5667149535193777, 7: -3.0689499459498917, 8: 2.38466765651207,
        9: 2.117034582445028, 10: -0.871391583777973, 11: 2.2404374302607883,
        12: 0.6315787787694688, 13: -0.08899033645133331, 14: 18.148505520854727,
        15: -9.194632392478356, 16: -4.436036387594894},
    {
        1: 10.427508642579134, 6: 242.28349177525817, 7: 165.20045171727028,
        8: -374.5467547226902, 9: -22.113666853125306, 10: 7.733432668472264,
        11: -30.674084731089398, 12: -9.332130526430229, 13: 15.697238121770845,
        14: -31.139403219565178, 15: -9.35292435884448, 16: 35.81684148639408},
    {
        1: 19.985053242002433, 6: -387.0373087493518, 7: -189.17813819516758,
        8: 527.8081592054236, 9: -11.57390253995963, 10: 6.8812326946963, 11: -1.0006050966910838,
        12: 0.7777137798053443, 13: -2.778205752353508, 14: -60.19669523126412,
        15: 84.32040550667716, 16: 11.99229113618279},
    {
        1: -25.69393346270375, 6: -154.18974869023643, 7: -231.5293791760455,
        8: 357.6391179106141, 9: 93.40532418362432, 10: -37.45832313645163, 11: 104.0996495089623,
        12: 29.8402934266605, 13: -43.53345659001114, 14: 96.32455395918828,
        15: -39.17726167561544, 16: -149.72683625798564},
)

N_STAGES = 12  # stages of one step
N_STAGES_EXTENDED = 16  # with the three dense-output stages


def _vector(table: dict[int, float], size: int) -> np.ndarray:
    out = np.zeros(size)
    for i, value in table.items():
        out[i - 1] = value
    return out


def _matrix(rows: list[dict[int, float]], size: int) -> np.ndarray:
    return np.ascontiguousarray(np.vstack([_vector(row, size) for row in rows]))


#: The same numbers as zero-based C-contiguous arrays (what the compiled loops read).
NODES = np.array(C)
STAGES = _matrix([{}] + [A[i] for i in range(2, N_STAGES_EXTENDED + 1)], N_STAGES_EXTENDED)
WEIGHTS = _vector(B, N_STAGES)
ERROR_5 = _vector(E5, N_STAGES + 1)
ERROR_3 = _vector(E3, N_STAGES + 1)
DENSE = _matrix(list(D), N_STAGES_EXTENDED)


def stage_sum(coefficients: np.ndarray, stages: range, row: str = "K[{j}, i]") -> str:
    """Σ_j c_j K[j, i] over the nonzero coefficients, as Python source with literal values."""
    return " + ".join(f"{float(coefficients[j])!r} * {row.format(j=j)}" for j in stages
                      if coefficients[j] != 0.0)


def stages_source(name: str, doc: str, nodes: np.ndarray, stages: np.ndarray,
                  rows: range) -> list[str]:
    """Source lines of a compiled function ``name(ks, t0, y0, h, K, ytmp, p, n)`` that
    evaluates the stages ``rows`` (zero-based) of an explicit Runge–Kutta tableau from
    (t0, y0) into K[row], each from the stages before it, for the first ``n`` components (the
    integrated ones; the rest of ytmp is left as the caller set it); ytmp ends as the last
    stage's y. Shared by the explicit pairs (DOP853, DOPRI5)."""
    out = ["@njit(cache=True, error_model=\"numpy\")",
           f"def {name}(ks, t0, y0, h, K, ytmp, p, n):", f'    """{doc}"""',
           "    rhs = ks.rhs", "    pp = p.ctypes", "    yp = ytmp.ctypes"]
    for s in rows:
        out += ["    for i in range(n):",
                f"        ytmp[i] = y0[i] + h * ({stage_sum(stages[s], range(s))})",
                f"    rhs(t0 + {float(nodes[s])!r} * h, yp, pp, _row(K, {s}))"]
    return out + ["", ""]


def loop_source() -> str:
    """The step's stage sums as straight-line numba source (coefficients as literals, zero
    entries left out, faster than loops over the dense tableau). The shared loops' module is
    joined with this text in place of the stand-ins of ``mechsim.integrators.compiled.stages``;
    the sums of a component are inlined into the loop, the stages (each with its calls of the
    model) are functions of their own."""
    out = stages_source("_dop853_stages",
                        "Stages 2 … 12 from (t0, y0) into K[1 … 11]; ytmp ends as stage 12's y.",
                        NODES, STAGES, range(1, N_STAGES))
    out += stages_source("_dop853_dense_stages",
                         "Stages 14 … 16 (dense output only) into K[13 … 15].",
                         NODES, STAGES, range(N_STAGES + 1, N_STAGES_EXTENDED))
    out += ["@njit(inline=\"always\")", "def _dop853_increment(K, i):",
            '    """(Σ b_j k_j, Σ E5_j k_j, Σ E3_j k_j) of component i."""',
            f"    return ({stage_sum(WEIGHTS, range(N_STAGES))}, "
            f"{stage_sum(ERROR_5, range(N_STAGES + 1))}, "
            f"{stage_sum(ERROR_3, range(N_STAGES + 1))})"]
    out += ["", "", "@njit(inline=\"always\")", "def _dop853_dense_sums(K, i):",
            '    """Σ_j D[r][j] k_j of component i, r = 0 … 3."""',
            "    return (" + ", ".join(stage_sum(DENSE[r], range(N_STAGES_EXTENDED))
                                     for r in range(4)) + ")"]
    return "\n".join(out) + "\n"
