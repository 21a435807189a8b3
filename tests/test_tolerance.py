"""The tolerance means what it says: for every system and formulation, ``auto`` at tolerances
1e-6 … 1e-12 ends a run of ten time scales within 100 × the tolerance of a reference computed
by a different method at 1e-14 (errors relative to the state scale: the largest |q| and the
largest |q̇| along the run, for coordinates and rates). Where the two 1e-14 references
themselves disagree (round-off amplified by chaotic motion) the test cannot judge below that
disagreement, and allows it. Also: the result reports what the run cost and its error
estimate, and the fixed-step methods size their steps from the tolerance."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

import mechsim
from mechsim.integrators import make_stepper
from mechsim.systems import system_class, system_ids

TOLERANCES = (1e-6, 1e-8, 1e-10, 1e-12)
HORIZON = 10.0  # time scales


def _variants() -> list[tuple[str, str]]:
    return [(sid, f) for sid in system_ids() for f in system_class(sid).formulations]


def _model(sid: str, formulation: str) -> mechsim.Model:
    cls = system_class(sid)
    return cls(formulation=formulation) if len(cls.formulations) > 1 else cls()


@cache
def _references(sid: str, formulation: str) -> tuple[np.ndarray, dict[str, np.ndarray],
                                                       tuple[float, float], float]:
    """Output times, the two references (DOP853 and radau15 at 1e-14), the state scales and
    how far the references are apart (relative)."""
    model = _model(sid, formulation)
    n = len(model.coordinates)
    T = HORIZON * model.time_scale()
    t = np.linspace(0.0, T, 11)[1:]
    refs = {"dop853": make_stepper(model, "dop853", 1e-14).advance(t),
            "radau15": _radau15(model, t)}
    fine = _radau15(model, np.linspace(0.0, T, 201)[1:])
    scales = (max(float(np.max(np.abs(fine[:, :n]))), 1e-300),
              max(float(np.max(np.abs(fine[:, n:2 * n]))), 1e-300))
    return t, refs, scales, _relative(refs["dop853"], refs["radau15"], n, scales)


def _radau15(model: mechsim.Model, t: np.ndarray) -> np.ndarray:
    """radau15 at 1e-14; for a state of momenta (``formulation: hamiltonian``, which radau15
    does not take) the Lagrangian formulation it comes from, its (q, q̇) mapped to (q, p)."""
    if model.structure.second_order:
        return make_stepper(model, "radau15", 1e-14).advance(t)
    lagrangian = _model(model.id, model.formulation)
    Y = make_stepper(lagrangian, "radau15", 1e-14).advance(t)
    Z, p = np.empty_like(Y), model.parameter_vector()
    for k in range(len(t)):
        model.kernels.to_momenta(float(t[k]), Y[k], p, Z[k])
    return Z


def _relative(Y: np.ndarray, R: np.ndarray, n: int, scales: tuple[float, float]) -> float:
    return max(float(np.max(np.abs(Y[:, :n] - R[:, :n]))) / scales[0],
               float(np.max(np.abs(Y[:, n:2 * n] - R[:, n:2 * n]))) / scales[1])


@pytest.mark.parametrize("work_terms", [True, False], ids=["with_work", "state_only"])
@pytest.mark.parametrize(("sid", "formulation"), _variants())
def test_auto_meets_the_tolerance(sid: str, formulation: str, work_terms: bool) -> None:
    """Also for a caller that reads the state only (``work_terms=False``: the explicit pairs'
    step control then judges q and q̇ alone)."""
    model = _model(sid, formulation)
    n = len(model.coordinates)
    t, refs, scales, disagreement = _references(sid, formulation)
    failures = []
    for tol in TOLERANCES:
        st = make_stepper(model, "auto", tol, horizon=t[-1], work_terms=work_terms)
        Y = st.advance(t)
        ref = refs["radau15" if st.method != "radau15" else "dop853"]
        err = _relative(Y, ref, n, scales)
        if err > 100 * tol + 10 * disagreement:
            failures.append(f"{st.method} at {tol:g}: {err:.2g} ({err / tol:.2g} × tol; "
                            f"references {disagreement:.1g} apart)")
    assert not failures, failures


def test_result_reports_the_cost_and_an_error_estimate() -> None:
    model = mechsim.load_system("kepler")
    run = mechsim.simulate(model, 10.0, 0.5, tolerance=1e-8)
    assert run.method == "dop853"
    assert run.n_steps > 0 and run.n_evaluations >= 12 * run.n_steps
    assert run.n_rejected >= 0
    exact = model.propagate(0.0, model.initial_y(), run.t)
    assert exact is not None
    err = np.max(np.abs(run.q - exact[:, :2]))
    # The estimate sums the local errors: the same order as the real error, here both tiny.
    assert 0.0 < run.error_estimate < 1e-8 and err < 1e-8


@pytest.mark.parametrize(("sid", "method"), [("kepler", "yoshida8"),
                                             ("spring_pendulum", "gauss6")])
def test_fixed_step_methods_size_their_steps_from_the_tolerance(sid: str, method: str) -> None:
    """Ten time scales at 1e-6 and 1e-10: each ends within the tolerance of the reference
    (relative to the state scale), and the tighter tolerance takes smaller steps."""
    model = mechsim.load_system(sid)
    n = len(model.coordinates)
    t, refs, scales, _ = _references(sid, model.formulation)
    steps = []
    for tol in (1e-6, 1e-10):
        st = make_stepper(model, method, tol)
        err = _relative(st.advance(t), refs["radau15"], n, scales)
        assert err < 10 * tol, (tol, err)
        steps.append(st.n_steps)
    assert steps[1] > 2 * steps[0]


@pytest.mark.parametrize(("system", "params", "kwargs", "expected"), [
    ("pendulum", {}, {}, "dop853"),
    ("pendulum", {}, {"tolerance": 1e-12}, "radau15"),  # DOP853 would need round-off
    ("kepler", {}, {"horizon": 1000.0}, "radau15"),  # errors pile up over long runs
    ("kepler", {}, {"closed_form": True}, "exact"),
    ("sphere_slide", {}, {}, "dop853"),  # events
    ("double_pendulum", {}, {}, "radau15"),  # chaotic: the probe sees DOP853's error explode
])
def test_auto_choice(system: str, params: dict, kwargs: dict, expected: str) -> None:
    assert make_stepper(mechsim.load_system(system, **params), "auto", **kwargs).method \
        == expected
