"""Free rigid body (PHYS0500 §7.2–7.7): inertia module, Euler's equations, quaternion attitude.

References: sympy volume integrals for the solid tensors; brute-force point sums for the
parallel-axis theorem; an independent scipy integration of Euler's equations with the attitude
as a rotation matrix (Ṙ = R [ω]×) for the trajectory; the linearised Euler equations for the
spin-stability rates.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

import mechsim
from mechsim.errors import ParameterError
from mechsim.systems import _inertia as rg

# --- inertia module ---------------------------------------------------------------------------


def test_solid_tensors_against_sympy_integrals() -> None:
    x, y, z, r, th = sp.symbols("x y z r theta", real=True)
    a, b, c, R, L = sp.Rational(3, 10), sp.Rational(1, 5), sp.Rational(1, 10), \
        sp.Rational(1, 20), sp.Rational(3, 10)
    # box: density 1/(abc), integrate y² + z² etc.
    rho = 1 / (a * b * c)
    lim = ((x, -a / 2, a / 2), (y, -b / 2, b / 2), (z, -c / 2, c / 2))
    box = [float(sp.integrate(rho * e, *lim)) for e in (y**2 + z**2, x**2 + z**2, x**2 + y**2)]
    assert np.allclose(np.diag(rg.box_inertia(1.0, (0.3, 0.2, 0.1))), box, rtol=1e-14)
    # cylinder along z in cylindrical coordinates, density 1/(π R² L)
    rho = 1 / (sp.pi * R**2 * L)
    lim = ((r, 0, R), (th, 0, 2 * sp.pi), (z, -L / 2, L / 2))
    Ixx = float(sp.integrate(rho * ((r * sp.sin(th)) ** 2 + z**2) * r, *lim))
    Izz = float(sp.integrate(rho * r**2 * r, *lim))
    assert np.allclose(rg.cylinder_inertia(1.0, 0.05, 0.3), np.diag([Ixx, Ixx, Izz]),
                       rtol=1e-14)
    # sphere: (2/5) M R², in spherical coordinates
    ph = sp.Symbol("phi", real=True)
    rho = 1 / (sp.Rational(4, 3) * sp.pi * R**3)
    Izz = float(sp.integrate(rho * (r * sp.sin(th)) ** 2 * r**2 * sp.sin(th),
                             (r, 0, R), (th, 0, sp.pi), (ph, 0, 2 * sp.pi)))
    assert np.allclose(rg.sphere_inertia(1.0, 0.05), Izz * np.eye(3), rtol=1e-14)


def test_parallel_axis_and_composite_against_point_sums() -> None:
    rng = np.random.default_rng(3)
    m = rng.uniform(0.5, 2.0, size=7)
    pos = rng.normal(size=(7, 3))

    def eq71(masses: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Eq. 7.1 literally: I_ij = Σ m (δ_ij Σ_k x_k² − x_i x_j)."""
        out = np.zeros((3, 3))
        for mm, p in zip(masses, points, strict=True):
            for i in range(3):
                for j in range(3):
                    out[i, j] += mm * ((i == j) * (p @ p) - p[i] * p[j])
        return out

    M, cm, I_cm = rg.composite([rg.Part(mm, np.zeros((3, 3)), tuple(p))
                                for mm, p in zip(m, pos, strict=True)])
    assert M == pytest.approx(m.sum())
    assert np.allclose(cm, (m[:, None] * pos).sum(0) / m.sum(), atol=1e-14)
    assert np.allclose(I_cm, eq71(m, pos - cm), atol=1e-13)
    Q = rng.normal(size=3)  # about an arbitrary point Q: J = I + M(a²1 − aaᵀ), a = CM − Q
    assert np.allclose(rg.parallel_axis(I_cm, M, cm - Q), eq71(m, pos - Q), atol=1e-12)
    # rotated parts: a box turned by R has tensor R I Rᵀ
    R = Rotation.from_euler("xyz", [0.3, -0.5, 1.1]).as_matrix()
    _, _, I_rot = rg.composite([rg.Part(2.0, rg.box_inertia(2.0, (0.3, 0.2, 0.1)), rotation=R)])
    assert np.allclose(I_rot, R @ rg.box_inertia(2.0, (0.3, 0.2, 0.1)) @ R.T, atol=1e-15)
    # a thin rod of point masses → M L²/12 about its centre
    n = 2001
    xs = np.linspace(-0.5, 0.5, n)
    _, _, rod = rg.composite([rg.Part(1.0 / n, np.zeros((3, 3)), (float(s), 0.0, 0.0))
                              for s in xs])
    assert rod[1, 1] == pytest.approx(1 / 12, rel=2e-3)


def test_principal_axes() -> None:
    R = Rotation.from_euler("zxz", [0.4, 0.7, -0.2]).as_matrix()
    I = R @ np.diag([1.0, 2.0, 3.0]) @ R.T
    moments, Q = rg.principal_axes(I)
    assert np.allclose(Q @ np.diag(moments) @ Q.T, I, atol=1e-14)
    assert np.allclose(Q.T @ Q, np.eye(3), atol=1e-14)
    assert np.linalg.det(Q) == pytest.approx(1.0)
    assert np.allclose(moments, [1, 2, 3])  # the rotation is small enough to keep the order
    assert np.allclose(Q, R, atol=1e-12)
    moments, Q = rg.principal_axes(np.diag([3.0, 1.0, 2.0]))
    assert np.allclose(moments, [3, 1, 2]) and np.allclose(Q, np.eye(3))


# --- dynamics --------------------------------------------------------------------------------


def reference(model: mechsim.systems.base.Model, t: np.ndarray) -> tuple[np.ndarray, ...]:
    """Euler's equations + Ṙ = R[ω]× with scipy (an independent attitude formulation)."""
    I = np.array(model.rigid_data().moments)
    N = np.array(model.rigid_data().torque)
    q0, w0 = model.initial_attitude()

    def f(_t: float, s: np.ndarray) -> np.ndarray:
        w = s[:3]
        R = s[3:].reshape(3, 3)
        dw = (np.cross(I * w, w) + N) / I
        W = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        return np.concatenate([dw, (R @ W).ravel()])

    s0 = np.concatenate([w0, Rotation.from_quat(q0).as_matrix().ravel()])
    sol = solve_ivp(f, (0, t[-1]), s0, method="DOP853", t_eval=t, rtol=1e-13, atol=1e-13)
    return sol.y[:3].T, sol.y[3:].T.reshape(-1, 3, 3)


@pytest.fixture(scope="module")
def flip() -> mechsim.SimulationResult:
    m = mechsim.load_system("rigid_body", **{"initial.phi": 0.3, "initial.theta": 0.8,
                                             "initial.psi": -1.0})
    return mechsim.simulate(m, 30.0, 0.25, tolerance=1e-12)


def test_trajectory_matches_rotation_matrix_integration(flip: mechsim.SimulationResult) -> None:
    w_ref, R_ref = reference(flip.model, flip.t)
    w = np.stack([flip.observables[f"omega_{i}"] for i in (1, 2, 3)], axis=1)
    R = Rotation.from_quat(flip.outputs.frames[:, 0, 3:]).as_matrix()
    # each flip amplifies phase errors: tight before the first one, looser over three
    early = flip.t < 4.0
    assert np.max(np.abs(w - w_ref)[early]) < 1e-9
    assert np.max(np.abs(R - R_ref)[early]) < 1e-9
    assert np.max(np.abs(w - w_ref)) < 2e-5
    assert np.max(np.abs(R - R_ref)) < 2e-5
    assert np.allclose(np.linalg.norm(flip.q, axis=1), 1.0, atol=1e-15)
    assert np.allclose(np.sum(flip.q * flip.v, axis=1), 0.0, atol=1e-15)


def test_intermediate_axis_flips_and_conservation(flip: mechsim.SimulationResult) -> None:
    w2 = flip.observables["omega_2"]
    assert w2.min() < -3.9 and w2.max() > 3.9  # it turns over, repeatedly
    # energy, L in space, 2T = ω·L, unit norm
    assert np.max(np.abs(flip.total - flip.total[0])) < 1e-10 * flip.total[0]
    L0 = flip.observables["angular_momentum"][0]
    for a in "xyz":
        assert np.max(np.abs(np.diff(flip.invariants[f"angular_momentum_{a}"]))) < 1e-10 * L0
    wL = sum(flip.observables[f"omega_{i}"] * flip.observables[f"angular_momentum_{i}"]
             for i in (1, 2, 3))
    assert np.allclose(wL, 2 * flip.kinetic, rtol=1e-14)
    assert np.allclose(flip.invariants["omega_along_momentum"], 2 * flip.kinetic / L0,
                       rtol=1e-10)
    assert np.max(np.abs(flip.invariants["constraint_unit_norm"])) < 1e-14
    # L world from the attitude: R (I ω) is the fixed vector
    Lw = np.stack([flip.invariants[f"angular_momentum_{a}"] for a in "xyz"], axis=1)
    assert np.allclose(Lw, Lw[0], atol=1e-10 * L0)
    assert np.max(np.abs(flip.balance_residual)) < 1e-10 * flip.total[0]


@pytest.mark.parametrize("axis", [1, 2, 3])
def test_spin_stability_about_each_axis(axis: int) -> None:
    w0, eps = 4.0, 1e-4
    values = {f"initial.omega_{i}": (w0 if i == axis else eps) for i in (1, 2, 3)}
    m = mechsim.load_system("rigid_body", **values)
    Om2 = m.spin_stability(axis)
    r = mechsim.simulate(m, 12.0, 0.01, tolerance=1e-12)
    wk = r.observables[f"omega_{axis}"]
    other = r.observables[f"omega_{axis % 3 + 1}"]
    if axis == 2:
        assert Om2 < 0
        assert wk.min() < 0  # flipped
        # early exponential growth at √(−Ω²)
        sel = (r.t > 2.5) & (r.t < 4.0)  # decaying mode gone, still linear
        rate = np.polyfit(r.t[sel], np.log(np.abs(other[sel])), 1)[0]
        assert rate == pytest.approx(math.sqrt(-Om2), rel=5e-3)
    else:
        assert Om2 > 0
        assert np.min(wk) > w0 * (1 - 1e-6)  # stays spinning, tiny wobble
        # wobble frequency from the zero crossings of the perturbation
        zc = r.t[1:][np.diff(np.sign(other)) != 0]
        period = 2 * np.mean(np.diff(zc))
        assert 2 * math.pi / period == pytest.approx(math.sqrt(Om2), rel=2e-3)


def test_constant_torque_work_balance() -> None:
    m = mechsim.load_system("rigid_body", **{"torque.x": 0.002, "torque.y": -0.001,
                                             "torque.z": 0.003, "initial.theta": 0.5})
    assert [law.key for law in m.laws()] == ["work_balance", "constraint:constraint_unit_norm"]
    r = mechsim.simulate(m, 10.0, 0.1, tolerance=1e-12)
    assert np.max(np.abs(r.balance_residual)) < 1e-10 * np.max(r.total)
    assert r.work_external[-1] == pytest.approx(r.total[-1] - r.total[0], abs=1e-13)
    assert abs(r.work_external[-1]) > 1e-3
    w_ref, R_ref = reference(m, r.t)
    w = np.stack([r.observables[f"omega_{i}"] for i in (1, 2, 3)], axis=1)
    assert np.max(np.abs(w - w_ref)) < 1e-8
    R = Rotation.from_quat(r.outputs.frames[:, 0, 3:]).as_matrix()
    assert np.max(np.abs(R - R_ref)) < 1e-8


def test_tip_mass_principal_frame_and_static_body_frame() -> None:
    m = mechsim.load_system("rigid_body", tip_mass=0.3, **{
        "tip_position.x": 0.15, "tip_position.y": 0.1, "tip_position.z": 0.05})
    M, cm, I = m.inertia()
    assert M == pytest.approx(1.3)
    assert np.allclose(cm, 0.3 * np.array([0.15, 0.1, 0.05]) / 1.3)
    moments, Q = m.principal()
    r = mechsim.simulate(m, 1.0, 0.5)
    f = r.outputs.frames
    # world_R_body = world_R_principal · principal_R_body must carry I back to the shape axes
    Rp = Rotation.from_quat(f[0, 0, 3:]).as_matrix()
    Rb = Rotation.from_quat(f[0, 1, 3:]).as_matrix()
    assert np.allclose(Rb, Q.T, atol=1e-14)
    assert np.allclose(Rb.T @ np.diag(moments) @ Rb, I, atol=1e-14)
    # shape centre in world = CM(origin) + R_p (−Qᵀ cm); the tip mass sits at the marker
    assert np.allclose(f[0, 1, :3], -Q.T @ cm, atol=1e-15)
    assert np.allclose(f[0, 2, :3], [0.15, 0.1, 0.05])
    assert np.allclose(Rp @ (f[0, 1, :3] + Rb @ f[0, 2, :3]),
                       Rp @ Q.T @ (np.array([0.15, 0.1, 0.05]) - cm), atol=1e-15)
    assert [s.static for s in m.frames] == [False, True, True]


def test_long_run_conservation() -> None:
    m = mechsim.load_system("rigid_body", shape="cylinder", **{
        "initial.omega_1": 1.0, "initial.omega_2": 2.0, "initial.omega_3": 3.0})
    r = mechsim.simulate(m, 300.0, 1.0, tolerance=1e-10)
    assert np.max(np.abs(r.total / r.total[0] - 1)) < 1e-8
    L0 = r.observables["angular_momentum"][0]
    for a in "xyz":
        inv = r.invariants[f"angular_momentum_{a}"]
        assert np.max(np.abs(inv - inv[0])) < 1e-8 * L0
    assert np.max(np.abs(r.invariants["constraint_unit_norm"])) < 1e-14


def test_parameter_validation() -> None:
    with pytest.raises(ParameterError, match="^shape:"):
        mechsim.load_system("rigid_body", shape="torus")
    with pytest.raises(ParameterError, match="^size.x:"):
        mechsim.load_system("rigid_body", **{"size.x": -1.0})
    with pytest.raises(ParameterError, match="^tip_position.x:"):
        mechsim.load_system("rigid_body", tip_mass=1.0, **{"tip_position.x": 0.0})


# --- exact (closed-form) torque-free motion ----------------------------------------------------


def _exact_vs_radau15(model: mechsim.systems.base.Model, scales: float) -> float:
    """Largest difference (q absolute, q̇ relative to its largest value) between the closed
    form and radau15 at 1e-14 at ten times over ``scales`` time scales."""
    from mechsim.integrators import make_stepper

    t = np.linspace(0.0, scales * model.time_scale(), 11)[1:]
    exact = make_stepper(model, "exact").advance(t)
    ref = make_stepper(model, "radau15", 1e-14).advance(t)
    scale = float(np.max(np.abs(ref[:, 4:8])))
    return max(float(np.max(np.abs(exact[:, :4] - ref[:, :4]))),
               float(np.max(np.abs(exact[:, 4:8] - ref[:, 4:8]))) / scale)


@pytest.mark.parametrize("values", [
    {"initial.omega_1": 3.0, "initial.omega_2": 0.5, "initial.omega_3": 0.2,
     "initial.theta": 1.0},  # polhode about the smallest moment (|L|² < 2E I₂)
    {"initial.omega_1": 0.1, "initial.omega_2": 0.5, "initial.omega_3": 3.0,
     "initial.theta": 1.0},  # about the largest (|L|² > 2E I₂)
    {"initial.omega_1": 1.0, "initial.omega_2": 2.0, "initial.omega_3": 1.5, "tip_mass": 0.3,
     "tip_position.y": 0.1, "initial.phi": 2.0},  # principal axes turned from the shape's
    {"shape": "cylinder", "initial.omega_1": 1.0, "initial.omega_2": 2.0,
     "initial.omega_3": 3.0},  # body of revolution: m = 0
    {"shape": "sphere", "initial.theta": 0.4},  # steady rotation
    {"initial.omega_1": 0.0, "initial.omega_2": 4.0, "initial.omega_3": 0.0},  # steady, unstable
])
def test_exact_solution_agrees_with_the_integrator(values: dict) -> None:
    m = mechsim.load_system("rigid_body", **values)
    assert m.has_closed_form()
    assert _exact_vs_radau15(m, 10.0) < 1e-13


def test_exact_solution_near_the_separatrix(flip: mechsim.SimulationResult) -> None:
    """The default body (1 − m ≈ 2e-5): at round-off up to the first flip; through the flips
    every error is amplified (by the same ~1e3 in the integrators, which then disagree with
    each other as much), and the exact run still tracks the rotation-matrix reference."""
    m = flip.model
    assert _exact_vs_radau15(m, 4.0) < 1e-13
    assert _exact_vs_radau15(m, 10.0) < 1e-10
    exact = mechsim.simulate(m, 30.0, 0.25, method="exact")
    assert exact.method == "exact"
    w_ref, R_ref = reference(m, exact.t)
    w = np.stack([exact.observables[f"omega_{i}"] for i in (1, 2, 3)], axis=1)
    assert np.max(np.abs(w - w_ref)) < 2e-5 and np.max(np.abs(w - w_ref)[exact.t < 4]) < 1e-9
    R = Rotation.from_quat(exact.outputs.frames[:, 0, 3:]).as_matrix()
    assert np.max(np.abs(R - R_ref)) < 2e-5
    # the invariants hold to round-off at every sample, flips included
    L0 = exact.observables["angular_momentum"][0]
    for a in "xyz":
        inv = exact.invariants[f"angular_momentum_{a}"]
        assert np.max(np.abs(inv - inv[0])) < 1e-13 * L0
    assert np.max(np.abs(exact.total / exact.total[0] - 1)) < 1e-13


def test_no_closed_form_under_a_torque() -> None:
    m = mechsim.load_system("rigid_body", **{"torque.x": 0.002})
    assert not m.has_closed_form()
    with pytest.raises(ParameterError, match="^method:"):
        mechsim.simulate(m, 1.0, 0.1, method="exact")


def test_kernels_make_no_arrays() -> None:
    """Every kernel function of both rigid-body systems runs without a heap allocation: counted
    with numba's runtime statistics (enabled by NUMBA_NRT_STATS in a fresh interpreter) against
    a function that only reads its arguments (whose unboxing is all a Python call costs)."""
    import os
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent("""
        import numpy as np
        from numba import njit
        from numba.core.runtime import rtsys
        import mechsim

        @njit
        def bare(t, y, p, out):
            out.flat[0] = y[0] + p[0]

        @njit
        def bare3(t, y, p):
            y[0] = y[0] + p[0]

        def count(f, *args):
            f(*args)
            before = rtsys.get_allocation_stats().alloc
            for _ in range(20):
                f(*args)
            return rtsys.get_allocation_stats().alloc - before

        for sid in ("rigid_body", "symmetric_top"):
            m = mechsim.load_system(sid)
            k, y, p = m.kernels, m.initial_y(), m.parameter_vector()
            outs = {"rhs": np.zeros(y.size), "energy": np.zeros(3),
                    "invariants": np.zeros(len(m.invariants)),
                    "observables": np.zeros(len(m.observables)),
                    "frames": np.zeros((len(m.frames), 7))}
            for name, out in outs.items():
                base = count(bare, 0.0, y, p, out)
                print(sid, name, count(getattr(k, name), 0.0, y, p, out) - base)
            z = y.copy()
            print(sid, "project", count(k.project, 0.0, z, p) - count(bare3, 0.0, z, p))
    """)
    env = {**os.environ, "NUMBA_NRT_STATS": "1"}
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                         text=True, timeout=600, check=True).stdout.split("\n")
    counts = {" ".join(line.split()[:2]): int(line.split()[2]) for line in out if line}
    assert len(counts) == 12
    assert all(v == 0 for v in counts.values()), counts
