"""Gauss–Legendre (order 6) on Hamilton's equations generated from the Lagrangian: order of
convergence, bounded energy error where DOP853 drifts, step halving when the stage iteration
does not converge, and where it does not apply."""

from __future__ import annotations

import numpy as np
import pytest

import mechsim
from mechsim.integrators import make_stepper


def test_sixth_order_convergence() -> None:
    model = mechsim.load_system("double_pendulum")
    t = np.array([2.0])
    ref = make_stepper(model, "dop853", 1e-14).advance(t)[0]
    errs = []
    for h in (0.02, 0.01):
        y = make_stepper(model, "gauss6", step=h).advance(t)[0]
        errs.append(np.max(np.abs(y[:4] - ref[:4])))
    order = np.log2(errs[0] / errs[1])
    assert 5.5 < order < 6.8, (errs, order)


def test_energy_bounded_where_dop853_drifts() -> None:
    model = mechsim.load_system("spring_pendulum")
    T = model.time_scale()
    g = mechsim.simulate(model, 2000 * T, T / 3, method="gauss6", outputs=("energy",))
    d = mechsim.simulate(model, 2000 * T, T / 3, method="dop853", outputs=("energy",))

    def drift(run: mechsim.SimulationResult) -> np.ndarray:
        E = run.total
        return np.abs(E - E[0]) / abs(E[0])

    dg, dd = drift(g), drift(d)
    n = len(dg) // 10
    assert dg.max() < 1e-12
    # No secular growth: above the round-off random walk (~1e-14), the error does not grow.
    assert dg[-n:].max() < max(3 * dg[:n].max(), 1e-13)
    assert dd[-n:].max() > 3 * dd[:n].max()  # DOP853's error grows with time
    assert g.work_external.max() == 0.0 and g.work_dissipated.max() == 0.0


def test_step_halving_when_stage_iteration_fails() -> None:
    """A step far too long for the fixed-point iteration (h ω ≫ 1) is subdivided until the
    stage equations converge, instead of returning garbage or stopping."""
    model = mechsim.load_system("double_pendulum")
    t = np.linspace(0.0, 3.0, 4)
    coarse = make_stepper(model, "gauss6", step=1.0)
    y = coarse.advance(t)
    assert coarse.n_steps > 3  # it had to subdivide
    assert np.all(np.isfinite(y))
    e = np.zeros(3)
    energies = []
    for row in y:
        model.kernels.energy(0.0, row, coarse.p, e)
        energies.append(e[0] + e[1])
    # Convergence, not accuracy, drives the subdivision: a long step is still a long step.
    assert np.max(np.abs(np.array(energies) - energies[0])) < 0.1 * abs(energies[0])


def test_refused_where_not_applicable() -> None:
    with pytest.raises(mechsim.ParameterError, match="gauss6 needs a conservative"):
        mechsim.simulate(mechsim.load_system("driven_oscillator"), 1.0, 0.1, method="gauss6")


@pytest.mark.parametrize("method", ["gauss6", "yoshida8"])
def test_step_sizing_follows_a_new_model(method: str) -> None:
    """The fixed-step methods keep the model's time scale between their step estimates; a
    new model (new parameter values) is asked again, so the step follows it."""
    short = mechsim.load_system("pendulum", length=0.25)
    stepper = make_stepper(mechsim.load_system("pendulum"), method, 1e-8)
    stepper.advance(np.array([0.5]))
    assert stepper.time_scale() == mechsim.load_system("pendulum").time_scale()
    stepper.set_model(short)
    assert stepper.time_scale() == short.time_scale() != mechsim.load_system(
        "pendulum").time_scale()
