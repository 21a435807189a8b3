"""Rigid dumbbell / diatomic molecule (Introduction to analytical mechanics, “Constraints”): six
degrees of freedom minus one rod constraint; the exact motion written here (CM parabola, the rod
turning uniformly about the fixed L̂ by Rodrigues' formula), the rod tension μdω² as the multiplier,
L about the CM conserved, free and in gravity; reduced and multiplier forms agree."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mechsim
from mechsim.errors import ParameterError

M1, M2, D, G = 1.0, 2.0, 1.0, 9.81
MU = M1 * M2 / (M1 + M2)


def model(**kw):
    return mechsim.load_system("dumbbell", **kw)


def exact(kw: dict, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(R, r₁, r₂) at t: R = R₀ + V₀t − ½gt²ẑ; n̂ = n̂₀ turned about ω̂ = n̂₀ × ṅ₀/|ṅ₀| by ωt."""
    th, ph, dth, dph = kw["initial.theta"], kw["initial.phi"], kw["initial_rate.theta"], \
        kw["initial_rate.phi"]
    g = kw.get("gravity", G)
    n0 = np.array([math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th)])
    dn0 = dth * np.array([math.cos(th) * math.cos(ph), math.cos(th) * math.sin(ph),
                          -math.sin(th)]) + math.sin(th) * dph * np.array([-math.sin(ph),
                                                                             math.cos(ph), 0])
    w = float(np.linalg.norm(dn0))
    axis = np.cross(n0, dn0) / w
    a = w * t[:, None]
    n = n0 * np.cos(a) + np.cross(axis, n0) * np.sin(a)  # axis ⟂ n0
    V0 = np.array([kw.get("initial_rate.cm_x", 1.0), 0.0, kw.get("initial_rate.cm_z", 6.0)])
    R = V0 * t[:, None] - 0.5 * g * t[:, None] ** 2 * np.array([0, 0, 1.0])
    M = M1 + M2
    return R, R + M2 / M * D * n, R - M1 / M * D * n


def positions(run: mechsim.SimulationResult) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    f = run.outputs.frames
    R = f[:, 0, :3]  # cm
    return R, R + f[:, 2, :3], R + f[:, 3, :3]  # mass_1, mass_2 are children of cm


DEFAULT = {"initial.theta": math.pi / 2, "initial.phi": 0.0, "initial_rate.theta": 1.5,
           "initial_rate.phi": 3.0}
TILTED = {"initial.theta": 1.2, "initial.phi": 0.3, "initial_rate.theta": 1.5,
          "initial_rate.phi": 3.0}


@pytest.mark.parametrize("form", ["reduced", "multiplier"])
@pytest.mark.parametrize("g", [0.0, G])
def test_exact_motion_free_and_in_gravity(form: str, g: float) -> None:
    kw = dict(TILTED, gravity=g)
    run = mechsim.simulate(model(formulation=form, **kw), 6.0, 0.05, tolerance=1e-12,
                           method="dop853")
    for got, want in zip(positions(run), exact(kw, run.t), strict=True):
        np.testing.assert_allclose(got, want, atol=2e-9)
    if form == "multiplier":
        np.testing.assert_allclose(run.q[:, 0:3], exact(kw, run.t)[1], atol=2e-9)


@pytest.mark.parametrize("form", ["reduced", "multiplier"])
def test_tension_of_pure_rotation(form: str) -> None:
    """Spinning in the horizontal plane at ω (in gravity): the rod tension is μω²d."""
    w = 2.5
    kw = {"initial.theta": math.pi / 2, "initial_rate.theta": 0.0, "initial_rate.phi": w,
          "gravity": G}
    run = mechsim.simulate(model(formulation=form, **kw), 5.0, 0.05, tolerance=1e-12)
    np.testing.assert_allclose(run.observables["tension"], MU * w**2 * D, rtol=1e-8)
    if form == "multiplier":
        np.testing.assert_allclose(run.observables["multiplier"], -MU * w**2 * D, rtol=1e-8)
    # the rod stays horizontal: the CM falls, but both ends fall alike
    _, r1, r2 = positions(run)
    np.testing.assert_allclose(r1[:, 2] - r2[:, 2], 0.0, atol=1e-9)


def test_forms_agree_and_tension_is_the_multiplier() -> None:
    a = mechsim.simulate(model(formulation="reduced", **TILTED), 8.0, 0.02, tolerance=1e-12,
                         method="dop853")
    b = mechsim.simulate(model(formulation="multiplier", **TILTED), 8.0, 0.02,
                         tolerance=1e-12)
    for x, y in zip(positions(a), positions(b), strict=True):
        np.testing.assert_allclose(x, y, atol=2e-9)
    # −λ (multiplier form) equals μ d (θ̇² + sin²θ φ̇²) (reduced form) and the constant μdω²
    w2 = 1.5**2 + (math.sin(1.2) * 3.0) ** 2
    np.testing.assert_allclose(a.observables["tension"], MU * D * w2, rtol=1e-10)
    np.testing.assert_allclose(b.observables["tension"], MU * D * w2, rtol=1e-7)
    assert np.max(np.abs(b.invariants["constraint_rod_length"])) < 1e-12
    # θ of the reduced form matches the direction of r₁ − r₂ in the multiplier form
    rel = b.q[:, 0:3] - b.q[:, 3:6]
    np.testing.assert_allclose(np.cos(a.q[:, 3]), rel[:, 2] / D, atol=1e-9)


def test_degrees_of_freedom() -> None:
    """Six Cartesian coordinates minus one constraint = the five of the reduced form."""
    red, mul = model(formulation="reduced"), model(formulation="multiplier")
    assert len(red.coordinates) == 5 and red.structure.n_constraints == 0
    assert len(mul.coordinates) == 6 and mul.structure.n_constraints == 1
    assert [c.name for c in red.coordinates] == ["cm_x", "cm_y", "cm_z", "theta", "phi"]


def test_conserved_about_the_centre_of_mass() -> None:
    run = mechsim.simulate(model(**TILTED), 10.0, 0.05, tolerance=1e-12)
    n0, dn0 = model(**TILTED).rod_state()
    L0 = MU * D**2 * np.cross(n0, dn0)
    L = np.stack([run.invariants[f"angular_momentum_{c}"] for c in "xyz"], axis=1)
    np.testing.assert_allclose(L, np.broadcast_to(L0, L.shape), atol=1e-12)
    np.testing.assert_allclose(run.invariants["rotational_energy"],
                               0.5 * MU * D**2 * float(dn0 @ dn0), rtol=1e-12)
    np.testing.assert_allclose(run.observables["angular_speed"], np.linalg.norm(dn0),
                               rtol=1e-12)
    # CM: horizontal momentum, and the vertical one in the freely falling frame M(Ż + gt)
    np.testing.assert_allclose(run.invariants["momentum_x"], (M1 + M2) * 1.0, rtol=1e-14)
    np.testing.assert_allclose(run.invariants["momentum_z_falling_frame"], (M1 + M2) * 6.0,
                               rtol=1e-12)
    np.testing.assert_allclose(run.observables["cm_height"], 6.0 * run.t - 0.5 * G * run.t**2,
                               atol=1e-9)


@pytest.mark.parametrize("form", ["reduced", "multiplier"])
def test_long_run_conservation(form: str) -> None:
    mod = model(formulation=form, gravity=0.0, **{"initial_rate.cm_z": 0.0})
    run = mechsim.simulate(mod, 2000.0, 0.5, tolerance=1e-12)
    e0 = run.total[0]
    assert np.max(np.abs(run.total - e0)) < 1e-8 * e0
    for c in "xyz":
        assert np.ptp(run.invariants[f"angular_momentum_{c}"]) < 1e-8
    if form == "multiplier":
        assert np.max(np.abs(run.invariants["constraint_rod_length"])) < 1e-12
    # still on the exact rotation after ~1000 turns
    kw = dict(DEFAULT, gravity=0.0, **{"initial_rate.cm_z": 0.0})
    _, r1, _ = exact(kw, run.t[-5:])
    np.testing.assert_allclose(positions(run)[1][-5:], r1, atol=1e-6)


def test_near_vertical_rod_needs_the_multiplier_form() -> None:
    kw = {"initial.theta": 1.0, "initial_rate.theta": 2.0, "initial_rate.phi": 0.05}
    with pytest.raises(ParameterError) as err:
        model(**kw)
    assert err.value.field == "formulation" and "multiplier" in str(err.value)
    run = mechsim.simulate(model(formulation="multiplier", **kw), 5.0, 0.05, tolerance=1e-12)
    for got, want in zip(positions(run), exact(dict(kw, **{"initial.phi": 0.0}), run.t),
                         strict=True):
        np.testing.assert_allclose(got, want, atol=1e-8)


@pytest.mark.parametrize("kw,field", [({"rod_length": 0.0}, "rod_length"),
                                      ({"initial.theta": 0.0}, "initial.theta"),
                                      ({"gravity": -9.81}, "gravity")])
def test_parameter_validation(kw: dict, field: str) -> None:
    with pytest.raises(ParameterError) as err:
        model(**kw)
    assert err.value.field == field
