"""Moving frames on the twisted cubic (“Moving Frames and the Twisted Cubic” and “Minimal Frames”).

Expected values come from closed forms written here independently of the model (the catalog's
N̂ = (u², −2u, 1)/|·|, R̂ = sgn(u)(1, u, u²)/|·|, ...), angular velocities from central
differences of those closed forms, and κ, τ from a sympy derivation of the general formulas.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from scipy.spatial.transform import Rotation

import mechsim
from mechsim.errors import ParameterError
from mechsim.systems import _rotation as rot


def _unit(w: np.ndarray) -> np.ndarray:
    return w / np.linalg.norm(w)


def closed_form_axes(u: float) -> dict[str, np.ndarray]:
    """Rows = axes. Frames as published: VBN in the right-handed order (V, N, B)."""
    v = np.array([1.0, 2 * u, 3 * u * u])
    a = np.array([0.0, 2.0, 6 * u])
    r = np.array([u, u * u, u**3])
    V = _unit(v)
    N = _unit(np.array([u * u, -2 * u, 1.0]))  # = r×v/|r×v| for u ≠ 0
    if u != 0:
        assert np.allclose(N, _unit(np.cross(r, v)))
    B = np.cross(V, N)
    R = (1.0 if u >= 0 else -1.0) * _unit(np.array([1.0, u, u * u]))
    Bf = _unit(np.cross(v, a))
    Nf = np.cross(Bf, V)
    return {"vbn": np.array([V, N, B]), "ric": np.array([R, np.cross(N, R), N]),
            "frenet": np.array([V, Nf, Bf])}


def fd_omega(name: str, u: float, h: float = 1e-5) -> np.ndarray:
    """(ω₁, ω₂, ω₃) = (γ, −β, α) from α = ė₁·e₂, β = ė₁·e₃, γ = ė₂·e₃ (rate u̇ = 1)."""
    E = closed_form_axes(u)[name]
    dE = (closed_form_axes(u + h)[name] - closed_form_axes(u - h)[name]) / (2 * h)
    alpha, beta, gamma = dE[0] @ E[1], dE[0] @ E[2], dE[1] @ E[2]
    return np.array([gamma, -beta, alpha])


@pytest.fixture(scope="module")
def run() -> mechsim.SimulationResult:
    m = mechsim.load_system("moving_frames")
    return mechsim.simulate(m, 4.0, 0.125, tolerance=1e-12)


def test_rotation_helpers_against_scipy() -> None:
    rng = np.random.default_rng(1)
    for _ in range(20):
        a, b = Rotation.random(random_state=rng), Rotation.random(random_state=rng)
        out = np.empty(4)
        rot.quat_mul(a.as_quat(), b.as_quat(), out)
        assert np.allclose(Rotation.from_quat(out).as_matrix(), (a * b).as_matrix(), atol=1e-14)
        v = rng.normal(size=3)
        w = np.empty(3)
        rot.quat_rotate(a.as_quat(), v, w)
        assert np.allclose(w, a.apply(v), atol=1e-14)
        rot.quat_rotate_inverse(a.as_quat(), v, w)
        assert np.allclose(w, a.inv().apply(v), atol=1e-14)
        rot.quat_from_rows(a.as_matrix().T.copy(), out)
        assert np.allclose(Rotation.from_quat(out).as_matrix(), a.as_matrix(), atol=1e-14)
        ang = rng.uniform([-math.pi, 0, -math.pi], [math.pi, math.pi, math.pi])
        rot.quat_from_euler_zxz(*ang, out)
        ref = Rotation.from_euler("ZXZ", ang)  # intrinsic z-x'-z'' = R_z(φ) R_x(θ) R_z(ψ)
        assert np.allclose(Rotation.from_quat(out).as_matrix(), ref.as_matrix(), atol=1e-14)
        back = np.empty(3)
        rot.euler_zxz_from_quat(out, back)
        assert np.allclose(back, ang, atol=1e-12)
    # 180° rotations (Shepperd branches) and the θ = 0 gimbal case
    for m in (np.diag([1.0, -1, -1]), np.diag([-1.0, 1, -1]), np.diag([-1.0, -1, 1])):
        rot.quat_from_rows(m.T.copy(), out)
        assert np.allclose(Rotation.from_quat(out).as_matrix(), m, atol=1e-15)
    rot.quat_from_euler_zxz(0.7, 0.0, 0.2, out)
    rot.euler_zxz_from_quat(out, back)
    assert np.allclose(back, [0.9, 0.0, 0.0], atol=1e-14)


def test_frames_match_closed_forms(run: mechsim.SimulationResult) -> None:
    names = [f.child for f in run.model.frames]
    for k, u in enumerate(run.q[:, 0]):
        ref = closed_form_axes(float(u))
        for i, name in enumerate(names):
            pose = run.outputs.frames[k, i]
            assert np.allclose(pose[:3], [u, u * u, u**3], atol=1e-12)
            R = Rotation.from_quat(pose[3:]).as_matrix()
            assert np.allclose(R, ref[name].T, atol=1e-12), (name, u)
            assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)


def test_angular_velocities_against_finite_differences(run: mechsim.SimulationResult) -> None:
    for k, u in enumerate(run.q[:, 0]):
        if abs(u) < 1e-3:  # RIC flips at u = 0: no central difference there
            continue
        for name in ("vbn", "ric", "frenet"):
            got = np.array([run.observables[f"{name}_omega_{a}"][k] for a in "xyz"])
            assert np.allclose(got, fd_omega(name, float(u)), atol=2e-8), (name, u)


def test_catalog_table_and_document_signs() -> None:
    """Catalog 000 S14 table, given as the document's (α, β, γ); ω = (γ, −β, α)."""
    m = mechsim.load_system("moving_frames", **{"initial.curve_parameter": 1.0})
    r = mechsim.simulate(m, 1.0, 1.0)
    o = {k: v[0] for k, v in r.observables.items()}
    # VBN in the document's VNB order at t = 1: α = 0.21822, β = −0.58321, γ = 0.53452
    assert [o["vbn_omega_x"], o["vbn_omega_y"], o["vbn_omega_z"]] == pytest.approx(
        [0.53452, 0.58321, 0.21822], abs=1e-5)
    assert o["vbn_angular_speed"] == pytest.approx(math.sqrt(33) / 7, abs=1e-14)
    # RIC at t = 1: α = 0.81650, β = 0, γ = 0.57735; |ω| = 1
    assert [o["ric_omega_x"], o["ric_omega_y"], o["ric_omega_z"]] == pytest.approx(
        [1 / math.sqrt(3), 0.0, math.sqrt(2 / 3)], abs=1e-14)
    assert o["ric_angular_speed"] == pytest.approx(1.0, abs=1e-14)
    # t = 2 row: |ω_VBN| = 0.31946, |ω_RIC| = 0.38983
    o2 = {k: v[1] for k, v in r.observables.items()}
    assert o2["vbn_angular_speed"] == pytest.approx(0.31946, abs=1e-5)
    assert o2["ric_angular_speed"] == pytest.approx(0.38983, abs=1e-5)


def test_curvature_torsion_sympy_and_darboux(run: mechsim.SimulationResult) -> None:
    u = sp.Symbol("u", real=True)
    r = sp.Matrix([u, u**2, u**3])
    r1, r2, r3 = r.diff(u), r.diff(u, 2), r.diff(u, 3)
    c = r1.cross(r2)
    kappa = sp.lambdify(u, sp.sqrt(c.dot(c)) / sp.sqrt(r1.dot(r1)) ** 3)
    tau = sp.lambdify(u, c.dot(r3) / c.dot(c))
    us = run.q[:, 0]
    k_ref = np.array([kappa(x) for x in us])
    t_ref = np.array([tau(x) for x in us])
    assert np.allclose(run.observables["curvature"], k_ref, rtol=1e-13)
    assert np.allclose(run.observables["torsion"], t_ref, rtol=1e-13)
    assert np.allclose(run.model.curvature_at(us), k_ref, rtol=1e-13)
    assert np.allclose(run.model.torsion_at(us), t_ref, rtol=1e-13)
    # Darboux vector in the Frenet frame: ω = |v| (τ, 0, κ)
    speed = run.observables["speed"]
    assert np.allclose(run.observables["frenet_omega_x"], speed * t_ref, rtol=1e-12)
    assert np.allclose(run.observables["frenet_omega_z"], speed * k_ref, rtol=1e-12)


def test_minimal_frames_and_crossover(run: mechsim.SimulationResult) -> None:
    assert np.max(np.abs(run.invariants["ric_omega_y"])) < 1e-14
    assert np.max(np.abs(run.invariants["frenet_omega_y"])) < 1e-14
    assert np.min(np.abs(run.observables["vbn_omega_y"])) > 1e-3  # VBN is not minimal
    # catalog: |ω_VBN| = |ω_RIC| ≈ 1.33379 at |u| ≈ 0.68855 (VBN faster inside)
    m = mechsim.load_system("moving_frames", **{"initial.curve_parameter": 0.68855})
    o = mechsim.simulate(m, 1e-3, 1e-3).observables
    assert o["vbn_angular_speed"][0] == pytest.approx(1.33379, abs=1e-4)
    assert o["ric_angular_speed"][0] == pytest.approx(1.33379, abs=1e-4)


def test_origin_is_finite_and_takes_the_right_limit(run: mechsim.SimulationResult) -> None:
    k = int(np.argmin(np.abs(run.q[:, 0])))
    assert abs(run.q[k, 0]) < 1e-12
    for values in (*run.observables.values(), *run.invariants.values()):
        assert np.all(np.isfinite(values))
    assert np.all(np.isfinite(run.outputs.frames))
    # exactly at u = 0 (and at u = ±1e-9): limits of the catalog table
    for u0, sign in ((0.0, 1.0), (1e-9, 1.0), (-1e-9, -1.0)):
        m = mechsim.load_system("moving_frames", **{"initial.curve_parameter": u0})
        o = {k: v[0] for k, v in mechsim.simulate(m, 1e-3, 1e-3).observables.items()}
        assert [o["vbn_omega_x"], o["vbn_omega_y"], o["vbn_omega_z"]] == pytest.approx(
            [2, 2, 0], abs=1e-8)
        assert [o["ric_omega_x"], o["ric_omega_y"], o["ric_omega_z"]] == pytest.approx(
            [sign * 2, 0, 1], abs=1e-8)
        assert [o["curvature"], o["torsion"]] == pytest.approx([2, 3], abs=1e-12)


def test_work_balance_and_rate(run: mechsim.SimulationResult) -> None:
    assert np.max(np.abs(run.balance_residual)) < 1e-10
    assert np.allclose(run.q[:, 0], -2 + run.t, atol=1e-13)
    m = mechsim.load_system("moving_frames", **{"initial_rate.curve_parameter": 2.0,
                                                "mass": 3.0})
    r = mechsim.simulate(m, 2.0, 0.25)
    u = r.q[:, 0]
    assert np.allclose(r.kinetic, 0.5 * 3 * 4 * (1 + 4 * u**2 + 9 * u**4), rtol=1e-14)
    assert np.max(np.abs(r.balance_residual)) < 1e-9 * np.max(r.kinetic)
    # angular velocity scales with the rate
    assert np.allclose(r.observables["ric_angular_speed"][1:4],
                       2 * np.array([mechsim.simulate(
                           mechsim.load_system("moving_frames",
                                               **{"initial.curve_parameter": float(x)}),
                           1e-3, 1e-3).observables["ric_angular_speed"][0] for x in u[1:4]]),
                       rtol=1e-12)
    assert [law.key for law in m.laws()] == ["work_balance", "invariant:ric_omega_y",
                                              "invariant:frenet_omega_y"]
    scales = m.law_scales()
    assert scales["invariant:ric_omega_y"] == pytest.approx(2 * 0.38983, abs=1e-4)


def test_parameter_validation() -> None:
    with pytest.raises(ParameterError, match="^mass:"):
        mechsim.load_system("moving_frames", mass=0.0)
    with pytest.raises(ParameterError, match="^initial.curve_parameter:"):
        mechsim.load_system("moving_frames", **{"initial.curve_parameter": 50.0})
