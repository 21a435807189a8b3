"""Spherical pendulum (Lecture 10, spherical pendulum (eqs. 10.47–10.48)): conical pendulum, small
oscillation about the cone, p_φ and E conserved; with a constant vertical torque G: E − E₀ = G Δφ
and p_φ − p_φ₀ = G t (both from
dE/dt = G φ̇ and ṗ_φ = G). The cone formulas were derived with sympy from the Lagrangian."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mechsim
from mechsim.errors import ParameterError

M, L, G = 0.7, 1.3, 9.81


def _model(**kw: object) -> mechsim.systems.base.Model:
    return mechsim.load_system("spherical_pendulum", mass=M, length=L, gravity=G, **kw)


@pytest.mark.parametrize("th0", [0.3, 1.0, 1.4])
def test_conical_pendulum_and_its_oscillation(th0: float) -> None:
    rate = math.sqrt(G / (L * math.cos(th0)))
    assert _model().conical_rate(th0) == pytest.approx(rate, rel=1e-15)
    steady = mechsim.simulate(_model(**{"initial.polar_angle": th0,
                                        "initial_rate.azimuth": rate}), 5.0, 0.05,
                              tolerance=1e-12)
    assert np.max(np.abs(steady.q[:, 0] - th0)) < 1e-9
    np.testing.assert_allclose(steady.q[:, 1], rate * steady.t, rtol=1e-10, atol=1e-12)
    # Perturb θ̇ slightly at fixed p_φ: θ − θ₀ ≈ (ε/ω) sin ωt with ω² = g(1 + 3cos²θ₀)/(l cos θ₀).
    w = math.sqrt(G / (L * math.cos(th0)) * (1 + 3 * math.cos(th0) ** 2))
    eps = 1e-5
    run = mechsim.simulate(_model(**{"initial.polar_angle": th0, "initial_rate.azimuth": rate,
                                     "initial_rate.polar_angle": eps}), 3 * 2 * math.pi / w,
                           0.002, tolerance=1e-13)
    dev = run.q[:, 0] - th0
    assert np.max(np.abs(dev - eps / w * np.sin(w * run.t))) < 2e-3 * eps / w


def test_free_pendulum_conserves_energy_and_p_phi_long_run() -> None:
    m = _model()
    assert [law.key for law in m.laws()] == ["energy", "energy_function", "work_balance",
                                            "invariant:azimuthal_momentum"]
    run = mechsim.simulate(m, 200.0, 0.05, tolerance=1e-11)
    scale = M * G * L
    assert np.max(np.abs(run.total - run.total[0])) < 1e-9 * scale
    p = run.invariants["azimuthal_momentum"]
    assert np.max(np.abs(p - p[0])) < 1e-9 * abs(p[0])
    assert np.max(np.abs(run.balance_residual)) < 1e-9 * scale


@pytest.mark.parametrize("torque", [0.3, -0.2])
def test_torque_work_balance(torque: float) -> None:
    m = _model(torque=torque)
    assert [law.key for law in m.laws()] == ["work_balance"]
    run = mechsim.simulate(m, 10.0, 0.01, tolerance=1e-12)
    dphi = run.q[:, 1] - run.q[0, 1]
    scale = M * G * L
    # E − E₀ = ∫ G φ̇ dt = G Δφ (the engine's W_ext must be exactly that work).
    assert np.max(np.abs((run.total - run.total[0]) - torque * dphi)) < 1e-9 * scale
    assert np.max(np.abs(run.work_external - torque * dphi)) < 1e-9 * scale
    p = run.observables["azimuthal_momentum"]
    assert np.max(np.abs(p - p[0] - torque * run.t)) < 1e-9 * M * L * L
    assert np.max(np.abs(run.balance_residual)) < 1e-9 * scale


def test_parameter_validation() -> None:
    with pytest.raises(ParameterError, match="^initial.polar_angle: must be > 0"):
        _model(**{"initial.polar_angle": 0.0})
    with pytest.raises(ParameterError, match="^length: must be > 0"):
        mechsim.load_system("spherical_pendulum", length=-1.0)
