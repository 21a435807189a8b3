"""Closed-form propagation (method "exact") against the integrator at tight tolerance, for
every system that has one; resumable; refused where there is none."""

from __future__ import annotations

import numpy as np
import pytest

import mechsim
from mechsim.integrators import make_stepper

CASES = [
    ("harmonic_oscillator", {"initial.x": 0.3, "initial_rate.x": -1.1}),
    ("damped_oscillator", {"damping": 0.4}),                       # underdamped
    ("damped_oscillator", {"damping": 4.0}),                       # critical: b = 2√(mk)
    ("damped_oscillator", {"damping": 9.0}),                       # overdamped
    ("driven_oscillator", {}),
    ("driven_oscillator", {"initial.x": 0.7, "initial_rate.x": 0.2, "drive_frequency": 2.0}),
    ("driven_oscillator", {"damping": 9.0, "initial.x": 0.3}),     # overdamped, driven
    ("driven_oscillator", {"damping": 0.0, "initial_rate.x": 0.5}),  # undamped, off resonance
    ("periodic_drive", {"harmonics": 5, "initial.x": 0.2}),
    ("planar_oscillator", {"formulation": "cartesian"}),
    ("pendulum", {}),                                              # libration
    ("pendulum", {"initial.angle": 3.1}),                          # near the separatrix
    ("pendulum", {"initial.angle": -0.5, "initial_rate.angle": 7.5}),  # rotation
    ("pendulum", {"initial.angle": 2.0, "initial_rate.angle": -9.0}),  # rotation, φ̇ < 0
    ("kepler", {"eccentricity": 0.0}),
    ("kepler", {"eccentricity": 0.5}),
    ("kepler", {"eccentricity": 0.9}),
]


@pytest.mark.parametrize("system, params", CASES)
def test_exact_matches_tight_integration(system: str, params: dict) -> None:
    model = mechsim.load_system(system, **params)
    t_end = 4 * model.time_scale()
    dt = model.time_scale() / 37
    exact = mechsim.simulate(model, t_end, dt, method="exact")
    assert exact.method == "exact" and exact.n_steps == 0
    ref = mechsim.simulate(model, t_end, dt, method="dop853", tolerance=1e-13)
    scale = max(1.0, float(np.max(np.abs(ref.q))))
    vscale = max(1.0, float(np.max(np.abs(ref.v))))
    assert np.max(np.abs(exact.q - ref.q)) < 1e-9 * scale
    assert np.max(np.abs(exact.v - ref.v)) < 1e-8 * vscale
    escale = max(1e-300, float(np.max(np.abs(ref.total))))
    assert np.max(np.abs(exact.work_dissipated - ref.work_dissipated)) < 1e-9 * escale
    assert np.max(np.abs(exact.work_external - ref.work_external)) < 1e-9 * escale
    assert np.max(np.abs(exact.balance_residual)) < 1e-12 * escale


@pytest.mark.parametrize("system, params", [("driven_oscillator", {}),
                                            ("periodic_drive", {"harmonics": 5}),
                                            ("rigid_body", {}),
                                            ("symmetric_top", {})])
def test_constants_kept_per_anchor_follow_the_anchor(system: str, params: dict) -> None:
    """``propagate`` keeps constants of each anchor (t0, y0) on the model: runs from other
    anchors in between change nothing, and each equals the run of a fresh model."""
    model = mechsim.load_system(system, **params)
    y0 = model.initial_y()
    y1 = y0.copy()
    y1[len(model.coordinates):2 * len(model.coordinates)] += 0.3  # other rates
    t = np.linspace(0.0, 3 * model.time_scale(), 40)
    anchors = [(0.0, y0), (1.5, y0), (0.0, y1), (1.5, y1)]
    first = [model.propagate(t0, y, t0 + t) for t0, y in anchors]
    again = [model.propagate(t0, y, t0 + t) for t0, y in reversed(anchors)][::-1]
    fresh = [mechsim.load_system(system, **params).propagate(t0, y, t0 + t)
             for t0, y in anchors]
    for a, b, c in zip(first, again, fresh, strict=True):
        assert np.array_equal(a, c) and np.array_equal(b, c)
    assert not np.allclose(first[2], first[0])  # the anchors do differ


def test_resumable_in_pieces_and_after_a_parameter_change() -> None:
    model = mechsim.load_system("kepler", eccentricity=0.6)
    t = np.linspace(0.0, 20.0, 201)
    whole = make_stepper(model, "exact").advance(t)
    stepper = make_stepper(model, "exact")
    pieces = np.vstack([stepper.advance(t[:50]), stepper.advance(t[50:120]),
                        stepper.advance(t[120:])])
    assert np.array_equal(whole, pieces)
    # A new gravitational parameter re-anchors at the current state: the orbit continues from
    # where it is, on the new conic (energy relative to the new GM changes accordingly).
    stepper.set_model(model.with_values(gravitational_parameter=2.0))
    after = stepper.advance(np.array([20.0, 21.0]))
    assert np.array_equal(after[0], pieces[-1])
    ref = make_stepper(model.with_values(gravitational_parameter=2.0), "dop853", 1e-13,
                       t0=20.0, y0=pieces[-1].copy()).advance(np.array([21.0]))
    assert np.max(np.abs(after[1] - ref[0])) < 1e-9


def test_auto_uses_closed_form_only_when_allowed() -> None:
    model = mechsim.load_system("harmonic_oscillator")
    assert mechsim.simulate(model, 1.0, 0.1).method == "dop853"
    assert mechsim.simulate(model, 1.0, 0.1, closed_form=True).method == "exact"
    pend = mechsim.load_system("double_pendulum")
    assert mechsim.simulate(pend, 1.0, 0.1, closed_form=True).method == "dop853"
    with pytest.raises(mechsim.ParameterError,
                       match="exact: double_pendulum .* no closed form"):
        mechsim.simulate(pend, 1.0, 0.1, method="exact")
    multiplier = mechsim.load_system("pendulum", formulation="multiplier")
    with pytest.raises(mechsim.ParameterError, match="no closed form"):
        mechsim.simulate(multiplier, 1.0, 0.1, method="exact")
    polar = mechsim.load_system("planar_oscillator", formulation="polar")
    with pytest.raises(mechsim.ParameterError, match="no closed form"):
        mechsim.simulate(polar, 1.0, 0.1, method="exact")
