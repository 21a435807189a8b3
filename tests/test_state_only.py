"""A caller that reads the state only (``make_stepper(..., work_terms=False)``,
``simulate(..., work_terms=False)``): the explicit pairs leave the work terms out of their
arithmetic and step control, and say so with NaN work columns, never a value that was not
computed. The tolerance holds as with them (``test_tolerance.py``, ``test_dopri5.py``)."""

from __future__ import annotations

import numpy as np
import pytest

import mechsim
from mechsim.integrators import make_stepper


@pytest.mark.parametrize("method", ["dop853", "dopri5"])
def test_the_work_terms_leave_the_step_control_and_the_outputs(method: str) -> None:
    """The benchmark's CR3BP orbit (about both primaries from r = 1.8): the primaries work on
    the particle (W_ext ≠ 0), and the work term's error estimate, not the state's, rejects
    steps (at 1e-4, 20 of DOP853's 34 rejections). Without it the controller
    rejects fewer; the state stays within the tolerance of the full run's."""
    model = mechsim.load_system("cr3bp", **{"initial.x": 1.8, "initial_rate.y": 0.7453559925})
    n = len(model.coordinates)
    t = np.linspace(0.0, 40 * np.pi, 201)
    full = make_stepper(model, method, 1e-4)
    Y = full.advance(t)
    assert np.all(np.isfinite(Y)) and np.abs(Y[:, 2 * n]).max() > 1e-3
    lean = make_stepper(model, method, 1e-4, work_terms=False)
    Z = lean.advance(t)
    assert np.all(np.isnan(Z[:, 2 * n:2 * n + 2]))
    assert lean.n_rejected < full.n_rejected
    scale = np.abs(Y[:, :2 * n]).max()
    assert np.abs(Z[:, :2 * n] - Y[:, :2 * n]).max() < 100 * 1e-4 * scale


def test_events_and_modes_go_on_without_the_work_terms() -> None:
    """gas_in_box: wall events whose handlers change the velocities; sphere_slide: a mode
    (the contact) switched by an event. The same events, at the same times within the
    tolerance, as with the work terms."""
    for sid, params in (("gas_in_box", {}), ("sphere_slide", {"initial.angle": 0.3})):
        model = mechsim.load_system(sid, **params)
        t = np.linspace(0.0, 5 * model.time_scale(), 51)
        runs = [make_stepper(model, "dop853", 1e-9, work_terms=w) for w in (True, False)]
        Y, Z = (st.advance(t) for st in runs)
        names = [[e[1] for e in st.events] for st in runs]
        assert names[0] == names[1] and names[0], sid
        times = [np.array([e[0] for e in st.events]) for st in runs]
        assert np.abs(times[0] - times[1]).max() < 1e-6 * t[-1], sid
        m = model.layout
        np.testing.assert_allclose(Z[:, m.modes], Y[:, m.modes], rtol=1e-6, atol=1e-6)


def test_simulate_reads_the_state_only_when_asked() -> None:
    model = mechsim.load_system("damped_oscillator")
    run = mechsim.simulate(model, 5.0, 0.5, method="radau15", work_terms=False)
    assert np.all(np.isnan(run.work_dissipated)) and np.all(np.isnan(run.work_external))
    both = mechsim.simulate(model, 5.0, 0.5, method="radau15")
    np.testing.assert_array_equal(run.q, both.q)  # radau15 integrates them either way
    assert both.work_dissipated[-1] > 0.0
