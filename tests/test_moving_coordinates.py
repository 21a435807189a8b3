"""Free particle in inertial, Galilean and accelerating coordinates (“Energy and Hamiltonians: Part
3 – Examples”, Cases 1–2; Lecture 10, linearly accelerated frame (eq. 10.24)): E and h exactly as
derived (with the document's "h_q = 0" corrected)."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import mechsim
from mechsim.errors import ParameterError

P = {"mass": 2.0, "frame_velocity": 0.7, "frame_acceleration": 0.4, "initial.x": 0.3,
     "initial_rate.x": 1.2}


def model(formulation: str, **kw):
    return mechsim.load_system("moving_coordinates", formulation=formulation, **{**P, **kw})


def test_energy_functions_from_the_lagrangians() -> None:
    """sympy: h_q of each L, and its value on the true motion."""
    t, m, u, a, x0, v0 = sp.symbols("t m u a x0 v0", real=True)
    q, qd = sp.symbols("q qd", real=True)
    for X, h_on_motion in ((u * t, m * (v0 - u) ** 2 / 2 - m * u**2 / 2),
                           (a * t**2 / 2, m * v0**2 / 2 - m * a * v0 * t)):
        L = m * (qd + X.diff(t)) ** 2 / 2
        h = sp.expand(qd * L.diff(qd) - L)
        assert sp.simplify(h - (m * qd**2 / 2 - m * X.diff(t) ** 2 / 2)) == 0
        motion = {q: x0 + v0 * t - X, qd: v0 - X.diff(t)}
        assert sp.simplify(h.subs(motion) - h_on_motion) == 0
        assert sp.simplify(L.subs(motion) - m * v0**2 / 2) == 0  # E = T = ½mv₀²
    # gauge form L′ = ½mq̇² − maq: h′ = ½mq̇² + maq is constant on q̈ = −a
    qt = x0 + v0 * t - a * t**2 / 2
    assert sp.simplify(sp.diff(m * qt.diff(t) ** 2 / 2 + m * a * qt, t)) == 0


@pytest.mark.parametrize("formulation", ["inertial", "galilean", "accelerating"])
def test_same_inertial_motion_and_energies(formulation: str) -> None:
    mod = model(formulation)
    r = mechsim.simulate(mod, 10.0, 0.1, tolerance=1e-12)
    x = (r.coordinate("x") if formulation == "inertial"
         else r.observables["inertial_position"])
    np.testing.assert_allclose(x, 0.3 + 1.2 * r.t, atol=1e-10)
    np.testing.assert_allclose(mod.inertial_position(r.t), 0.3 + 1.2 * r.t, atol=1e-14)
    E = 0.5 * 2.0 * 1.2**2
    np.testing.assert_allclose(r.total, E, rtol=1e-11)  # E conserved in all three
    h = {"inertial": E + 0 * r.t,
         "galilean": 0.5 * 2.0 * (1.2 - 0.7) ** 2 - 0.5 * 2.0 * 0.7**2 + 0 * r.t,
         "accelerating": E - 2.0 * 0.4 * 1.2 * r.t}[formulation]
    np.testing.assert_allclose(r.energy_function, h, atol=1e-10)
    np.testing.assert_allclose(mod.energy_function(r.t), h, atol=1e-13)
    assert np.max(np.abs(r.balance_residual)) < 1e-10
    if formulation != "inertial":
        fr = r.outputs.frames  # moving_frame (child of world), particle (child of it)
        np.testing.assert_allclose(fr[:, 0, 0], r.observables["frame_position"], atol=1e-15)
        np.testing.assert_allclose(fr[:, 0, 0] + fr[:, 1, 0], 0.3 + 1.2 * r.t, atol=1e-10)


def test_document_comoving_case() -> None:
    """u = v₀: q ≡ x₀ and h_q = −½mv₀² — constant, but not the "0" of L395."""
    mod = model("galilean", frame_velocity=1.2)
    r = mechsim.simulate(mod, 10.0, 0.5)
    np.testing.assert_allclose(r.coordinate("q"), 0.3, atol=1e-12)
    np.testing.assert_allclose(r.energy_function, -0.5 * 2.0 * 1.2**2, atol=1e-12)
    np.testing.assert_allclose(r.total, 0.5 * 2.0 * 1.2**2, atol=1e-12)


def test_accelerating_frame() -> None:
    mod = model("accelerating")
    r = mechsim.simulate(mod, 20.0, 0.1, tolerance=1e-12)
    q = 0.3 + 1.2 * r.t - 0.2 * r.t**2
    np.testing.assert_allclose(r.coordinate("q"), q, atol=1e-10)
    h_gauge = r.invariants["gauge_energy_function"]
    np.testing.assert_allclose(h_gauge, 0.5 * 2.0 * 1.2**2 + 2.0 * 0.4 * 0.3, atol=1e-10)
    np.testing.assert_allclose(r.observables["frame_position"], 0.2 * r.t**2, atol=1e-13)


def test_laws_and_frames() -> None:
    keys = {f: [law.key for law in model(f).laws()]
            for f in ("inertial", "galilean", "accelerating")}
    assert keys["inertial"] == ["energy", "energy_function", "work_balance"]
    assert keys["galilean"] == ["energy", "energy_function", "work_balance"]  # Case 1
    assert keys["accelerating"] == ["energy", "work_balance",  # Case 2: E yes, h no
                                    "invariant:gauge_energy_function"]
    for f in ("galilean", "accelerating"):
        assert [(s.child, s.parent, s.static) for s in model(f).frames] == [
            ("moving_frame", "world", False), ("particle", "moving_frame", False)]


def test_long_run() -> None:
    r = mechsim.simulate(model("accelerating"), 1000.0, 1.0, tolerance=1e-12)
    assert np.max(np.abs(r.total / r.total[0] - 1)) < 1e-10
    assert np.max(np.abs(r.balance_residual)) < 1e-8


def test_parameter_validation() -> None:
    with pytest.raises(ParameterError) as err:
        model("rotating")
    assert err.value.field == "formulation"
    with pytest.raises(ParameterError) as err:
        model("galilean", mass=0.0)
    assert err.value.field == "mass"
    with pytest.raises(ParameterError) as err:
        model("galilean", frame_speed=1.0)
    assert err.value.field == "frame_speed"
