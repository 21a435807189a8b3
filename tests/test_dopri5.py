"""``dopri5``: Dormand and Prince's 5(4) pair in the shared explicit Runge–Kutta loop.

The tableau in the project is the published method: its order conditions hold, and a plain
numpy step built from it (not mechsim's compiled loop) converges with the published orders
(5 for the solution, 4 for the dense output and the error estimate) on Kepler's problem
against Kepler's equation. The compiled method's steps follow a 5th-order error estimate (the
step count grows like tol^(−1/5)), its end errors follow the tolerance, and it agrees with
independent references (radau15 at 1e-14 and DOP853 at 1e-13) within 100 × the tolerance at
1e-4, 1e-6 and 1e-8 — at output times inside its steps too (dense output), with events
(bounces, collisions) and with constraints (the pendulum with a multiplier)."""

from __future__ import annotations

from collections.abc import Callable
from functools import cache

import numpy as np
import pytest

import mechsim
from mechsim.integrators import StiffnessError, make_stepper
from mechsim.integrators import dopri5_tableau as tab
from test_dop853_tableau import _exact, _f  # Kepler's problem and its closed form

# --- the tableau -----------------------------------------------------------------------------


def test_order_conditions() -> None:
    b = np.append(tab.WEIGHTS, 0.0)
    b_hat = b - tab.ERROR
    c, A = tab.NODES, tab.STAGES
    assert np.allclose(A.sum(axis=1), c, atol=1e-15, rtol=0)
    assert np.array_equal(A[6, :6], tab.WEIGHTS)  # FSAL: stage 7 is f at the new point
    for k in range(1, 6):  # Σ b c^(k−1) = 1/k: order 5; the embedded solution order 4
        assert np.sum(b * c ** (k - 1)) == pytest.approx(1 / k, abs=1e-15)
        if k <= 4:
            assert np.sum(b_hat * c ** (k - 1)) == pytest.approx(1 / k, abs=1e-15)
    assert abs(np.sum(b_hat * c**4) - 1 / 5) > 1e-4  # and not 5: a real error estimate
    # Two conditions that involve A (trees of order 3 and 5).
    assert b @ A @ c == pytest.approx(1 / 6, abs=1e-15)
    assert b @ A @ (A @ (A @ c)) == pytest.approx(1 / 120, abs=1e-15)


def _step(t: float, y: np.ndarray, h: float
          ) -> tuple[np.ndarray, np.ndarray, Callable[[float], np.ndarray]]:
    """One DOPRI5 step from the tableau alone: (y_new, error vector, dense(θ))."""
    K = np.zeros((7, y.size))
    for s in range(7):
        K[s] = _f(t + tab.NODES[s] * h, y + h * (tab.STAGES[s, :s] @ K[:s]))
    y_new = y + h * (tab.WEIGHTS @ K[:6])
    F1 = y_new - y
    F2 = h * K[0] - F1
    F3 = 2 * F1 - h * (K[0] + K[6])
    F4 = h * (tab.DENSE @ K)

    def dense(theta: float) -> np.ndarray:
        return y + theta * (F1 + (1 - theta) * (F2 + theta * (F3 + (1 - theta) * F4)))

    return y_new, h * (tab.ERROR @ K), dense


def test_observed_orders_of_a_plain_step() -> None:
    t0, y0 = 0.3, _exact(0.3)
    sol, dense, est = [], [], []
    for h in (0.1, 0.05):
        y1, e, interp = _step(t0, y0, h)
        sol.append(np.max(np.abs(y1 - _exact(t0 + h))))
        dense.append(np.max(np.abs(interp(0.37) - _exact(t0 + 0.37 * h))))
        est.append(np.max(np.abs(e)))
    order = [float(np.log2(x[0] / x[1])) for x in (sol, dense, est)]
    # Local errors ~h^(p+1): 6 for the solution, 5 for the dense output and the estimate.
    assert 5.5 < order[0] < 6.6, sol
    assert 4.5 < order[1] < 5.6, dense
    assert 4.5 < order[2] < 5.6, est


# --- the compiled method ---------------------------------------------------------------------

def _kepler() -> tuple[mechsim.Model, np.ndarray, np.ndarray]:
    model = mechsim.load_system("kepler")
    t = np.linspace(0.0, 10 * model.time_scale(), 41)[1:]
    exact = model.propagate(0.0, model.initial_y(), t)
    assert exact is not None
    return model, t, exact


def test_steps_follow_a_fifth_order_estimate_and_errors_the_tolerance() -> None:
    model, t, exact = _kepler()
    n = len(model.coordinates)
    steps, errors = [], []
    for tol in (1e-4, 1e-9):
        st = make_stepper(model, "dopri5", tol)
        Y = st.advance(t)
        steps.append(st.n_steps)
        errors.append(float(np.max(np.abs(Y[:, :2 * n] - exact[:, :2 * n]))))
    # Steps grow like tol^(−1/5): 10× over five decades (DOP853's 1/8 would give 4.2×).
    assert 6.0 < steps[1] / steps[0] < 16.0, steps
    # The end error follows the tolerance (tolerance proportionality), within it.
    assert 1e3 < errors[0] / errors[1] < 1e7, errors
    assert errors[0] < 1e-4 and errors[1] < 1e-9, errors


def test_reports_its_cost_and_an_error_estimate() -> None:
    model, t, exact = _kepler()
    run = mechsim.simulate(model, 10.0, 0.5, tolerance=1e-6, method="dopri5")
    assert run.method == "dopri5"
    # Two evaluations to start (f and the first-step probe), six per step tried, FSAL.
    assert run.n_evaluations == 2 + 6 * (run.n_steps + run.n_rejected)
    st = make_stepper(model, "dopri5", 1e-6)
    Y = st.advance(t)
    err = float(np.max(np.abs(Y[:, :2] - exact[:, :2])))
    assert 0.0 < st.error_estimate and err / 100 < st.error_estimate * 1e3 < err * 1e5


# Not the chaotic ones (CR3BP, double pendulum, the asymmetric rigid body), where the motion
# amplifies any method's error past the tolerance: ``auto`` takes radau15 there (as for
# DOP853, a method chosen by name is the caller's choice).
_SYSTEMS = [("kepler", None), ("spring_pendulum", None), ("central_force_3d", "cartesian"),
            ("symmetric_top", None), ("damped_oscillator", None), ("geodesic", None),
            ("pendulum", "multiplier"), ("gas_in_box", None), ("collision", None)]


def _model(sid: str, formulation: str | None) -> mechsim.Model:
    return mechsim.load_system(sid, **({"formulation": formulation} if formulation else {}))


@cache
def _references(sid: str, formulation: str | None
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[float, float]]:
    """201 output times over ten time scales, DOP853 at 1e-13 and radau15 at 1e-14 there, and
    the state scales (largest |q|, |q̇|)."""
    model = _model(sid, formulation)
    n = len(model.coordinates)
    t = np.linspace(0.0, 10 * model.time_scale(), 202)[1:]
    a = make_stepper(model, "dop853", 1e-13).advance(t)
    b = make_stepper(model, "radau15", 1e-14).advance(t)
    return t, a, b, (max(float(np.max(np.abs(b[:, :n]))), 1e-300),
                     max(float(np.max(np.abs(b[:, n:2 * n]))), 1e-300))


@pytest.mark.parametrize("work_terms", [True, False], ids=["with_work", "state_only"])
@pytest.mark.parametrize(("sid", "formulation"), _SYSTEMS)
def test_meets_the_tolerance_at_every_output(sid: str, formulation: str | None,
                                             work_terms: bool) -> None:
    """Every one of 200 outputs (from the dense output: the steps never land on output
    times) within 100 × the tolerance of both references, relative to the state scale, at
    1e-4, 1e-6, 1e-8; events at the references' times. Also with the work terms left out."""
    model = _model(sid, formulation)
    n = len(model.coordinates)
    t, a, b, scales = _references(sid, formulation)
    ref_events = make_stepper(model, "dop853", 1e-13)
    ref_events.advance(t)
    failures = []
    for tol in (1e-4, 1e-6, 1e-8):
        st = make_stepper(model, "dopri5", tol, work_terms=work_terms)
        assert st.method == "dopri5"
        Y = st.advance(t)
        for name, ref in (("dop853", a), ("radau15", b)):
            err = max(float(np.max(np.abs(Y[:, :n] - ref[:, :n]))) / scales[0],
                      float(np.max(np.abs(Y[:, n:2 * n] - ref[:, n:2 * n]))) / scales[1])
            if err > 100 * tol:
                failures.append(f"{tol:g} vs {name}: {err:.2g} ({err / tol:.2g} × tol)")
        if model.events:  # those up to the last output (the last step may go on past it)
            mine, ref_ev = ([e for e in x.events if e[0] <= t[-1]]
                            for x in (st, ref_events))
            assert [e[1] for e in mine] == [e[1] for e in ref_ev]
            dt = np.abs(np.array([e[0] for e in mine]) - np.array([e[0] for e in ref_ev]))
            assert np.all(dt <= 100 * tol * t[-1]), (tol, dt.max())
    assert not failures, failures


def test_constraints_stay_at_round_off() -> None:
    model = _model("pendulum", "multiplier")
    st = make_stepper(model, "dopri5", 1e-4)
    Y = st.advance(np.linspace(0.0, 10 * model.time_scale(), 101)[1:])
    r = np.hypot(Y[:, 0], Y[:, 1])
    assert np.max(np.abs(r - r[0])) < 1e-12 * r[0]


def test_takes_inputs_and_restarts() -> None:
    """``restart`` (inputs held over an output interval): going on from a returned state
    gives the same run as without it, within the tolerance."""
    model, t, exact = _kepler()
    st = make_stepper(model, "dopri5", 1e-8)
    Y1 = st.advance(t[:20])
    st.restart(float(t[19]), Y1[-1], model.parameter_vector())
    Y2 = st.advance(t[20:])
    assert np.max(np.abs(Y2[:, :2] - exact[20:, :2])) < 1e-7


def test_stiff_damping_stops_with_reason() -> None:
    model = mechsim.load_system("damped_oscillator", damping=1e6)
    st = make_stepper(model, "dopri5")
    with pytest.raises(StiffnessError) as e:
        st.advance(np.arange(1, 1001) * 0.01)
    assert "dopri5" in str(e.value) and "3.25" in str(e.value)
    assert st.n_steps < 5000


def test_auto_never_chooses_it() -> None:
    for sid in ("kepler", "damped_oscillator", "cr3bp"):
        for tol in (1e-4, 1e-8):
            assert make_stepper(mechsim.load_system(sid), "auto", tol).method != "dopri5"
