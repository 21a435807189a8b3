"""Central force in three dimensions (Lecture 10, central force in spherical coordinates (eq.
10.19), spherical coordinates): the orbit stays in the plane normal to L; L (with p_φ = L_z) and the
LRL vector are conserved; Kepler apsides and period from the elements written here; the motion
equals the planar ``central_force`` turned by a rotation built here from L; harmonic: each axis is a
simple harmonic motion."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import mechsim
from mechsim.errors import ParameterError

TILTED = {"initial.r": 1.2, "initial.theta": 1.1, "initial.phi": 0.4, "initial_rate.r": 0.3,
          "initial_rate.theta": 0.4, "initial_rate.phi": 0.8}


def model(**kw):
    return mechsim.load_system("central_force_3d", **kw)


def start(kw: dict) -> tuple[np.ndarray, np.ndarray]:
    """Cartesian position and velocity from the spherical parameters, written out here:
    r = r r̂, v = ṙ r̂ + r θ̇ θ̂ + r sinθ φ̇ φ̂."""
    r, th, ph = kw["initial.r"], kw["initial.theta"], kw["initial.phi"]
    dr, dth, dph = kw["initial_rate.r"], kw["initial_rate.theta"], kw["initial_rate.phi"]
    rhat = np.array([math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th)])
    that = np.array([math.cos(th) * math.cos(ph), math.cos(th) * math.sin(ph), -math.sin(th)])
    phat = np.array([-math.sin(ph), math.cos(ph), 0.0])
    return r * rhat, dr * rhat + r * dth * that + r * math.sin(th) * dph * phat


def positions(run: mechsim.SimulationResult) -> np.ndarray:
    return run.outputs.frames[:, 1, :3]  # frame ``particle``


@pytest.fixture(scope="module", params=["spherical", "cartesian"])
def run(request: pytest.FixtureRequest) -> mechsim.SimulationResult:
    return mechsim.simulate(model(formulation=request.param, **TILTED), 30.0, 0.01,
                            tolerance=1e-13, method="dop853")


def test_orbit_in_the_plane_normal_to_L(run: mechsim.SimulationResult) -> None:
    r0, v0 = start(TILTED)
    L0 = np.cross(r0, v0)
    n = L0 / np.linalg.norm(L0)
    assert abs(math.acos(n[2])) > 0.3  # really tilted
    assert np.max(np.abs(positions(run) @ n)) < 1e-11
    L = np.stack([run.invariants[f"angular_momentum_{c}"] for c in "xyz"], axis=1)
    np.testing.assert_allclose(L, np.broadcast_to(L0, L.shape), atol=1e-12)
    assert np.max(np.ptp(L, axis=0)) < 1e-11
    if run.model.formulation == "spherical":
        # the document's statement: p_φ = m r² sin²θ φ̇ is L_z
        r, th, dph = run.q[:, 0], run.q[:, 1], run.v[:, 2]
        np.testing.assert_allclose(r**2 * np.sin(th) ** 2 * dph, L[:, 2], atol=1e-12)


def test_runge_lenz_and_kepler_elements(run: mechsim.SimulationResult) -> None:
    r0, v0 = start(TILTED)
    L0 = np.cross(r0, v0)
    A0 = np.cross(v0, L0) - r0 / np.linalg.norm(r0)
    A = np.stack([run.invariants[f"runge_lenz_{c}"] for c in "xyz"], axis=1)
    np.testing.assert_allclose(A, np.broadcast_to(A0, A.shape), atol=1e-11)
    assert np.max(np.ptp(A, axis=0)) < 1e-11
    E = 0.5 * float(v0 @ v0) - 1 / np.linalg.norm(r0)
    a, e = 1 / (2 * abs(E)), float(np.linalg.norm(A0))
    r = np.linalg.norm(positions(run), axis=1)
    assert r.min() == pytest.approx(a * (1 - e), rel=1e-6)  # sampled: near the apsides
    assert r.max() == pytest.approx(a * (1 + e), rel=1e-6)
    # periapsis lies along A
    i = int(np.argmin(r))
    np.testing.assert_allclose(positions(run)[i] / r[i], A0 / e, atol=3e-3)
    # the orbit frame: z along L, x along A
    rot = Rotation.from_quat(run.outputs.frames[:, 2, 3:]).as_matrix()
    np.testing.assert_allclose(rot[:, :, 2], np.broadcast_to(L0 / np.linalg.norm(L0),
                                                             (r.size, 3)), atol=1e-11)
    np.testing.assert_allclose(rot[:, :, 0], np.broadcast_to(A0 / e, (r.size, 3)), atol=1e-10)


def test_period() -> None:
    mod = model(**TILTED)
    r0, v0 = start(TILTED)
    a = 1 / (2 * abs(0.5 * float(v0 @ v0) - 1 / np.linalg.norm(r0)))
    T = 2 * math.pi * math.sqrt(a**3)  # m = k = 1
    run = mechsim.simulate(mod, 3 * T, T, tolerance=1e-13, method="dop853")
    np.testing.assert_allclose(positions(run), np.broadcast_to(r0, (4, 3)), atol=1e-9)


def test_local_basis_frame(run: mechsim.SimulationResult) -> None:
    """``particle`` axes: x = θ̂, y = φ̂, z = r̂ at the particle."""
    p = positions(run)
    r = np.linalg.norm(p, axis=1)
    th, ph = np.arccos(p[:, 2] / r), np.arctan2(p[:, 1], p[:, 0])
    rhat = p / r[:, None]
    that = np.stack([np.cos(th) * np.cos(ph), np.cos(th) * np.sin(ph), -np.sin(th)], axis=1)
    phat = np.stack([-np.sin(ph), np.cos(ph), 0 * ph], axis=1)
    rot = Rotation.from_quat(run.outputs.frames[:, 1, 3:]).as_matrix()
    np.testing.assert_allclose(rot[:, :, 2], rhat, atol=1e-12)
    np.testing.assert_allclose(rot[:, :, 0], that, atol=1e-12)
    np.testing.assert_allclose(rot[:, :, 1], phat, atol=1e-12)


def test_equals_the_planar_form_after_a_rotation() -> None:
    """Rotate the start into the orbit plane (e₁ = r̂₀, e₃ = L̂), run the planar two-body
    ``central_force`` with μ = m (m₁ = m₂ = 2m, CM at rest), rotate back."""
    r0, v0 = start(TILTED)
    e1 = r0 / np.linalg.norm(r0)
    e3 = np.cross(r0, v0) / np.linalg.norm(np.cross(r0, v0))
    e2 = np.cross(e3, e1)
    rn = float(np.linalg.norm(r0))
    planar = mechsim.load_system("central_force", formulation="cartesian", potential="kepler",
                                 mass_1=2.0, mass_2=2.0, force_constant=1.0,
                                 **{"initial.r": rn, "initial.theta": 0.0,
                                    "initial_rate.r": float(v0 @ e1),
                                    "initial_rate.theta": float(v0 @ e2) / rn,
                                    "initial_rate.cm_x": 0.0, "initial_rate.cm_y": 0.0})
    a = mechsim.simulate(planar, 20.0, 0.05, tolerance=1e-13, method="dop853")
    xy = a.q[:, 2:4]
    turned = xy[:, :1] * e1 + xy[:, 1:2] * e2
    for form in ("spherical", "cartesian"):
        b = mechsim.simulate(model(formulation=form, **TILTED), 20.0, 0.05, tolerance=1e-13,
                             method="dop853")
        np.testing.assert_allclose(positions(b), turned, atol=1e-10)
        np.testing.assert_allclose(b.total, a.total, atol=1e-12)


def test_forms_agree() -> None:
    kw = dict(TILTED, potential="kepler")
    s = mechsim.simulate(model(formulation="spherical", **kw), 20.0, 0.1, tolerance=1e-13,
                         method="dop853")
    c = mechsim.simulate(model(formulation="cartesian", **kw), 20.0, 0.1, tolerance=1e-13,
                         method="dop853")
    np.testing.assert_allclose(positions(s), positions(c), atol=1e-10)


def test_harmonic_is_simple_harmonic_per_axis() -> None:
    k, m = 2.0, 0.5
    w = math.sqrt(k / m)
    for form in ("spherical", "cartesian"):
        mod = model(formulation=form, potential="harmonic", spring_constant=k, mass=m, **TILTED)
        run = mechsim.simulate(mod, 10.0, 0.05, tolerance=1e-13, method="dop853")
        r0, v0 = mod.cartesian_state()
        exact = np.cos(w * run.t)[:, None] * r0 + np.sin(w * run.t)[:, None] * v0 / w
        np.testing.assert_allclose(positions(run), exact, atol=1e-10)
        for c in "xyz":
            assert np.ptp(run.invariants[f"energy_{c}"]) < 1e-11


def test_long_run_conservation() -> None:
    mod = model(**TILTED)
    T = 2 * math.pi * math.sqrt(mod.kepler_elements()["semi_major_axis"] ** 3)
    run = mechsim.simulate(mod, 300 * T, T / 7, tolerance=1e-12, method="gauss6")
    assert np.max(np.abs(run.total - run.total[0])) < 1e-10 * abs(run.total[0])
    for c in "xyz":
        assert np.ptp(run.invariants[f"angular_momentum_{c}"]) < 1e-9
        assert np.ptp(run.invariants[f"runge_lenz_{c}"]) < 1e-8
    n = np.array([run.invariants[f"angular_momentum_{c}"][0] for c in "xyz"])
    assert np.max(np.abs(positions(run) @ (n / np.linalg.norm(n)))) < 1e-9


def test_near_polar_orbits_need_the_cartesian_form() -> None:
    polar = {"initial.theta": 1.0, "initial_rate.theta": 1.0, "initial_rate.phi": 0.05}
    with pytest.raises(ParameterError) as err:
        model(**polar)
    assert err.value.field == "formulation" and "cartesian" in str(err.value)
    run = mechsim.simulate(model(formulation="cartesian", **polar), 10.0, 0.1,
                           tolerance=1e-12)
    assert np.ptp(run.total) < 1e-10


@pytest.mark.parametrize("kw,field", [({"initial.theta": 0.0}, "initial.theta"),
                                      ({"initial.theta": math.pi}, "initial.theta"),
                                      ({"initial_rate.theta": 0.0, "initial_rate.phi": 0.0},
                                       "initial_rate.theta"),
                                      ({"potential": "yukawa"}, "potential")])
def test_parameter_validation(kw: dict, field: str) -> None:
    with pytest.raises(ParameterError) as err:
        model(**kw)
    assert err.value.field == field


def test_component_laws_are_scaled_by_the_vector() -> None:
    """The default start has L_x = m r² φ̇ ... ≈ 6e-17 (cos π/2): each component's drift is
    measured against |L| (and |A| against mk), not against its own round-off value."""
    mod = model()
    r0, v0 = start({p.name: mod.value(p.name) for p in mod.parameter_spec()
                    if p.name.startswith("initial")})
    scales = mod.law_scales()
    for c in "xyz":
        assert scales[f"invariant:angular_momentum_{c}"] == pytest.approx(
            float(np.linalg.norm(np.cross(r0, v0))), rel=1e-14)
        assert scales[f"invariant:runge_lenz_{c}"] == 1.0
