"""The Hamiltonian formulation generated from a declared Lagrangian (PHYS0500 – Advanced
Classical Mechanics, §3.6 Hamiltonian Dynamics): its state holds the canonical momenta, checked
here against momenta and Hamiltonians written by hand (pendulum, double pendulum, charged
particle in cylindrical coordinates with its velocity-dependent potential); its trajectory
against the Lagrangian formulation it comes from, integrated separately; H equal to the
published energy function."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mechsim
from mechsim.errors import ParameterError
from mechsim.integrators import make_stepper
from mechsim.runcore.run import Block

TOL = 1e-12


def _states(model: mechsim.Model, t: np.ndarray) -> np.ndarray:
    """The raw state rows (q, p, work terms) of a run of ``model``."""
    return make_stepper(model, "dop853", TOL).advance(t)


def test_pendulum_momentum_and_hamiltonian() -> None:
    m, R, g = 1.7, 0.8, 9.81
    kw = {"mass": m, "length": R, "gravity": g, "initial.angle": 2.5,
          "initial_rate.angle": 0.4}
    ham = mechsim.load_system("pendulum", formulation="hamiltonian", **kw)
    lag = mechsim.load_system("pendulum", **kw)
    assert ham.initial_y()[1] == pytest.approx(m * R * R * 0.4, rel=1e-15)  # p = m R² φ̇
    t = np.linspace(0.0, 10.0, 501)
    Y = _states(ham, t)
    phi, p = Y[:, 0], Y[:, 1]
    H = p**2 / (2 * m * R * R) + m * g * R * (1 - np.cos(phi))
    run_h = mechsim.simulate(ham, 10.0, 0.02, tolerance=TOL, method="dop853")
    run_l = mechsim.simulate(lag, 10.0, 0.02, tolerance=TOL, method="dop853")
    assert np.max(np.abs(H - run_h.energy_function)) < 1e-12 * H[0]
    assert np.max(np.abs(H - H[0])) < 1e-9 * H[0]
    # the published rates are q̇ = p/(m R²), not p; the trajectory is the Lagrangian one
    assert np.max(np.abs(run_h.v[:, 0] - p / (m * R * R))) < 1e-12
    assert np.max(np.abs(run_h.q - run_l.q)) < 1e-8
    assert np.max(np.abs(run_h.v - run_l.v)) < 1e-8


def test_double_pendulum_hamiltonian_by_hand() -> None:
    """H(θ, p) of the double pendulum with the Legendre transform done by hand (the mass
    matrix inverted in closed form); regular motion, so the forms agree to the tolerance."""
    m1, m2, l1, l2, g = 1.2, 0.7, 1.0, 0.6, 9.81
    kw = {"mass_1": m1, "mass_2": m2, "length_1": l1, "length_2": l2, "gravity": g,
          "initial.angle_1": 0.3, "initial.angle_2": -0.2, "initial_rate.angle_1": 0.5}
    ham = mechsim.load_system("double_pendulum", formulation="hamiltonian", **kw)
    t = np.linspace(0.0, 8.0, 401)
    Y = _states(ham, t)
    a1, a2, p1, p2 = Y[:, 0], Y[:, 1], Y[:, 2], Y[:, 3]
    c, s = np.cos(a1 - a2), np.sin(a1 - a2)
    T = (m2 * l2**2 * p1**2 + (m1 + m2) * l1**2 * p2**2 - 2 * m2 * l1 * l2 * p1 * p2 * c) / (
        2 * m2 * l1**2 * l2**2 * (m1 + m2 * s**2))
    V = -(m1 + m2) * g * l1 * np.cos(a1) - m2 * g * l2 * np.cos(a2)
    run_h = mechsim.simulate(ham, 8.0, 0.02, tolerance=TOL, method="dop853")
    run_l = mechsim.simulate(mechsim.load_system("double_pendulum", **kw), 8.0, 0.02,
                             tolerance=TOL, method="dop853")
    scale = float(np.max(np.abs(run_l.kinetic)))
    assert np.max(np.abs(run_h.kinetic - T)) < 1e-12 * scale
    offset = run_h.potential - V  # the system's zero of V: a constant
    assert np.ptp(offset) < 1e-12 * scale
    assert np.max(np.abs(run_h.energy_function - (T + V + offset[0]))) < 1e-12 * scale
    assert np.max(np.abs(run_h.q - run_l.q)) < 1e-8
    assert np.max(np.abs(run_h.v - run_l.v)) < 1e-8


def test_charged_particle_canonical_momentum_is_not_m_v() -> None:
    """Cylindrical coordinates, uniform B along z: p_φ = m ρ² φ̇ + ½ q B ρ² (the vector
    potential's share), constant to the last bit (φ is cyclic: ṗ_φ = ∂L/∂φ = 0);
    H = (p_ρ² + (p_φ − ½ q B ρ²)²/ρ² + p_z²)/2m + q φ_E."""
    m, q, B, Ez = 1.3, 0.8, 2.0, 0.3
    kw = {"mass": m, "charge": q, "magnetic_field": B, "electric_field.z": Ez}
    ham = mechsim.load_system("charged_particle", formulation="hamiltonian", **kw)
    t = np.linspace(0.0, 6.0, 301)
    Y = _states(ham, t)
    rho, z, p_rho, p_phi, p_z = Y[:, 0], Y[:, 2], Y[:, 3], Y[:, 4], Y[:, 5]
    lag = mechsim.load_system("charged_particle", **kw)
    q0, v0 = lag.initial_state()
    assert p_phi[0] == pytest.approx(m * q0[0]**2 * v0[1] + q * B * q0[0]**2 / 2, rel=1e-15)
    assert np.all(p_phi == p_phi[0])
    H = (p_rho**2 + (p_phi - q * B * rho**2 / 2)**2 / rho**2 + p_z**2) / (2 * m) - q * Ez * z
    run_h = mechsim.simulate(ham, 6.0, 0.02, tolerance=TOL, method="dop853")
    assert np.max(np.abs(run_h.energy_function - H)) < 1e-12 * max(1.0, abs(H[0]))
    run_l = mechsim.simulate(lag, 6.0, 0.02, tolerance=TOL, method="dop853")
    assert np.max(np.abs(run_h.q - run_l.q)) < 1e-8
    assert np.max(np.abs(run_h.v - run_l.v)) < 1e-8
    assert run_h.model.chosen_formulation == "hamiltonian"
    assert run_h.model.formulation == "cylindrical"


def test_methods_that_need_q_dot_in_the_state_refuse() -> None:
    ham = mechsim.load_system("pendulum", formulation="hamiltonian")
    with pytest.raises(ParameterError, match="radau15"):
        mechsim.simulate(ham, 1.0, 0.1, method="radau15")
    with pytest.raises(ParameterError):
        mechsim.simulate(ham, 1.0, 0.1, method="exact")
    run = mechsim.simulate(ham, 1.0, 0.1, tolerance=1e-11)  # auto: an explicit method
    assert run.method == "dop853" and math.isfinite(float(run.q[-1, 0]))


def test_the_run_core_releases_rates_not_momenta() -> None:
    """What a node publishes as JointState velocity (``Block.rates``) is q̇ in the Hamiltonian
    form too: the Lagrangian form's rates, run separately."""
    from test_runcore import Collector, _run  # the plain-Python observer of the core's tests

    class Rates(Collector):
        def __init__(self) -> None:
            super().__init__()
            self.rates: list[np.ndarray] = []

        def encode(self, block: Block) -> None:
            self.rates += list(block.rates)
            super().encode(block)

    kw = {"mass": 2.0, "length": 1.5, "initial.angle": 1.0, "initial_rate.angle": 0.7}
    _, ham = _run("pendulum", {"formulation": "hamiltonian", **kw}, "dop853", 2.0, Rates())
    _, lag = _run("pendulum", kw, "dop853", 2.0, Rates())
    for seen in (ham, lag):
        assert seen.run is not None
        seen.run.advance_to(2.0)
    p = np.array(ham.Y)[:, 1]
    assert np.max(np.abs(p - 2.0 * 1.5**2 * np.array(ham.rates)[:, 0])) < 1e-12  # p = m R² φ̇
    assert np.max(np.abs(np.array(ham.rates) - np.array(lag.Y)[:, 1:2])) < 1e-8
