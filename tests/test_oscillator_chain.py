"""A chain of identical oscillators (PHYS0500 §8.1, §8.3–8.4): its frequencies and modes against
scipy's generalized eigenproblem |A − ω²M| = 0 of the stiffness matrix built here; the notes'
claim (n/2 frequencies above ω₀, n/2 below, ω₀ itself for odd n) holds with walls at both ends
and not otherwise, as the eigenvalues computed here show; the integrated motion is the modal
superposition computed here from the same eigenproblem."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import eigh

import mechsim

M, KAPPA = 0.8, 3.0


def _stiffness(n: int, walls: str) -> np.ndarray:
    """A of V = ½ xᵀ A x: neighbours joined by κ, a wall spring κ at each walled end."""
    A = np.zeros((n, n))
    for j in range(n - 1):
        A[j, j] += KAPPA
        A[j + 1, j + 1] += KAPPA
        A[j, j + 1] -= KAPPA
        A[j + 1, j] -= KAPPA
    if walls in ("both", "left"):
        A[0, 0] += KAPPA
    if walls == "both":
        A[-1, -1] += KAPPA
    return A


def _eig(n: int, walls: str) -> tuple[np.ndarray, np.ndarray]:
    w2, a = eigh(_stiffness(n, walls), M * np.eye(n))
    return np.sqrt(np.clip(w2, 0.0, None)), a


def _model(n: int, walls: str, **kw: float) -> mechsim.Model:
    return mechsim.load_system("oscillator_chain", count=n, walls=walls, mass=M,
                               spring_constant=KAPPA, **kw)


@pytest.mark.parametrize("walls", ["both", "left", "none"])
def test_frequencies_against_the_eigenproblem(walls: str) -> None:
    for n in range(1, 13):
        w, _ = _eig(n, walls)
        assert np.allclose(_model(n, walls).mode_frequencies(), w, rtol=1e-12,
                           atol=1e-7 * w[-1])


@pytest.mark.parametrize("walls", ["both", "left", "none"])
def test_the_n_over_2_claim_needs_both_walls(walls: str) -> None:
    w0 = math.sqrt(2 * KAPPA / M)  # one mass between two held neighbours: κ + κ₁₂, κ₁₂ = κ
    holds = []
    for n in range(1, 13):
        w, _ = _eig(n, walls)
        at = np.isclose(w, w0, rtol=1e-9)
        below, above = int(np.sum((w < w0) & ~at)), int(np.sum((w > w0) & ~at))
        claim = below == above == n // 2 and int(at.sum()) == n % 2
        assert _model(n, walls).document_claim_holds() == claim
        holds.append(claim)
    if walls == "both":
        assert all(holds)
    elif walls == "left":  # holds for even n only: ω₀ is never a frequency
        assert holds == [n % 2 == 0 for n in range(1, 13)]
    else:
        assert not any(holds)


@pytest.mark.parametrize(("n", "walls"), [(5, "both"), (4, "left"), (3, "none")])
def test_motion_is_the_modal_superposition(n: int, walls: str) -> None:
    D = 0.1
    run = mechsim.simulate(_model(n, walls, **{"initial.amplitude": D}), 20.0, 0.02,
                           tolerance=1e-12, method="dop853")
    w, a = _eig(n, walls)  # M-orthonormal columns
    x0 = np.zeros(n)
    x0[0] = D
    eta0 = a.T @ (M * x0)
    expected = (eta0 * np.cos(np.outer(run.t, w))) @ a.T
    assert np.max(np.abs(run.q - expected)) < 1e-9
    for r in range(n):
        e = run.invariants[f"mode_energy_{r + 1}"]
        assert np.max(np.abs(e - e[0])) < 1e-11 * np.max(run.total)


def test_pure_mode_stays_pure() -> None:
    n, r = 6, 4
    run = mechsim.simulate(_model(n, "both", **{"initial.mode": r}), 10.0, 0.05,
                           tolerance=1e-12)
    shape = np.sin(np.arange(1, n + 1) * r * math.pi / (n + 1))
    ratio = run.q / (shape / np.max(np.abs(shape)))
    assert np.max(np.abs(ratio - ratio[:, :1])) < 1e-8
    w = 2 * math.sqrt(KAPPA / M) * math.sin(r * math.pi / (2 * (n + 1)))
    assert np.max(np.abs(ratio[:, 0] - 0.1 * np.cos(w * run.t))) < 1e-9
