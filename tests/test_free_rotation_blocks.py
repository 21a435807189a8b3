"""The torque-free rigid body's closed form as evaluated in blocks of samples
(``_free_rotation._torque_free_motion``): its vectorizing cos/sin and half angles against
``math``, and runs of several blocks, in any order of the times and from any anchor time,
against an independent integration."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mechsim
from mechsim.integrators import make_stepper
from mechsim.systems import _free_rotation, _rigid


def test_cos_sin_within_an_ulp_of_math() -> None:
    rng = np.random.default_rng(11)
    x = np.concatenate([
        rng.uniform(-1.0, 1.0, 20000), rng.uniform(-1e3, 1e3, 20000),
        rng.uniform(-2.0**19, 2.0**19, 20000),  # the largest reduced here
        rng.uniform(-1e9, 1e9, 2000),  # reduced by math
        np.arange(-2000, 2000) * (0.5 * math.pi),  # next to multiples of π/2
        np.nextafter(np.arange(-2000, 2000) * (0.5 * math.pi), np.inf),
        [0.0, -0.0, 5e-324, -1e-300, 2.0**19, -(2.0**19), np.nextafter(2.0**19, np.inf)]])
    c, s = np.empty_like(x), np.empty_like(x)
    _free_rotation._cos_sin(x, c, s)
    cos_ref = np.array([math.cos(v) for v in x])
    sin_ref = np.array([math.sin(v) for v in x])
    # within an ulp of 1 (values of magnitude ≤ 1), and relative to small values
    assert np.max(np.abs(c - cos_ref)) <= 2.3e-16
    assert np.max(np.abs(s - sin_ref)) <= 2.3e-16
    small = np.abs(x) < 0.5
    assert np.max(np.abs(s[small] - sin_ref[small]) / np.maximum(np.abs(sin_ref[small]),
                                                                    5e-324)) <= 2.3e-16
    odd = np.array([np.inf, -np.inf, np.nan])
    c, s = np.empty(3), np.empty(3)
    _free_rotation._cos_sin(odd, c, s)
    assert np.isnan(c).all() and np.isnan(s).all()


def test_half_angle_is_half_of_atan2() -> None:
    rng = np.random.default_rng(5)
    points = [tuple(p) for p in rng.normal(size=(2000, 2))]
    points += [(0.0, 1.0), (0.0, -1.0), (1e-300, -2.0), (-1e-300, -2.0), (0.0, 0.0),
               (-0.0, 0.0), (0.0, -0.0), (-0.0, -0.0), (3.0, 0.0), (-3.0, -0.0)]
    for y, x in points:
        half = 0.5 * math.atan2(y, x)
        c, s = _free_rotation._half_angle(y, x, math.hypot(x, y))
        assert abs(c - math.cos(half)) <= 4e-16 and abs(s - math.sin(half)) <= 4e-16, (y, x)
        assert math.copysign(1.0, s) == math.copysign(1.0, math.sin(half)), (y, x)


BODIES = [
    {"initial.omega_1": 3.0, "initial.omega_2": 1.0, "initial.omega_3": 2.0},
    {"initial.omega_1": 0.02, "initial.omega_2": 4.0, "initial.omega_3": 0.02},  # 1 − m ≈ 2e-5
    {"initial.omega_1": -0.02, "initial.omega_2": 4.0, "initial.omega_3": -0.03},  # other side
    {"shape": "cylinder", "initial.omega_1": 1.0, "initial.omega_2": 2.0,
     "initial.omega_3": 3.0},  # body of revolution: m = 0
]


@pytest.mark.parametrize("values", BODIES)
def test_several_blocks_in_any_order_against_an_integration(values: dict) -> None:
    """700 times (three blocks, the last one partial), shuffled, from an anchor t₀ ≠ 0 with
    nonzero work terms: every row as radau15 at 1e-14 gives it, the work terms carried."""
    model = mechsim.load_system("rigid_body", **values)
    t0 = 3.0
    y0 = model.initial_y()
    y0[8:] = (0.25, -0.5)
    t = t0 + np.linspace(0.0, 2.0 * model.time_scale(), 701)[1:]
    order = np.random.default_rng(2).permutation(t.size)
    rows = np.empty_like(model.propagate(t0, y0, t[order]))
    rows[order] = model.propagate(t0, y0, t[order])
    ref = make_stepper(model, "radau15", 1e-14, t0=t0, y0=y0).advance(t)
    assert np.max(np.abs(rows[:, :4] - ref[:, :4])) < 1e-12
    scale = float(np.max(np.abs(ref[:, 4:8])))
    assert np.max(np.abs(rows[:, 4:8] - ref[:, 4:8])) < 1e-12 * scale
    assert np.array_equal(rows[:, 8:], np.broadcast_to(y0[8:], (t.size, 2)))


@pytest.mark.parametrize("values", BODIES[:3])
def test_the_initial_state_is_reproduced(values: dict) -> None:
    model = mechsim.load_system("rigid_body", **values)
    y0 = model.initial_y()
    q0 = y0[:4] / np.linalg.norm(y0[:4])
    w0 = np.array(_rigid.rb_omega(y0))
    rows, W = _free_rotation.free_rotation(model.rigid.moments, q0, w0, np.zeros(1))
    assert np.max(np.abs(rows[0, :4] - q0)) < 1e-15
    assert np.max(np.abs(W[0] - w0)) < 1e-14 * np.max(np.abs(w0))
