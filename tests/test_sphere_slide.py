"""Particle sliding off a sphere (Introduction to analytical mechanics, “Constraints”): normal
force = multiplier, departure event at
cos θ = (2 cos θ₀ + R θ̇₀²/g)/3 (2/3 from rest), its time against an mpmath quadrature, the
projectile flight afterwards, both formulations agreeing, energy and work balance.

Oracles are written out here from energy conservation (checked with sympy in development):
θ̇² = θ̇₀² + (2g/R)(cos θ₀ − cos θ) on the sphere, N = m g cos θ − m R θ̇², departure where N = 0,
t* = ∫ dθ/θ̇ from θ₀ to θ*.
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest

import mechsim
from mechsim.errors import ParameterError
from mechsim.integrators import make_stepper

M, R, G = 0.5, 1.5, 9.81


def _model(form: str, th0: float = 0.01, w0: float = 0.0) -> mechsim.systems.base.Model:
    return mechsim.load_system("sphere_slide", formulation=form, mass=M, radius=R, gravity=G,
                               **{"initial.angle": th0, "initial_rate.angle": w0})


def _departure(th0: float, w0: float) -> tuple[float, float, float]:
    """(θ*, θ̇*, t*) from energy conservation, t* by 30-digit quadrature."""
    mpmath.mp.dps = 30
    c = (2 * math.cos(th0) + R * w0**2 / G) / 3
    th_star = math.acos(c)
    rate = lambda th: mpmath.sqrt(w0**2 + 2 * G / R * (mpmath.cos(th0) - mpmath.cos(th)))  # noqa: E731
    t_star = mpmath.quad(lambda th: 1 / rate(th), [th0, (th0 + th_star) / 2, th_star])
    return th_star, float(rate(th_star)), float(t_star)


def _angle_and_xz(form: str, Y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    if form == "polar":
        r, th = Y[:, 0], Y[:, 1]
        return th, r * np.sin(th), r * np.cos(th)
    x, z = Y[:, 0], Y[:, 1]
    return np.arctan2(x, z), x, z


@pytest.mark.parametrize("form", ["polar", "cartesian"])
@pytest.mark.parametrize(("th0", "w0"), [(0.01, 0.0), (0.3, 0.0), (0.2, 1.0)])
def test_departure_angle_and_time(form: str, th0: float, w0: float) -> None:
    th_star, _, t_star = _departure(th0, w0)
    m = _model(form, th0, w0)
    run = mechsim.simulate(m, t_star + 0.5, 0.01, tolerance=1e-12)
    assert [n for _, n in run.events] == ["departure"]
    t_ev = run.events[0][0]
    assert abs(t_ev - t_star) < 1e-9 * t_star
    # State at exactly the event time (a row there holds the state after the handler).
    Y = make_stepper(m, "dop853", 1e-12).advance(np.array([0.0, t_ev]))
    th, _, _ = _angle_and_xz(form, Y[1:])
    assert abs(math.cos(th[0]) - m.departure_cosine()) < 1e-10  # type: ignore[attr-defined]
    assert abs(math.cos(th[0]) - (2 * math.cos(th0) + R * w0**2 / G) / 3) < 1e-10
    if th0 == 0.01 and w0 == 0.0:
        assert abs(math.cos(th[0]) - 2 / 3) < 1e-4  # the textbook point, θ₀ → 0


@pytest.mark.parametrize("form", ["polar", "cartesian"])
def test_normal_force_on_sphere_then_zero_in_flight(form: str) -> None:
    th0 = 0.3
    m = _model(form, th0)
    run = mechsim.simulate(m, 1.5, 0.005, tolerance=1e-12)
    t_ev = run.events[0][0]
    on = run.t < t_ev
    th, _, _ = _angle_and_xz(form, np.column_stack([run.q]))
    N_expected = M * G * (3 * np.cos(th[on]) - 2 * math.cos(th0))
    assert np.max(np.abs(run.observables["normal_force"][on] - N_expected)) < 1e-8 * M * G
    assert np.allclose(m.normal_force_at(th[on]), N_expected, rtol=1e-14, atol=1e-14 * M * G)
    assert np.all(run.observables["normal_force"][on] > 0)
    assert np.all(run.observables["normal_force"][~on] == 0.0)
    np.testing.assert_array_equal(run.mode("phase"), (~on).astype(float))
    # On the sphere the constraint holds to round-off; off it the particle moves away.
    assert np.max(np.abs(run.observables["distance_from_centre"][on] - R)) < 1e-12
    assert np.all(np.diff(run.observables["distance_from_centre"][~on]) > 0)


@pytest.mark.parametrize("form", ["polar", "cartesian"])
def test_free_flight_is_the_projectile_parabola(form: str) -> None:
    th0 = 0.2
    th_s, w_s, t_s = _departure(th0, 0.0)
    m = _model(form, th0)
    run = mechsim.simulate(m, t_s + 0.6, 0.01, tolerance=1e-12)
    x0, z0 = R * math.sin(th_s), R * math.cos(th_s)
    vx, vz = R * w_s * math.cos(th_s), -R * w_s * math.sin(th_s)
    after = run.t > run.events[0][0]
    tau = run.t[after] - t_s
    _, x, z = _angle_and_xz(form, run.q[after])
    assert np.max(np.abs(x - (x0 + vx * tau))) < 1e-8
    assert np.max(np.abs(z - (z0 + vz * tau - G * tau**2 / 2))) < 1e-8


def test_formulations_agree_and_energy_balance_holds() -> None:
    runs = [mechsim.simulate(_model(f, 0.05), 3.0, 0.01, tolerance=1e-12)
            for f in ("polar", "cartesian")]
    _, xp, zp = _angle_and_xz("polar", runs[0].q)
    _, xc, zc = _angle_and_xz("cartesian", runs[1].q)
    assert np.max(np.hypot(xp - xc, zp - zc)) < 1e-8
    assert abs(runs[0].events[0][0] - runs[1].events[0][0]) < 1e-10
    for r in runs:
        scale = M * G * 2 * R
        assert np.max(np.abs(r.total - r.total[0])) < 1e-10 * scale
        assert np.max(np.abs(r.balance_residual)) < 1e-10 * scale
        assert np.max(np.abs(r.invariants["constraint_surface"])) < 1e-12
        assert np.max(np.abs(r.energy_function - r.total)) < 1e-10 * scale


def test_laws_and_events_declared() -> None:
    m = _model("polar")
    keys = [law.key for law in m.laws()]
    assert keys == ["energy", "energy_function", "work_balance", "constraint:constraint_surface"]
    assert [e.name for e in m.events] == ["departure"] and m.events[0].direction == -1
    assert [q.name for q in m.modes] == ["phase"]


def test_parameter_validation() -> None:
    with pytest.raises(ParameterError, match="^initial_rate.angle: too fast"):
        _model("polar", 0.0, 3.0)
    with pytest.raises(ParameterError, match="^initial.angle: must be <"):
        _model("polar", 2.0)
    with pytest.raises(ParameterError, match="^radius: must be > 0"):
        mechsim.load_system("sphere_slide", radius=0.0)
