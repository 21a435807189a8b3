"""Planar isotropic oscillator (PHYS0500 §1.2, “Energy and Hamiltonians: Part 3 – Examples”, Case
3): Cartesian and polar forms agree, exact elliptic orbit, L_z, E_x, E_y and E = h conserved, the
document's radial equation is missing the centrifugal term."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import mechsim
from mechsim.errors import ParameterError

IC = {"initial.x": 0.8, "initial.y": -0.3, "initial_rate.x": 0.5, "initial_rate.y": 1.4}


def model(**kw):
    return mechsim.load_system("planar_oscillator", **kw)


def test_polar_equations_from_the_lagrangian() -> None:
    """sympy: the polar EL equation is m r̈ = −k r + m r θ̇² (the document's L445 drops the
    last term; its numerical form at L452 has it)."""
    t = sp.Symbol("t")
    m, k = sp.symbols("m k", positive=True)
    r, th = sp.Function("r")(t), sp.Function("theta")(t)
    L = m * (r.diff(t) ** 2 + r**2 * th.diff(t) ** 2) / 2 - k * r**2 / 2
    el_r = sp.diff(L.diff(r.diff(t)), t) - L.diff(r)
    assert sp.simplify(el_r - (m * r.diff(t, 2) + k * r - m * r * th.diff(t) ** 2)) == 0
    # Cartesian L under x = r cos θ, y = r sin θ is the polar L.
    x, y = r * sp.cos(th), r * sp.sin(th)
    Lc = m * (x.diff(t) ** 2 + y.diff(t) ** 2) / 2 - k * (x**2 + y**2) / 2
    assert sp.simplify(Lc - L) == 0


@pytest.mark.parametrize("formulation", ["cartesian", "polar"])
def test_exact_orbit(formulation: str) -> None:
    m = model(formulation=formulation, mass=1.5, spring_constant=3.0, **IC)
    r = mechsim.simulate(m, 15.0, 0.05, tolerance=1e-12, method="dop853")
    xy = m.exact_position(r.t)
    if formulation == "cartesian":
        got = r.q
    else:
        got = np.stack([r.observables["x"], r.observables["y"]], axis=-1)
    np.testing.assert_allclose(got, xy, atol=2e-9)
    w = math.sqrt(2.0)
    vx0, vy0 = 0.5, 1.4
    E = 0.5 * 1.5 * (vx0**2 + vy0**2) + 0.5 * 3.0 * (0.8**2 + 0.3**2)
    Lz = 1.5 * (0.8 * vy0 + 0.3 * vx0)
    assert m.natural_frequency() == pytest.approx(w, rel=1e-15)
    np.testing.assert_allclose(r.total, E, rtol=1e-10)
    np.testing.assert_allclose(r.energy_function, r.total, rtol=1e-10)  # E = h (Case 3)
    np.testing.assert_allclose(r.invariants["angular_momentum"], Lz, rtol=1e-10)
    np.testing.assert_allclose(r.invariants["energy_x"], 0.5 * 1.5 * vx0**2 + 1.5 * 0.64,
                               rtol=1e-9)
    assert np.max(np.abs(r.balance_residual)) < 1e-9


def test_formulations_agree() -> None:
    rs = [mechsim.simulate(model(formulation=f, **IC), 30.0, 0.1, tolerance=1e-12,
                           method="dop853") for f in ("cartesian", "polar")]
    np.testing.assert_allclose(rs[0].observables["radius"], rs[1].observables["radius"],
                               atol=1e-8)
    np.testing.assert_allclose(rs[0].total, rs[1].total, rtol=1e-10)
    np.testing.assert_allclose(rs[0].outputs.frames[:, 2, :3], rs[1].outputs.frames[:, 2, :3],
                               atol=1e-8)  # the mass frame


def test_document_circular_orbit() -> None:
    """S̄₀ = (R, 0, 0, Rω₀): r ≡ R, θ = ω₀t, KE = ½kR², E = kR², L_z = mR²ω₀. The text's
    radial equation m r̈ + k r = 0 would give r = R cos ω₀t instead."""
    R, mass, k = 0.7, 2.0, 8.0
    w = math.sqrt(k / mass)
    m = model(formulation="polar", mass=mass, spring_constant=k,
              **{"initial.x": R, "initial.y": 0.0, "initial_rate.x": 0.0,
                 "initial_rate.y": R * w})
    r = mechsim.simulate(m, 10.0, 0.05, tolerance=1e-12)
    np.testing.assert_allclose(r.coordinate("r"), R, atol=1e-10)
    np.testing.assert_allclose(r.coordinate("theta"), w * r.t, atol=1e-9)
    np.testing.assert_allclose(r.kinetic, 0.5 * k * R**2, rtol=1e-10)
    np.testing.assert_allclose(r.total, k * R**2, rtol=1e-10)
    np.testing.assert_allclose(r.invariants["angular_momentum"], mass * R**2 * w, rtol=1e-10)
    assert np.max(np.abs(r.coordinate("r") - R * np.cos(w * r.t))) > 0.5 * R


def test_long_run_conservation() -> None:
    cart = mechsim.simulate(model(**IC), 2000.0, 0.5, tolerance=1e-14)
    assert cart.method == "radau15"  # auto at 1e-14: the machine-precision method
    rel = np.abs(cart.total / cart.total[0] - 1)
    assert rel.max() < 1e-8
    assert np.ptp(cart.invariants["angular_momentum"]) < 1e-10
    polar = mechsim.simulate(model(formulation="polar", **IC), 2000.0, 0.5, tolerance=1e-12)
    assert np.max(np.abs(polar.total / polar.total[0] - 1)) < 1e-8
    assert np.ptp(polar.invariants["angular_momentum"]) < 1e-8
    assert np.max(np.abs(polar.balance_residual)) < 1e-8


def test_frames() -> None:
    m = model(formulation="polar", **IC)
    assert [(f.child, f.parent, f.static) for f in m.frames] == [
        ("center", "world", True), ("polar", "center", False), ("mass", "center", False)]


def test_parameter_validation() -> None:
    with pytest.raises(ParameterError) as err:
        model(formulation="polar", **{"initial.x": 1.0, "initial.y": 0.0,
                                      "initial_rate.x": 0.3, "initial_rate.y": 0.0})
    assert err.value.field == "formulation"
    model(formulation="cartesian", **{"initial_rate.y": 0.0})  # fine: a line through 0
    with pytest.raises(ParameterError) as err:
        model(spring_constant=0.0)
    assert err.value.field == "spring_constant"
    with pytest.raises(ParameterError) as err:
        model(formulation="spherical")
    assert err.value.field == "formulation"
