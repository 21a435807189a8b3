"""Kepler problem (PHYS0500 §4.6): Kepler's equation, period, apsides, conserved L and LRL
vector, long-run energy conservation. Oracles computed here (scipy root finding)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

import mechsim

GM, MU, A, E = 2.0, 0.5, 1.7, 0.6


def _kepler_position(t: float) -> tuple[float, float]:
    n = math.sqrt(GM / A**3)
    M = (n * t) % (2 * math.pi)
    Ea = brentq(lambda x: x - E * math.sin(x) - M, 0.0, 2 * math.pi, xtol=1e-15)
    return A * (math.cos(Ea) - E), A * math.sqrt(1 - E * E) * math.sin(Ea)


@pytest.fixture(scope="module")
def run() -> mechsim.SimulationResult:
    m = mechsim.load_system("kepler", gravitational_parameter=GM, reduced_mass=MU,
                            semi_major_axis=A, eccentricity=E)
    period = 2 * math.pi * math.sqrt(A**3 / GM)
    return mechsim.simulate(m, 3 * period, period / 500, tolerance=1e-12)


def test_positions_match_keplers_equation(run: mechsim.SimulationResult) -> None:
    exact = np.array([_kepler_position(t) for t in run.t])
    assert np.max(np.abs(run.q - exact)) < 1e-9 * A
    # the model's oracle (Newton on Kepler's equation) is this solution, and so is the run
    assert np.max(np.abs(run.model.position_at(run.t) - exact)) < 1e-12 * A


def test_period_apsides_and_elements(run: mechsim.SimulationResult) -> None:
    period = 2 * math.pi * math.sqrt(A**3 / GM)
    k = int(round(period / (run.t[1] - run.t[0])))
    assert np.allclose(run.q[k], run.q[0], atol=1e-9)
    r = run.observables["radius"]
    assert r.min() == pytest.approx(A * (1 - E), rel=1e-10)
    assert r.max() == pytest.approx(A * (1 + E), rel=1e-7)
    energy = run.total[0]
    assert energy == pytest.approx(-MU * GM / (2 * A), rel=1e-12)  # a = k / 2|E|, k = μGM
    L = run.invariants["angular_momentum"][0]
    assert L == pytest.approx(MU * math.sqrt(GM * A * (1 - E * E)), rel=1e-12)
    Ax, Ay = run.invariants["runge_lenz_x"], run.invariants["runge_lenz_y"]
    assert math.hypot(Ax[0], Ay[0]) == pytest.approx(MU * (MU * GM) * E, rel=1e-12)
    assert abs(Ay[0]) < 1e-12  # points to pericentre on +x


def test_invariants_conserved(run: mechsim.SimulationResult) -> None:
    for name in ("angular_momentum", "runge_lenz_x"):
        v = run.invariants[name]
        assert np.max(np.abs(v - v[0])) < 1e-10 * abs(v[0])
    assert np.max(np.abs(run.invariants["runge_lenz_y"])) < 1e-10 * MU * MU * GM
    assert np.allclose(run.observables["areal_velocity"],
                       run.invariants["angular_momentum"] / (2 * MU), rtol=1e-14)


def test_long_run_energy_default_settings() -> None:
    """10⁴ orbits of the default orbit (e = 0.5) at default settings: |ΔE/E| ≤ 1e-10."""
    m = mechsim.load_system("kepler")
    period = 2 * math.pi
    run = mechsim.simulate(m, 1e4 * period, period / 2, outputs=("energy", "invariants"))
    E0 = run.total[0]
    assert np.max(np.abs(run.total - E0)) / abs(E0) <= 1e-10
    L = run.invariants["angular_momentum"]
    assert np.max(np.abs(L - L[0])) / abs(L[0]) <= 1e-10


def test_bad_eccentricity() -> None:
    with pytest.raises(mechsim.ParameterError, match="eccentricity: must be < 1"):
        mechsim.load_system("kepler", eccentricity=1.0)
