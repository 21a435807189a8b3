"""``simulate`` runs a model without events in one compiled call (``integrators.runs``), and
a closed form in one evaluation: its rows, outputs and counters equal those of the stepper
``make_stepper`` makes, advanced and evaluated from Python, bit for bit, for every system and
every method the call covers."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import mechsim
from mechsim.errors import ParameterError
from mechsim.integrators import StiffnessError, make_stepper
from mechsim.integrators.runs import plan_run
from mechsim.integrators.state import Status
from mechsim.simulate import OUTPUTS, evaluate, output_times, simulate
from mechsim.systems import system_ids

METHODS = ("dop853", "dopri5", "radau15", "auto")


def _by_stepper(model: Any, method: str, tolerance: float, t_end: float, output_dt: float,
                work_terms: bool = True) -> tuple[np.ndarray, Any, Any]:
    t = output_times(t_end, output_dt)
    st = make_stepper(model, method, tolerance, horizon=t_end, work_terms=work_terms)
    Y = st.advance(t)
    return Y, evaluate(model, t, Y, st.p, OUTPUTS), st


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(np.array_equal(a, b, equal_nan=True))


@pytest.mark.parametrize("system", system_ids())
def test_one_call_equals_the_stepper_bit_for_bit(system: str) -> None:
    model = mechsim.load_system(system)
    tau = model.time_scale()
    for method in METHODS + (("exact",) if model.has_closed_form() else ()):
        if method == "dopri5" and model.events:
            continue
        res = simulate(model, 2.0 * tau, 0.1 * tau, tolerance=1e-8, method=method)
        Y, out, st = _by_stepper(model, method, 1e-8, 2.0 * tau, 0.1 * tau)
        at = model.layout
        assert _same(res.q, Y[:, at.q]) and _same(res.v, Y[:, at.v]), (system, method)
        assert _same(res.work_external, Y[:, at.work_external]), (system, method)
        assert res.method == st.method and res.n_steps == st.n_steps
        assert res.n_evaluations == st.n_evaluations
        assert res.error_estimate == st.error_estimate
        assert _same(res.kinetic, out.kinetic) and _same(res.potential, out.potential)
        for name, v in out.invariants.items():
            assert _same(res.invariants[name], v), (system, method, name)
        for name, v in out.observables.items():
            assert _same(res.observables[name], v), (system, method, name)
        if out.frames is not None:
            assert _same(res.outputs.frames, out.frames)


def test_without_work_terms_and_with_fewer_outputs() -> None:
    model = mechsim.load_system("double_pendulum")
    res = simulate(model, 3.0, 0.05, tolerance=1e-9, method="dop853", work_terms=False,
                   outputs=("energy",))
    Y, out, _ = _by_stepper(model, "dop853", 1e-9, 3.0, 0.05, work_terms=False)
    assert _same(res.q, Y[:, model.layout.q]) and np.isnan(res.work_external).all()
    assert _same(res.kinetic, out.kinetic) and res.invariants == {}


_FIELDS = {"electric_field.x": 0.3, "electric_field.y": -0.2, "electric_field.z": 0.1}


@pytest.mark.parametrize("system, values", [
    ("charged_particle", {"formulation": "symmetric", **_FIELDS}),
    ("charged_particle", {"formulation": "landau", **_FIELDS}),
    ("rigid_body", {}), ("pendulum", {}), ("pendulum", {"initial_rate.angle": 9.0})])
@pytest.mark.parametrize("work_terms", [True, False])
def test_a_compiled_closed_form_equals_its_stepper_bit_for_bit(
        system: str, values: dict[str, Any], work_terms: bool) -> None:
    """A closed form compiled (``Model.closed_form_kernel``: the charged particle's Cartesian
    formulations, the free rigid body off its principal axes, the pendulum's reduced form,
    librating and rotating) runs in one compiled call:
    rows, outputs and counters as the ``exact`` stepper's, which calls ``propagate``."""
    model = mechsim.load_system(system, **values)
    assert model.closed_form_kernel(model.initial_y()) is not None
    tau = model.time_scale()
    res = simulate(model, 3.0 * tau, 0.05 * tau, method="exact", work_terms=work_terms)
    Y, out, st = _by_stepper(model, "exact", 1e-10, 3.0 * tau, 0.05 * tau, work_terms)
    if not work_terms:
        Y[:, [model.layout.work_external, model.layout.work_dissipated]] = np.nan
    assert _same(res.q, Y[:, model.layout.q]) and _same(res.v, Y[:, model.layout.v])
    assert _same(res.work_external, Y[:, model.layout.work_external])
    assert (res.n_steps, res.n_evaluations) == (st.n_steps, st.n_evaluations) == (0, 1)
    assert _same(res.kinetic, out.kinetic) and _same(res.potential, out.potential)
    for name, v in out.observables.items():
        assert _same(res.observables[name], v), name
    assert out.frames is not None and _same(res.outputs.frames, out.frames)


@pytest.mark.parametrize("system", ["driven_oscillator", "periodic_drive", "charged_particle"])
def test_a_closed_form_without_work_terms_has_the_same_motion(system: str) -> None:
    """Without the work terms a closed form may skip them (the driven oscillators' ∫ b ẋ²):
    the motion is the one with them, bit for bit, and the work terms are NaN."""
    model = mechsim.load_system(system)
    tau = model.time_scale()
    full = simulate(model, 3.0 * tau, 0.05 * tau, method="exact", outputs=())
    bare = simulate(model, 3.0 * tau, 0.05 * tau, method="exact", outputs=(),
                    work_terms=False)
    assert _same(bare.q, full.q) and _same(bare.v, full.v)
    assert np.isfinite(full.work_dissipated).all()
    assert np.isnan(bare.work_external).all() and np.isnan(bare.work_dissipated).all()


def test_autos_ladder_keeps_the_cost_monotone_where_the_probe_judges_a_decade_harder() -> None:
    """On the double pendulum from θ = (2, 2.5) over 5 s, the probe judges DOP853 at 1e-3 to
    miss its tolerance but DOP853 at 1e-4 to meet it: ``auto`` at 1e-3 takes DOP853 at the
    tighter tolerance rather than radau15 at its finest, so no looser tolerance costs more."""
    model = mechsim.load_system("double_pendulum")  # (θ₁, θ₂) = (2, 2.5) from rest
    costs = []
    for tol in (1e-8, 1e-7, 1e-6, 1e-5, 1e-4, 1e-3):
        run = simulate(model, 5.0, 0.025, tolerance=tol, method="auto", outputs=())
        costs.append((tol, run.method, run.n_evaluations))
    assert all(b[2] <= a[2] for a, b in zip(costs, costs[1:], strict=False)), costs
    assert all(method == "dop853" for _, method, _ in costs), costs


def test_bad_settings_are_refused_as_before() -> None:
    model = mechsim.load_system("pendulum")
    with pytest.raises(mechsim.ParameterError, match="^tolerance"):
        simulate(model, 1.0, tolerance=2.0, method="dop853")
    with pytest.raises(mechsim.ParameterError, match="^method"):
        simulate(model, 1.0, method="rk4")


def test_a_run_the_loop_stops_short_of_is_left_to_the_stepper() -> None:
    """A stiff phase stops the compiled loop with that status (a ``Status`` value, as an int);
    ``simulate`` then runs the stepper, which raises what the solver contract says."""
    model = mechsim.load_system("damped_oscillator", damping=1e6)
    plan = plan_run(model, "dop853", 1e-10, OUTPUTS, horizon=10.0)
    assert plan is not None
    t = output_times(10.0, 0.01)
    run = plan.prepare(model, model.initial_y(), model.parameter_vector(), t, None,
                       entry=True)
    status, buf = run.run()
    assert status == Status.STIFF and run.layout.counters(buf)[0] < t.size
    with pytest.raises(StiffnessError, match="^damped_oscillator: dop853 stopped"):
        simulate(model, 10.0, 0.01, tolerance=1e-10, method="dop853")


def test_a_repeated_call_is_set_up_once_and_returns_arrays_of_its_own() -> None:
    """``simulate`` keeps what a call works out before it runs (settings, output times, plan)
    per model and arguments: a repeated call gives what a model fresh from ``load_system``
    gives, in arrays of its own (writing the first result's changes nothing); a call that
    differs in any argument gets its own set-up; an argument that cannot be a key (an
    array) is worked out afresh."""
    def load() -> Any:
        return mechsim.load_system("pendulum", tolerance=1e-9, publish_rate=20.0)

    def same_run(a: Any, b: Any) -> bool:
        return (_same(a.t, b.t) and _same(a.q, b.q) and _same(a.v, b.v)
                and _same(a.work_external, b.work_external) and a.method == b.method
                and (a.n_steps, a.n_evaluations, a.tolerance) == (b.n_steps, b.n_evaluations,
                                                                  b.tolerance))

    model = load()
    first = simulate(model, 1.0)
    first.t[:] = -1.0
    first.q[:] = -1.0
    again = simulate(model, 1.0)
    assert same_run(again, simulate(load(), 1.0)) and again.t.flags.writeable
    for change in ({"t_end": 1.5}, {"output_dt": 0.1}, {"tolerance": 1e-6},
                   {"method": "radau15"}, {"publish_rate": 5.0}, {"outputs": ("energy",)},
                   {"work_terms": False}, {"step": 0.01, "method": "yoshida6"},
                   {"closed_form": True, "method": "auto"}):
        given = {"t_end": 1.0, **change}
        assert same_run(simulate(model, **given), simulate(load(), **given)), change
    assert same_run(simulate(model, 1.0, np.array(0.05)), simulate(load(), 1.0, 0.05))
    # outputs as a list, first call on a model (nothing kept for it yet) and again
    fresh = load()
    for _ in range(2):
        listed = simulate(fresh, 1.0, outputs=["energy"])
        assert same_run(listed, simulate(load(), 1.0, outputs=("energy",)))
        assert _same(listed.total, simulate(load(), 1.0, outputs=("energy",)).total)
    for wrong in (None, "energy", 5):  # refused with the field named, not a TypeError
        with pytest.raises(ParameterError, match="outputs: a tuple of output names"):
            simulate(fresh, 1.0, outputs=wrong)  # type: ignore[arg-type]


def test_what_is_kept_for_a_model_goes_with_it() -> None:
    """The set-ups and plans kept per model are dropped when the model is, so a model made
    later (maybe at the same address) never finds another's."""
    import gc

    from mechsim.integrators import runs
    from mechsim.simulate import _SET_UPS

    model = mechsim.load_system("pendulum")
    simulate(model, 0.5)
    key = id(model)
    assert key in _SET_UPS._kept and key in runs._PLANS._kept
    del model
    gc.collect()
    assert key not in _SET_UPS._kept and key not in runs._PLANS._kept


def test_the_whole_run_loops_are_called_with_the_types_set_up_compiles() -> None:
    from mechsim.integrators.compiled import run_signatures

    model = mechsim.load_system("pendulum")
    for method in ("dop853", "radau15"):
        simulate(model, 1.0, 0.1, method=method)
        mechsim.simulate_many(model, 1.0, 0.1, states=[[1.0, 0.0], [0.5, 0.0]], method=method)
    simulate(mechsim.load_system("charged_particle", formulation="symmetric"), 1.0, 0.1,
             method="exact")  # a compiled closed form
    for loop, types in run_signatures().items():
        assert [tuple(s) for s in loop.overloads] == [types], loop.__name__


@pytest.mark.parametrize("system, values", [("kepler", {"eccentricity": 0.9}),
                                            ("double_pendulum", {}), ("pendulum", {})])
def test_autos_choice_never_costs_more_at_a_looser_tolerance(system: str,
                                                             values: dict[str, Any]) -> None:
    """``auto``'s choice over the decades of tolerance: a looser tolerance never gets a run
    with more evaluations (no cliff; radau15 at its finest
    ε for every tolerance within a percent), and each run meets
    its tolerance against a run at 1e-13 over the same horizon."""
    model = mechsim.load_system(system, **values)
    T = 10.0 * model.time_scale()
    ref = simulate(model, T, T / 10, tolerance=1e-13, method="radau15", outputs=())
    scale = max(float(np.max(np.abs(ref.q))), float(np.max(np.abs(ref.v))))
    costs = []
    for tol in (1e-10, 1e-9, 1e-8, 1e-7, 1e-6, 1e-5, 1e-4):
        run = simulate(model, T, T / 10, tolerance=tol, method="auto", outputs=())
        costs.append((tol, run.method, run.n_evaluations))
        err = max(float(np.max(np.abs(run.q[-1] - ref.q[-1]))),
                  float(np.max(np.abs(run.v[-1] - ref.v[-1])))) / scale
        assert err <= tol or system == "double_pendulum", (tol, run.method, err)
    # (radau15 at its finest ε takes the tolerance only for its first step and its dense
    # outputs: its count moves by a few evaluations in ten thousand)
    assert all(b[2] <= 1.01 * a[2] for a, b in zip(costs, costs[1:], strict=False)), costs


def test_a_results_arrays_are_those_of_the_run_whatever_is_written_into_another() -> None:
    """A result makes its arrays from its run's buffer when first read: writing into one
    (q) changes none read after it, the rates of a Hamiltonian formulation included (the
    double pendulum's q̇ = M(q)⁻¹ p, made from the rows as run)."""
    for model in (mechsim.load_system("pendulum"),
                  mechsim.load_system("double_pendulum", formulation="hamiltonian")):
        untouched = simulate(model, 1.0, 0.1, method="dop853")
        written = simulate(model, 1.0, 0.1, method="dop853")
        written.q[:] = 0.0
        assert _same(written.v, untouched.v) and _same(written.kinetic, untouched.kinetic)
        assert _same(written.t, untouched.t) and not _same(written.q, untouched.q)
