"""Rotating frame and the rotating Earth (PHYS0500 ch. 6).

References: the rotating-frame particle obeys the linear constant-coefficient system
r̈ = g − 2ω × ṙ − ω × (ω × r), solved exactly here with a matrix exponential; a free particle is
a straight line in the fixed axes (catalog oracle); first-order eastward deflection and the
Foucault rate −Ω sin λ (catalog 003 §6.2); the rotating and inertial formulations agree.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.spatial.transform import Rotation

import mechsim
from mechsim.errors import ParameterError

SYS = "rotating_frame"


def enu(r: mechsim.SimulationResult) -> np.ndarray:
    return np.stack([r.observables[n] for n in ("east", "north", "up")], axis=1)


def exact_path(lat: float, Om: float, g: float, r0: np.ndarray, v0: np.ndarray,
               t: np.ndarray) -> np.ndarray:
    w = Om * np.array([0.0, math.cos(lat), math.sin(lat)])
    W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    A = np.zeros((7, 7))
    A[0:3, 3:6] = np.eye(3)
    A[3:6, 0:3] = -W @ W
    A[3:6, 3:6] = -2 * W
    A[3:6, 6] = [0, 0, -g]
    s0 = np.concatenate([r0, v0, [1.0]])
    return np.array([expm(A * tk) @ s0 for tk in t])[:, :3]


FAST = {"rotation_rate": 0.3, "latitude": 0.7, "initial.east": 1.0, "initial.north": -2.0,
        "initial.up": 50.0, "initial_rate.east": 3.0, "initial_rate.north": 1.0,
        "initial_rate.up": 4.0}


@pytest.mark.parametrize("formulation", ["rotating", "inertial"])
def test_exact_solution_fast_rotation(formulation: str) -> None:
    m = mechsim.load_system(SYS, formulation=formulation, **FAST)
    r = mechsim.simulate(m, 5.0, 0.1, tolerance=1e-12)
    ref = exact_path(0.7, 0.3, 9.81, np.array([1.0, -2.0, 50.0]), np.array([3.0, 1.0, 4.0]),
                     r.t)
    assert np.max(np.abs(enu(r) - ref)) < 1e-8
    J = r.invariants["jacobi_integral"]
    assert np.max(np.abs(J - J[0])) < 1e-10 * abs(J[0])
    assert np.max(np.abs(r.balance_residual)) < 1e-9 * np.max(np.abs(r.total))
    # the inertial energy E = T + V is not conserved, J = E − ω·L is
    assert np.ptp(r.total) > 1.0
    assert "energy" not in [law.kind for law in m.laws()]


def test_free_particle_is_a_straight_line_in_fixed_axes() -> None:
    m = mechsim.load_system(SYS, gravity=0.0, **FAST)
    r = mechsim.simulate(m, 8.0, 0.2, tolerance=1e-12)
    w = m.omega_enu()
    r0, v0 = np.array([1.0, -2.0, 50.0]), np.array([3.0, 1.0, 4.0])
    X = r0 + np.outer(r.t, v0 + np.cross(w, r0))  # eq. 6.2 at t = 0, then uniform motion
    rot = Rotation.from_rotvec(-np.outer(r.t, w))
    assert np.max(np.abs(enu(r) - rot.apply(X))) < 1e-8


def test_eastward_deflection() -> None:
    m = mechsim.load_system(SYS, **{"initial.east": 0.0, "latitude": math.radians(40)})
    t_fall = math.sqrt(2 * 100.0 / 9.81)
    r = mechsim.simulate(m, t_fall, t_fall, tolerance=1e-13)
    assert m.eastward_deflection() == pytest.approx(0.016815, abs=1e-6)  # catalog: 1.6815 cm
    assert r.observables["east"][-1] == pytest.approx(m.eastward_deflection(), rel=1e-6)
    assert abs(r.observables["up"][-1]) < 1e-5  # lands at t = √(2h/g) up to O(Ω²)
    south = mechsim.load_system(SYS, **{"initial.east": 0.0, "latitude": -math.radians(40)})
    rs = mechsim.simulate(south, t_fall, t_fall, tolerance=1e-13)
    assert rs.observables["east"][-1] == pytest.approx(r.observables["east"][-1], rel=1e-12)
    # vertical launch to height h lands west by 4/3 ω cosλ √(8h³/g) (catalog supplement)
    v_up = math.sqrt(2 * 9.81 * 100.0)
    up = mechsim.load_system(SYS, **{"initial.east": 0.0, "initial.up": 0.0,
                                     "initial_rate.up": v_up})
    ru = mechsim.simulate(up, 2 * v_up / 9.81, 2 * v_up / 9.81, tolerance=1e-13)
    assert ru.observables["east"][-1] == pytest.approx(-4 * m.eastward_deflection(), rel=1e-5)


def plane_rate(r: mechsim.SimulationResult) -> float:
    angle = np.unwrap(2 * r.observables["swing_plane_angle"]) / 2
    return float(np.polyfit(r.t, angle, 1)[0])


def test_foucault_precession_exaggerated_rotation() -> None:
    m = mechsim.load_system(SYS, formulation="foucault_pendulum", rotation_rate=0.01)
    r = mechsim.simulate(m, 300.0, 0.5, tolerance=1e-11)
    assert plane_rate(r) == pytest.approx(m.foucault_rate(), rel=2e-3)
    assert m.foucault_rate() == pytest.approx(-0.01 * math.sin(math.radians(40)))
    J = r.invariants["jacobi_integral"]
    assert np.max(np.abs(J - J[0])) < 1e-9 * abs(r.kinetic.max())
    assert np.max(np.abs(r.invariants["constraint_rod_length"])) < 1e-13
    # the rod pulls: tension ≈ m g (small amplitude) and never negative
    assert r.observables["tension"].min() > 0.95 * 9.81
    # southern hemisphere: the other way round
    s = mechsim.simulate(m.with_values(latitude=-math.radians(40)), 300.0, 0.5,
                         tolerance=1e-11)
    assert plane_rate(s) == pytest.approx(-m.foucault_rate(), rel=2e-3)


def test_foucault_precession_earth_rate() -> None:
    m = mechsim.load_system(SYS, formulation="foucault_pendulum",
                            latitude=math.radians(48.85))  # Paris
    r = mechsim.simulate(m, 1200.0, 1.0, tolerance=1e-11)
    assert plane_rate(r) == pytest.approx(m.foucault_rate(), rel=3e-3)
    # a full turn of the plane takes one sidereal day / sin λ
    assert 2 * math.pi / abs(m.foucault_rate()) / 3600 == pytest.approx(
        86164.1 / math.sin(math.radians(48.85)) / 3600, rel=1e-5)


def test_frames() -> None:
    m = mechsim.load_system(SYS, formulation="foucault_pendulum", rotation_rate=0.01,
                            earth_radius=100.0)
    r = mechsim.simulate(m, 10.0, 5.0)
    names = [f.child for f in m.frames]
    assert names == ["earth", "enu", "pivot", "bob", "swing_plane"]
    assert [f.static for f in m.frames] == [False, True, True, False, False]
    lat = math.radians(40)
    f = r.outputs.frames
    E, N, U = Rotation.from_quat(f[0, 1, 3:]).as_matrix().T
    assert np.allclose(E, [0, 1, 0]) and np.allclose(U, [math.cos(lat), 0, math.sin(lat)])
    assert np.allclose(N, [-math.sin(lat), 0, math.cos(lat)])
    assert np.allclose(f[0, 1, :3], 100 * U)
    Rz = Rotation.from_quat(f[-1, 0, 3:]).as_matrix()
    assert np.allclose(Rz, Rotation.from_euler("z", 0.01 * 10.0).as_matrix())
    # ω in the ENU frame is the Earth's axis: world z seen from ENU = (0, cos λ, sin λ)
    assert np.allclose(np.array([E, N, U]) @ [0, 0, 1], [0, math.cos(lat), math.sin(lat)])
    assert np.allclose(f[:, 3, :3], enu(r))
    assert np.allclose(f[0, 2, :3], [0, 0, 10.0])


def test_parameters() -> None:
    with pytest.raises(ParameterError, match="^latitude:"):
        mechsim.load_system(SYS, latitude=2.0)
    with pytest.raises(ParameterError, match="^initial.east:"):
        mechsim.load_system(SYS, formulation="foucault_pendulum", **{"initial.east": 10.0})
    with pytest.raises(ParameterError, match="^formulation:"):
        mechsim.load_system(SYS, formulation="newtonian")
