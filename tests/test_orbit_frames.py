"""VBN and RIC frames on an orbit (“Minimal Frames”, “Moving Frames and the Twisted Cubic”).

Oracles, none of them the model's own frame code: the circular orbit's closed forms (R̂, Î, Ĉ
turn at the mean motion n about the fixed normal; VBN = (Î, Ĉ, R̂) there), the frames rebuilt
here from the document's definitions (V̂ = v/|v|, N̂ = r×v/|r×v|, ...) out of the integrated
state, the moving-frame matrix entries α = ė₁·e₂, β = ė₁·e₃, γ = ė₂·e₃ from central
differences of the frames as published on /tf, and the apsides' closed forms
|ω_VBN|/|ω_RIC| = μ/(r v²) = 1/(1 ± e) (the velocity turns at μ/(r² v), the radius at v/r).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import mechsim
from mechsim.errors import ParameterError
from mechsim.outputs.messages import MessageFactory


def _unit(w: np.ndarray) -> np.ndarray:
    return w / np.linalg.norm(w, axis=-1, keepdims=True)


def document_axes(r: np.ndarray, v: np.ndarray) -> dict[str, np.ndarray]:
    """Rows = axes, per sample: VBN in the right-handed order (V̂, N̂, B̂), RIC (R̂, Î, Ĉ)."""
    V, N, R = _unit(v), _unit(np.cross(r, v)), _unit(r)
    return {"vbn": np.stack([V, N, np.cross(V, N)], axis=1),
            "ric": np.stack([R, np.cross(N, R), N], axis=1)}


def tf_axes(run: mechsim.SimulationResult) -> dict[str, np.ndarray]:
    """Axes (rows) of the frames from the /tf messages a node publishes for each sample."""
    factory = MessageFactory(run.model, "orbit")
    out: dict[str, list[np.ndarray]] = {"vbn": [], "ric": []}
    for k in range(len(run.t)):
        for tf in factory.transforms(run.outputs.frames[k], 0, static=False):
            name = tf.child_frame_id.rsplit("/", 1)[-1]
            assert tf.header.frame_id.endswith("centre")
            q = tf.transform.rotation
            out[name].append(Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix().T)
            p = tf.transform.translation
            assert [p.x, p.y, p.z] == pytest.approx(run.q[k], abs=1e-12)
    return {k: np.array(v) for k, v in out.items()}


def moving_frame_entries(axes: np.ndarray, dt: float) -> np.ndarray:
    """(α, β, γ) per interior sample from central differences of the axes."""
    E, dE = axes[1:-1], (axes[2:] - axes[:-2]) / (2 * dt)
    return np.stack([np.sum(dE[:, 0] * E[:, 1], axis=1), np.sum(dE[:, 0] * E[:, 2], axis=1),
                     np.sum(dE[:, 1] * E[:, 2], axis=1)], axis=1)


def omega(run: mechsim.SimulationResult, frame: str) -> np.ndarray:
    return np.stack([run.observables[f"{frame}_omega_{a}"] for a in "xyz"], axis=1)


def test_circular_orbit_closed_forms() -> None:
    """μ = k/m = 4, r = 1: n = 2, speed 2, inclined 40°: R̂ = cos nt P̂ + sin nt Q̂."""
    inc, n = math.radians(40.0), 2.0
    P, Q = np.array([1.0, 0, 0]), np.array([0, math.cos(inc), math.sin(inc)])
    m = mechsim.load_system("orbit_frames", **{
        "mass": 2.0, "force_constant": 8.0, "initial_rate.x": 0.0,
        "initial_rate.y": n * Q[1], "initial_rate.z": n * Q[2]})
    run = mechsim.simulate(m, 4.0, 0.05, tolerance=1e-12)
    c, s = np.cos(n * run.t)[:, None], np.sin(n * run.t)[:, None]
    R, I, C = c * P + s * Q, -s * P + c * Q, np.broadcast_to(np.cross(P, Q), (len(run.t), 3))
    assert np.allclose(run.q, R, atol=1e-9)
    axes = tf_axes(run)
    assert np.allclose(axes["ric"], np.stack([R, I, C], axis=1), atol=1e-9)
    assert np.allclose(axes["vbn"], np.stack([I, C, R], axis=1), atol=1e-9)
    assert np.allclose(omega(run, "ric"), [0.0, 0.0, n], atol=1e-9)
    assert np.allclose(omega(run, "vbn"), [0.0, n, 0.0], atol=1e-9)
    assert np.allclose(run.observables["ric_angular_speed"], n, atol=1e-9)


@pytest.fixture(scope="module")
def kepler() -> mechsim.SimulationResult:
    """The default orbit: e = 0.21, inclined 30°, one period (2π a^{3/2}, a = 1/0.79)."""
    period = 2 * math.pi * (1 / 0.79) ** 1.5
    return mechsim.simulate(mechsim.load_system("orbit_frames"), period, period / 4000,
                            tolerance=1e-12)


@pytest.fixture(scope="module")
def oblate() -> mechsim.SimulationResult:
    m = mechsim.load_system("orbit_frames", perturbation="oblateness")
    return mechsim.simulate(m, 20.0, 2e-3, tolerance=1e-12)


@pytest.mark.parametrize("case", ["kepler", "oblate"])
def test_tf_quaternions_are_the_documents_frames(case: str,
                                                 request: pytest.FixtureRequest) -> None:
    run = request.getfixturevalue(case)
    ref, got = document_axes(run.q, run.v), tf_axes(run)
    for name in ("vbn", "ric"):
        assert np.allclose(got[name], ref[name], atol=1e-12), name


@pytest.mark.parametrize("perturbation", ["none", "oblateness"])
@pytest.mark.parametrize("velocity", [(0.0, 1.1, 0.0), (0.0, -1.1, 0.0), (0.0, 0.0, 1.1),
                                      (0.0, 1e-9, 1.1), (0.0, -1.1, 1e-12), (0.3, -0.2, -1.0)],
                         ids=["equatorial", "retrograde", "polar", "near_polar",
                              "near_retrograde", "generic"])
def test_quaternions_on_every_orbit_orientation(perturbation: str,
                                                velocity: tuple[float, ...]) -> None:
    """Equatorial, retrograde and polar planes (where an angle from the ascending node is
    undefined): the published rotations are the axes to round-off."""
    rates = {f"initial_rate.{c}": w for c, w in zip("xyz", velocity, strict=True)}
    m = mechsim.load_system("orbit_frames", perturbation=perturbation, **rates)
    run = mechsim.simulate(m, 6.0, 0.05, tolerance=1e-12)
    ref = document_axes(run.q, run.v)
    for i, name in ((1, "vbn"), (2, "ric")):
        q = run.outputs.frames[:, i, 3:]
        assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-14)
        got = Rotation.from_quat(q).as_matrix().transpose(0, 2, 1)
        assert np.allclose(got, ref[name], atol=1e-14), name


def test_an_applied_effort_turns_the_frames() -> None:
    """A force F ẑ (the effort on z) on the equatorial orbit at r = x̂, v = 1.1 ŷ: a·N̂ = F/m,
    VBN turns about B̂ at a·N̂/|v|, RIC about R̂ at |r| a·Ĉ/|r × v|; both F/(m |v|) here."""
    m = mechsim.load_system("orbit_frames", mass=2.0, **{"initial_rate.z": 0.0,
                                                       "initial_rate.y": 1.1})
    p, y = m.parameter_vector().copy(), m.initial_y()
    names = [q.name for q in m.observables]
    out = np.zeros(len(names))
    m.kernels.observables(0.0, y, p, out)
    assert dict(zip(names, out, strict=True))["normal_acceleration"] == 0.0
    p[m.effort_slice()] = [0.0, 0.0, 0.5]
    m.kernels.observables(0.0, y, p, out)
    got = dict(zip(names, out, strict=True))
    assert got["normal_acceleration"] == pytest.approx(0.25, rel=1e-14)
    assert got["vbn_omega_z"] == pytest.approx(0.25 / 1.1, rel=1e-14)
    assert got["ric_omega_x"] == pytest.approx(0.25 / 1.1, rel=1e-14)
    assert got["vbn_omega_y"] == pytest.approx(0.5 / 1.1, rel=1e-14)  # μ/(r²v), μ = k/m


@pytest.mark.parametrize("case", ["kepler", "oblate"])
def test_angular_velocity_against_central_differences(case: str,
                                                      request: pytest.FixtureRequest) -> None:
    """ω = (γ, −β, α) of the moving-frame matrix, differenced from the published frames."""
    run = request.getfixturevalue(case)
    dt = float(run.t[1] - run.t[0])
    axes = tf_axes(run)
    for name in ("vbn", "ric"):
        a, b, g = moving_frame_entries(axes[name], dt).T
        fd = np.stack([g, -b, a], axis=1)
        got = omega(run, name)[1:-1]
        assert np.max(np.abs(got - fd)) < 1e-5 * np.max(np.abs(got)), name
        if name == "ric":  # Ṙ·Ĉ ≡ 0, to the differences' truncation error
            assert np.max(np.abs(b)) < 1e-6 * np.max(np.abs(got))


def test_vbn_is_minimal_under_a_central_force(kepler: mechsim.SimulationResult) -> None:
    """“Minimal Frames”: "in the case of a central force ... VBN is a minimal frame". True,
    but α = V̇·N̂ and γ = Ṅ·B̂ vanish (a ∥ r), not β = V̇·B̂, and a·v = 0 does not hold."""
    dt = float(kepler.t[1] - kepler.t[0])
    a, b, g = moving_frame_entries(tf_axes(kepler)["vbn"], dt).T
    assert np.max(np.abs(a)) < 1e-9 and np.max(np.abs(g)) < 1e-9
    assert np.min(np.abs(b)) > 0.3
    accel = (kepler.v[2:] - kepler.v[:-2]) / (2 * dt)
    a_dot_v = np.sum(accel * kepler.v[1:-1], axis=1)
    assert np.max(np.abs(a_dot_v)) > 0.1  # the document's stated reason fails
    assert np.max(np.abs(kepler.observables["normal_acceleration"])) < 1e-12


def test_vbn_is_not_minimal_with_oblateness(oblate: mechsim.SimulationResult) -> None:
    dt = float(oblate.t[1] - oblate.t[0])
    axes = tf_axes(oblate)
    a, b, g = moving_frame_entries(axes["vbn"], dt).T
    scale = np.max(np.abs(b))
    for entry in (a, g):  # 1e-9 under the central force (above), here:
        assert np.max(np.abs(entry)) > 1e-3 * scale
    assert np.max(np.abs(moving_frame_entries(axes["ric"], dt)[:, 1])) < 1e-6 * scale
    assert np.max(np.abs(oblate.observables["normal_acceleration"])) > 1e-3
    # the orbit plane precesses: L changes direction; E and L_z (axisymmetry) are kept
    L = np.cross(oblate.q, oblate.v)
    assert np.max(np.abs(L[:, 0] - L[0, 0])) > 1e-2
    assert np.max(np.abs(L[:, 2] - L[0, 2])) < 1e-10
    assert np.max(np.abs(oblate.total - oblate.total[0])) < 1e-10
    # an equatorial orbit keeps its plane: VBN is minimal there even with J₂
    m = mechsim.load_system("orbit_frames", perturbation="oblateness",
                            **{"initial_rate.y": 1.1, "initial_rate.z": 0.0})
    flat = mechsim.simulate(m, 5.0, 0.05, tolerance=1e-12)
    assert np.max(np.abs(omega(flat, "vbn")[:, [0, 2]])) < 1e-12


def test_apsides_closed_forms(kepler: mechsim.SimulationResult) -> None:
    """At periapsis and apoapsis |ω_VBN| / |ω_RIC| = μ/(r v²) = 1/(1 ± e); |ω_RIC| = |L|/r²."""
    e = 1.1**2 - 1  # r = 1, v = 1.1 v_circular, at periapsis
    ratio = kepler.observables["vbn_angular_speed"] / kepler.observables["ric_angular_speed"]
    r = np.linalg.norm(kepler.q, axis=1)
    assert ratio[0] == pytest.approx(1 / (1 + e), rel=1e-12)
    assert ratio[np.argmax(r)] == pytest.approx(1 / (1 - e), rel=1e-9)
    h = np.linalg.norm(np.cross(kepler.q, kepler.v), axis=1)
    assert np.allclose(kepler.observables["ric_angular_speed"], h / r**2, rtol=1e-12)
    assert np.max(r) == pytest.approx((1 + e) / (1 - e), rel=1e-9)


def test_kepler_invariants_and_effort_free_default(kepler: mechsim.SimulationResult) -> None:
    names = [q.name for q in kepler.model.invariants]
    assert names == [f"angular_momentum_{a}" for a in "xyz"] + [f"runge_lenz_{a}" for a in "xyz"]
    for values in kepler.invariants.values():
        assert np.max(np.abs(values - values[0])) < 1e-9
    assert [f.child for f in kepler.model.frames] == ["centre", "vbn", "ric"]


def test_radial_start_is_refused() -> None:
    with pytest.raises(ParameterError, match="^initial_rate.x:"):
        mechsim.load_system("orbit_frames", **{"initial_rate.x": 1.0, "initial_rate.y": 0.0,
                                               "initial_rate.z": 0.0})
    with pytest.raises(ParameterError, match="^perturbation:"):
        mechsim.load_system("orbit_frames", perturbation="drag")
