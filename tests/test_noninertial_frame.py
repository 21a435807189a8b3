"""A free particle seen from a frame with a varying rotation rate and an oscillating origin
(PHYS0500 §6.1): the motion is the uniform inertial motion mapped into the frame (computed
here); the acceleration seen in the frame, by finite differences of the run, is the sum of the
four fictitious forces of the notes' effective force, each of which is the notes' formula
evaluated here; the inertial invariants hold; both formulations agree."""

from __future__ import annotations

import numpy as np
import pytest

import mechsim

M, W0, DW, OMEGA, A = 1.7, 0.6, 0.5, 0.9, 0.4
X0, Y0, VX0, VY0 = 1.2, -0.3, 0.1, 0.4


def _model(form: str, **kw: float) -> mechsim.Model:
    params = {"mass": M, "rotation_rate": W0, "rate_swing": DW, "swing_frequency": OMEGA,
              "origin_amplitude": A, "initial.x": X0, "initial.y": Y0,
              "initial_rate.x": VX0, "initial_rate.y": VY0, **kw}
    return mechsim.load_system("noninertial_frame", formulation=form, **params)


def _frame(t: np.ndarray) -> tuple[np.ndarray, ...]:
    """φ, ω, ω̇ and the origin's R, Ṙ, R̈ (along world x) of the frame's prescribed motion."""
    phi = W0 * t + DW / OMEGA * (1 - np.cos(OMEGA * t))
    w = W0 + DW * np.sin(OMEGA * t)
    wdot = DW * OMEGA * np.cos(OMEGA * t)
    R, dR, ddR = A * np.sin(OMEGA * t), A * OMEGA * np.cos(OMEGA * t), \
        -A * OMEGA**2 * np.sin(OMEGA * t)
    return phi, w, wdot, R, dR, ddR


def _expected(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Moving-frame position and velocity of the uniform inertial motion (eqs. 6.1, 6.4):
    X = X₀ + V t, r = R_z(−φ)(X − R x̂), v_r = R_z(−φ)(V − Ṙ x̂) − ω ẑ × r."""
    phi, w, _, R, dR, _ = _frame(t)
    V = np.array([dR[0] + VX0 - W0 * Y0, VY0 + W0 * X0])  # v_f = V + v_r + ω × r at t = 0
    X, Y = X0 + V[0] * t, Y0 + V[1] * t
    c, s = np.cos(phi), np.sin(phi)
    x, y = c * (X - R) + s * Y, -s * (X - R) + c * Y
    vx = c * (V[0] - dR) + s * V[1] + w * y
    vy = -s * (V[0] - dR) + c * V[1] - w * x
    return np.stack([x, y], 1), np.stack([vx, vy], 1)


@pytest.mark.parametrize("form", ["moving", "inertial"])
def test_motion_is_uniform_inertial_motion_seen_from_the_frame(form: str) -> None:
    run = mechsim.simulate(_model(form), 30.0, 0.01, tolerance=1e-12)
    pos, vel = _expected(run.t)
    frames = run.outputs.frames  # particle in the moving frame: frame 1, translation x, y
    assert np.max(np.abs(frames[:, 1, :2] - pos)) < 1e-9
    if form == "moving":
        assert np.max(np.abs(run.q - pos)) < 1e-9 and np.max(np.abs(run.v - vel)) < 1e-9
    for name in ("inertial_momentum_x", "inertial_momentum_y", "inertial_angular_momentum",
                 "inertial_energy"):
        v = run.invariants[name]
        assert np.max(np.abs(v - v[0])) < 1e-11 * max(1.0, abs(v[0]))


def test_fictitious_forces_are_the_documents() -> None:
    """m a_r (central differences of the integrated v_r) = −m R̈ − m ω̇ × r − m ω × (ω × r)
    − 2m ω × v_r (PHYS0500 line 1452, F = 0), each term computed here from the run's r, v_r
    and the frame's motion, and equal to the published observable."""
    dt = 1e-3
    run = mechsim.simulate(_model("moving"), 12.0, dt, tolerance=1e-13)
    t, r, v = run.t, run.q, run.v
    phi, w, wdot, _, _, ddR = _frame(t)
    zx = lambda a: np.stack([-a[:, 1], a[:, 0]], 1)  # ẑ × a  # noqa: E731
    c, s = np.cos(phi), np.sin(phi)
    terms = {
        "translational_force": -M * np.stack([c * ddR, -s * ddR], 1),  # −m R_z(−φ) R̈ x̂
        "euler_force": -M * wdot[:, None] * zx(r),
        "centrifugal_force": -M * (w**2)[:, None] * zx(zx(r)),
        "coriolis_force": -2 * M * w[:, None] * zx(v),
    }
    obs = run.observables
    for name, f in terms.items():
        published = np.stack([obs[f"{name}_x"], obs[f"{name}_y"]], 1)
        assert np.max(np.abs(published - f)) < 1e-12 * (1 + np.max(np.abs(f))), name
    accel = (v[2:] - v[:-2]) / (2 * dt)
    total = sum(terms.values())[1:-1]
    assert np.max(np.abs(M * accel - total)) < 1e-5 * np.max(np.abs(total))
    # the Euler force is not negligible here: it is what a constant-ω model leaves out
    assert np.max(np.abs(terms["euler_force"])) > 0.1 * np.max(np.abs(total))


def test_steady_frame_keeps_the_jacobi_integral() -> None:
    """Without the swing and the origin's motion (ω constant, R̈ = 0): the moving form's h is
    the Jacobi integral ½m v_r² − ½m ω² r² (PHYS0500 §6.1, catalog), conserved."""
    m = _model("moving", rate_swing=0.0, origin_amplitude=0.0)
    run = mechsim.simulate(m, 20.0, 0.01, tolerance=1e-12)
    r2 = np.sum(run.q**2, 1)
    jacobi = 0.5 * M * np.sum(run.v**2, 1) - 0.5 * M * W0**2 * r2
    assert np.allclose(run.energy_function, jacobi, atol=1e-12)
    assert np.max(np.abs(jacobi - jacobi[0])) < 1e-11
