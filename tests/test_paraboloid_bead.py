"""Particle inside z = a r² (Lecture 10, particle inside a vertical paraboloid (eqs. 10.31–10.36)):
steady circle v₀ = r₀√(2ag) with λ = mg, the multiplier identity
λ = (mg + 4aE + 8a³J_z²/m)/(1 + 4a²r²)² (checked here with sympy against the z-equation form
λ = m[g + 2a(ṙ² + r²φ̇²)]/(1 + 4a²r²), and numerically against the engine's multiplier), λ ≥ 0, E
and J_z conserved, radial frequency ω_r = 2√(2ag)/√(1 + 4a²r₀²)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import mechsim
from mechsim.errors import ParameterError

M, A, G = 0.9, 0.5, 9.81


def _model(form: str, r0: float, w0: float, dr0: float = 0.0) -> mechsim.systems.base.Model:
    return mechsim.load_system("paraboloid_bead", formulation=form, mass=M,
                               paraboloid_coefficient=A, gravity=G,
                               **{"initial.radius": r0, "initial_rate.azimuth": w0,
                                  "initial_rate.radius": dr0})


def test_multiplier_identity_symbolically() -> None:
    m, a, g, r = sp.symbols("m a g r", positive=True)
    rd, wd = sp.symbols("rd wd", real=True)
    E = m * ((1 + 4 * a**2 * r**2) * rd**2 + r**2 * wd**2) / 2 + m * g * a * r**2
    J = m * r**2 * wd
    from_z_equation = m * (g + 2 * a * (rd**2 + r**2 * wd**2)) / (1 + 4 * a**2 * r**2)
    identity = (m * g + 4 * a * E + 8 * a**3 * J**2 / m) / (1 + 4 * a**2 * r**2) ** 2
    assert sp.simplify(from_z_equation - identity) == 0


@pytest.mark.parametrize("form", ["multiplier", "reduced"])
@pytest.mark.parametrize("r0", [0.4, 1.0, 2.0])
def test_steady_circle(form: str, r0: float) -> None:
    w = _model(form, r0, 1.0).steady_rate()  # the model's oracle, checked against the
    assert w == pytest.approx(math.sqrt(2 * A * G), rel=1e-15)  # document's φ̇² = 2ag
    run = mechsim.simulate(_model(form, r0, w), 5.0, 0.05, tolerance=1e-12)
    assert np.max(np.abs(run.q[:, 0] - r0)) < 1e-9 * r0
    np.testing.assert_allclose(run.observables["multiplier"], M * G, rtol=1e-9)
    np.testing.assert_allclose(run.observables["normal_force"],
                               M * G * math.sqrt(1 + 4 * A * A * r0 * r0), rtol=1e-9)


@pytest.mark.parametrize("form", ["multiplier", "reduced"])
def test_multiplier_from_invariants_and_conservation(form: str) -> None:
    run = mechsim.simulate(_model(form, 1.0, 2.0, 0.7), 30.0, 0.01, tolerance=1e-12)
    r = run.q[:, 0]
    E = run.total
    J = run.invariants["angular_momentum"]
    lam = (M * G + 4 * A * E + 8 * A**3 * J**2 / M) / (1 + 4 * A * A * r * r) ** 2
    np.testing.assert_allclose(run.observables["multiplier"], lam, rtol=1e-8)
    assert run.observables["multiplier"].min() > 0
    scale = M * G * A
    assert np.max(np.abs(E - E[0])) < 1e-9 * scale
    assert np.max(np.abs(J - J[0])) < 1e-10 * abs(J[0])
    assert np.max(np.abs(run.balance_residual)) < 1e-9 * scale
    # Turning radii from m g a u² − E u + J²/(2m) = 0, u = r².
    disc = math.sqrt(E[0] ** 2 - 2 * G * A * J[0] ** 2)
    u_lo, u_hi = (E[0] - disc) / (2 * M * G * A), (E[0] + disc) / (2 * M * G * A)
    assert abs(r.min() ** 2 - u_lo) < 1e-3 * u_lo and abs(r.max() ** 2 - u_hi) < 1e-3 * u_hi
    assert np.all(r**2 > u_lo - 1e-9) and np.all(r**2 < u_hi + 1e-9)
    if form == "multiplier":
        assert np.max(np.abs(run.invariants["constraint_surface"])) < 1e-12


def test_forms_agree_and_radial_frequency() -> None:
    r0 = 0.8
    w = math.sqrt(2 * A * G)
    wr = 2 * math.sqrt(2 * A * G) / math.sqrt(1 + 4 * A * A * r0 * r0)
    eps = 1e-5
    runs = [mechsim.simulate(_model(f, r0, w, eps), 3 * 2 * math.pi / wr, 0.002,
                             tolerance=1e-13) for f in ("multiplier", "reduced")]
    np.testing.assert_allclose(runs[0].q[:, :2], runs[1].q[:, :2], atol=1e-9)
    np.testing.assert_allclose(runs[0].observables["multiplier"],
                               runs[1].observables["multiplier"], rtol=1e-8)
    dev = runs[1].q[:, 0] - r0
    assert np.max(np.abs(dev - eps / wr * np.sin(wr * runs[1].t))) < 2e-3 * eps / wr


def test_parameter_validation() -> None:
    with pytest.raises(ParameterError, match="^initial_rate.azimuth: must be non-zero"):
        _model("reduced", 1.0, 0.0)
    with pytest.raises(ParameterError, match="^paraboloid_coefficient: must be > 0"):
        mechsim.load_system("paraboloid_bead", paraboloid_coefficient=0.0)
