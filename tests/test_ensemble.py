"""``simulate_many``: every member equals the single run it stands for, bit for bit (rows,
outputs, counters, the method ``auto`` chose), whichever way it ran (the shared compiled call,
its own stepper after an event, one core or all, a Dask cluster of worker processes)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import mechsim
from mechsim.integrators import make_stepper
from mechsim.simulate import evaluate, output_times


def _equal_member(res: Any, i: int, single: Any) -> None:
    m = res.member(i)
    assert m.method == single.method
    for name in ("q", "v", "work_external", "work_dissipated", "kinetic", "potential"):
        assert np.array_equal(getattr(m, name), getattr(single, name), equal_nan=True), name
    for name, v in single.invariants.items():
        assert np.array_equal(m.invariants[name], v, equal_nan=True), name
    for name, v in single.observables.items():
        assert np.array_equal(m.observables[name], v, equal_nan=True), name
    assert (m.n_steps, m.n_evaluations, m.n_rejected) == (
        single.n_steps, single.n_evaluations, single.n_rejected)
    assert m.error_estimate == single.error_estimate
    assert m.events == single.events


@pytest.mark.parametrize("method", ["auto", "dop853", "dopri5", "radau15", "gauss6"])
def test_members_by_parameters_equal_single_runs(method: str) -> None:
    model = mechsim.load_system("pendulum")
    values = [{"initial.angle": a, "length": ell}
              for a, ell in ((0.3, 1.0), (2.9, 1.0), (1.5, 0.5), (0.01, 2.0), (3.1, 1.2))]
    T = 4.0 * model.time_scale()
    res = mechsim.simulate_many(model, T, T / 20, parameters=values, tolerance=1e-9,
                                method=method)
    assert len(res) == 5 and res.q.shape == (5, 21, 1)
    for i, v in enumerate(values):
        _equal_member(res, i, mechsim.simulate(model.with_values(**v), T, T / 20,
                                               tolerance=1e-9, method=method))


def test_hamiltonian_members_publish_rates_not_momenta() -> None:
    """A formulation whose state holds momenta (p = m R² θ̇ for the pendulum): the members'
    ``v`` are the rates q̇, as the Lagrangian form of the same pendulums computes them."""
    values = [{"initial.angle": a, "length": ell, "mass": m}
              for a, ell, m in ((0.3, 1.0, 1.0), (2.5, 0.5, 3.0), (1.0, 2.0, 0.5))]
    hamiltonian = mechsim.load_system("pendulum", formulation="hamiltonian")
    T = 4.0 * hamiltonian.time_scale()
    res = mechsim.simulate_many(hamiltonian, T, T / 20, parameters=values, tolerance=1e-11,
                                method="dop853")
    for i, v in enumerate(values):
        lagrangian = mechsim.simulate(mechsim.load_system("pendulum", **v), T, T / 20,
                                      tolerance=1e-11, method="dop853")
        assert np.max(np.abs(res.q[i] - lagrangian.q)) < 1e-7
        assert np.max(np.abs(res.v[i] - lagrangian.v)) < 1e-7, v


def test_members_by_state_equal_steppers_from_that_state() -> None:
    model = mechsim.load_system("pendulum", formulation="multiplier")
    n_q = len(model.coordinates)
    rng = np.random.default_rng(7)
    states = []
    for angle in rng.uniform(0.1, 3.0, 6):
        y = model.with_values(**{"initial.angle": float(angle)}).initial_y()
        states.append(np.r_[y[:n_q], y[n_q:2 * n_q]])
    t_end = 3.0
    for method in ("dop853", "radau15", "auto"):
        res = mechsim.simulate_many(model, t_end, 0.1, states=states, tolerance=1e-9,
                                    method=method, threads=1)
        t = output_times(t_end, 0.1)
        for i, s in enumerate(states):
            y0 = model.layout.compose(s[:n_q], s[n_q:], modes=model.initial_y()[
                model.layout.modes])
            st = make_stepper(model, method, 1e-9, y0=y0, horizon=t_end)
            Y = st.advance(t)
            assert res.methods[i] == st.method
            assert np.array_equal(res.q[i], Y[:, model.layout.q]), (method, i)
            assert np.array_equal(res.v[i], Y[:, model.layout.v]), (method, i)
            out = evaluate(model, t, Y, st.p)
            assert np.array_equal(res.kinetic[i], out.kinetic)
            assert res.n_evaluations[i] == st.n_evaluations


def test_members_with_events_run_by_their_stepper_and_still_equal() -> None:
    model = mechsim.load_system("collision")
    values = [{"impact_parameter": b} for b in (0.0, 0.1, 0.2, 0.4)]
    res = mechsim.simulate_many(model, 2.0, 0.05, parameters=values, tolerance=1e-9,
                                method="dop853")
    for i, v in enumerate(values):
        single = mechsim.simulate(model.with_values(**v), 2.0, 0.05, tolerance=1e-9,
                                  method="dop853")
        _equal_member(res, i, single)
    assert any(res.events[i] for i in range(3))  # the head-on ones collide


def test_one_core_and_all_cores_give_the_same_members() -> None:
    model = mechsim.load_system("double_pendulum")
    n_q = len(model.coordinates)
    states = np.zeros((9, 2 * n_q))
    states[:, 0] = np.linspace(0.1, 2.0, 9)
    a = mechsim.simulate_many(model, 2.0, 0.1, states=states, tolerance=1e-8, threads=1,
                              outputs=("energy",))
    b = mechsim.simulate_many(model, 2.0, 0.1, states=states, tolerance=1e-8,
                              outputs=("energy",))
    assert np.array_equal(a.q, b.q) and np.array_equal(a.total, b.total)
    assert a.outputs.invariants == {} and a.outputs.frames is None


@pytest.mark.parametrize("kwargs, field, reason", [
    ({}, "parameters", "give parameter values"),
    ({"parameters": {"mass": 1.0}}, "parameters", "sequence of mappings"),
    ({"parameters": [{"mass": -1.0}]}, "mass", ""),
    ({"parameters": [{"formulation": "multiplier"}]}, "parameters", "formulation"),
    ({"states": [[1.0, 0.0, 0.0]]}, "states", "columns"),
    ({"states": [[np.nan, 0.0]]}, "states", "finite"),
    ({"states": [[1.0, 0.0]], "parameters": [{}, {}]}, "states", "1 rows for 2"),
    ({"states": [[1.0, 0.0]], "cluster": 3}, "cluster", "scheduler address"),
    ({"states": [[1.0, 0.0]], "method": "rk4"}, "method", "must be one of"),
])
def test_bad_ensembles_are_refused_naming_the_field(kwargs: dict[str, Any], field: str,
                                                    reason: str) -> None:
    model = mechsim.load_system("pendulum")
    with pytest.raises(mechsim.ParameterError, match=f"^{field}: .*{reason}"):
        mechsim.simulate_many(model, 1.0, 0.1, **kwargs)


def test_a_local_dask_cluster_gives_the_same_members() -> None:
    pytest.importorskip("distributed")
    model = mechsim.load_system("pendulum")
    values = [{"initial.angle": a} for a in np.linspace(0.2, 3.0, 7)]
    here = mechsim.simulate_many(model, 3.0, 0.1, parameters=values, tolerance=1e-10)
    there = mechsim.simulate_many(model, 3.0, 0.1, parameters=values, tolerance=1e-10,
                                  cluster="local", members_per_task=2)
    assert there.methods == here.methods
    for name in ("q", "v", "work_external", "kinetic", "potential", "n_steps",
                 "n_evaluations", "error_estimate"):
        assert np.array_equal(getattr(there, name), getattr(here, name)), name
    for i in range(len(values)):
        assert there.member(i).model.values == here.member(i).model.values
