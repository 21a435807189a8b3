"""Geodesics (PHYS0500 ch. 2): constant speed, great circles on the sphere (L fixed, path in the
plane ⟂ L, period 2πR/v, normal force −mv²/R), helices on the cylinder (exact φ(t), z(t)),
straight lines on the unrolled cone (|r|² = |r₀|² + 2r₀·v₀t + v²t², since the normal force is
⟂ r on a cone through the apex), Clairaut's ρ²φ̇, constraint residual at round-off."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mechsim
from mechsim.errors import ParameterError

M, R, V = 0.7, 1.4, 1.3


def _run(surface: str, t_end: float, **kw: object) -> mechsim.simulate.SimulationResult:
    m = mechsim.load_system("geodesic", surface=surface, mass=M, radius=R,
                            **{"initial.speed": V, **kw})
    return mechsim.simulate(m, t_end, 0.01, tolerance=1e-12)


def _common(run: mechsim.simulate.SimulationResult) -> None:
    speed = np.linalg.norm(run.v, axis=1)
    assert np.max(np.abs(speed - V)) < 1e-10 * V
    assert np.max(np.abs(run.total - run.total[0])) < 1e-10 * M * V * V
    assert np.max(np.abs(run.invariants["constraint_surface"])) < 1e-13
    c = run.invariants["clairaut"]
    assert np.max(np.abs(c - c[0])) < 1e-10 * R * V
    assert np.max(np.abs(run.balance_residual)) < 1e-10 * M * V * V


@pytest.mark.parametrize("psi", [0.0, 0.6, 1.3])
def test_sphere_great_circle(psi: float) -> None:
    period = 2 * math.pi * R / V
    run = _run("sphere", period, **{"initial.height": 0.5, "initial.heading": psi})
    _common(run)
    Lvec = M * np.cross(run.q, run.v)
    assert np.max(np.abs(Lvec - Lvec[0])) < 1e-10 * M * R * V
    n = Lvec[0] / np.linalg.norm(Lvec[0])
    assert np.max(np.abs(run.q @ n)) < 1e-10 * R  # in the plane through the centre ⟂ L
    assert np.max(np.abs(run.q[-1] - run.q[0])) < 1e-9 * R  # closed after 2πR/v
    np.testing.assert_allclose(run.observables["normal_force"], -M * V * V / R, rtol=1e-9)
    for name in ("angular_momentum_x", "angular_momentum_y"):
        assert np.max(np.abs(run.invariants[name] - run.invariants[name][0])) < 1e-10 * M * R * V


def test_cylinder_helix() -> None:
    psi, z0, phi0 = 0.4, 0.2, 0.3
    run = _run("cylinder", 8.0, **{"initial.height": z0, "initial.heading": psi,
                                   "initial.azimuth": phi0})
    _common(run)
    phi = phi0 + V * math.cos(psi) / R * run.t
    expected = np.column_stack([R * np.cos(phi), R * np.sin(phi), z0 + V * math.sin(psi) * run.t])
    assert np.max(np.abs(run.q - expected)) < 1e-9
    np.testing.assert_allclose(run.observables["normal_force"], -M * (V * math.cos(psi)) ** 2 / R,
                               rtol=1e-9)


@pytest.mark.parametrize(("alpha", "psi"), [(0.5, 0.3), (0.3, -0.8)])
def test_cone_straight_line_when_unrolled(alpha: float, psi: float) -> None:
    run = _run("cone", 6.0, half_angle=alpha, **{"initial.height": 1.0, "initial.heading": psi})
    _common(run)
    r0, v0 = run.q[0], run.v[0]
    d2 = r0 @ r0 + 2 * (r0 @ v0) * run.t + V * V * run.t**2
    np.testing.assert_allclose(np.sum(run.q**2, axis=1), d2, rtol=1e-10)
    # Clairaut: closest approach to the axis where the heading is along the parallel.
    c = run.invariants["clairaut"][0]
    rho_min = abs(c) / V
    assert run.observables["axis_distance"].min() >= rho_min * (1 - 1e-9)
    assert run.observables["normal_force"].max() <= 0  # the surface pulls inward (concave side)


def test_parameter_validation() -> None:
    with pytest.raises(ParameterError, match="^initial.height: must be inside"):
        mechsim.load_system("geodesic", surface="sphere", radius=1.0, **{"initial.height": 2.0})
    with pytest.raises(ParameterError, match="^initial.height: must be > 0 on the cone"):
        mechsim.load_system("geodesic", surface="cone", **{"initial.height": -1.0})
    with pytest.raises(ParameterError, match="^initial.heading: straight down"):
        mechsim.load_system("geodesic", surface="cone", **{"initial.heading": -math.pi / 2})
    with pytest.raises(ParameterError, match="^surface: must be one of"):
        mechsim.load_system("geodesic", surface="torus")
