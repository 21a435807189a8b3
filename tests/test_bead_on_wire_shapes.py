"""Bead on a wire (Introduction to analytical mechanics, “Brachistochrone problem – shortest time
problem”, PHYS0500 ch. 2): the cycloid as tautochrone/brachistochrone and a user-given curve.
Oracle: from rest anywhere on a cycloid of radius a the bead reaches the bottom after π√(a/g) and
passes it again every 2π√(a/g) (s̈ = −(g/4a) s in the arc length from the bottom, which follows from
z = s²/8a; catalog 001 §2.12)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mechsim

G, A = 9.81, 0.6


@pytest.mark.parametrize(("form", "x0"), [("reduced", 0.0), ("reduced", 0.4),
                                          ("reduced", 3.0), ("multiplier", 0.4),
                                          ("multiplier", 2.5)])
def test_cycloid_descent_time_from_any_start(form: str, x0: float) -> None:
    m = mechsim.load_system("bead_on_wire", shape="cycloid", formulation=form, gravity=G,
                            cycloid_radius=A, **{"initial.x": x0})
    t_bottom = math.pi * math.sqrt(A / G)
    run = mechsim.simulate(m, 3.2 * t_bottom, 0.01, tolerance=1e-12)
    times = run.event_times("lowest_point")
    expected = t_bottom * np.array([1.0, 3.0])
    assert times.size == 2
    np.testing.assert_allclose(times, expected, rtol=1e-10)
    scale = m.value("mass") * G * A
    assert np.max(np.abs(run.total - run.total[0])) < 1e-10 * scale
    assert np.max(np.abs(run.balance_residual)) < 1e-10 * scale
    assert np.all(np.isfinite(run.observables["normal_force"]))
    if form == "multiplier":
        for name, r in run.invariants.items():
            assert np.max(np.abs(r)) < 1e-12, name


def test_cycloid_normal_force_agrees_between_forms() -> None:
    kw = {"shape": "cycloid", "cycloid_radius": A, "initial.x": 0.3}
    red = mechsim.simulate(mechsim.load_system("bead_on_wire", **kw), 2.0, 0.01,
                           tolerance=1e-12)
    mul = mechsim.simulate(mechsim.load_system("bead_on_wire", formulation="multiplier", **kw),
                           2.0, 0.01, tolerance=1e-12)
    np.testing.assert_allclose(red.observables["x"], mul.q[:, 0], atol=1e-8)
    np.testing.assert_allclose(red.observables["normal_force"],
                               mul.observables["normal_force"], rtol=1e-7)
    # At the bottom (s = 0): N = m(g + v²/(4a)), v² = 2 g z₀ (z₀ = s₀²/8a).
    s, ds = red.q[:, 0], red.v[:, 0]
    k = np.argmin(np.abs(s))
    v2 = ds[k] ** 2
    assert abs(red.observables["normal_force"][k] - (G + v2 / (4 * A))) < 1e-3 * G
    z0 = s[0] ** 2 / (8 * A)
    assert abs(red.total[0] - G * z0) < 1e-12


def test_custom_curve_forms_agree_and_conserve_energy() -> None:
    kw = {"shape": "custom", "curve": "cosh(x) - 1 + 0.1*sin(3*x)", "initial.x": 1.0}
    red = mechsim.simulate(mechsim.load_system("bead_on_wire", **kw), 5.0, 0.01,
                           tolerance=1e-12)
    mul = mechsim.simulate(mechsim.load_system("bead_on_wire", formulation="multiplier", **kw),
                           5.0, 0.01, tolerance=1e-12)
    np.testing.assert_allclose(red.q[:, 0], mul.q[:, 0], atol=1e-8)
    x = mul.q[:, 0]
    np.testing.assert_allclose(mul.q[:, 1], np.cosh(x) - 1 + 0.1 * np.sin(3 * x), atol=1e-13)
    for r in (red, mul):
        assert np.max(np.abs(r.total - r.total[0])) < 1e-10 * 9.81
    np.testing.assert_allclose(red.observables["normal_force"], mul.observables["normal_force"],
                               rtol=1e-7)
