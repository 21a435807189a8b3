"""Event machinery of the DOP853 stepper: location on the dense output, handlers, restarts,
mode entries, bookkeeping on SimulationResult, Zeno detection; for Lagrangian and direct models.

Oracle: a ball dropped from rest at height h bouncing with restitution e under gravity g hits
the floor at t₁ = √(2h/g) and then after each flight of 2 eᵏ v₁ / g (v₁ = g t₁); its apexes lie
half a flight after each impact. These follow from constant acceleration alone.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import mechsim
from mechsim.errors import IntegrationError, ParameterError
from mechsim.integrators import loop_signatures, make_stepper
from mechsim.params import nonnegative, number, positive
from mechsim.systems.base import Event, Quantity, Structure
from mechsim.systems.direct import DirectModel
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

PARAMS = (
    positive("mass", 1.0, "kg", "ball mass"),
    positive("gravity", 9.81, "m/s^2", "g"),
    nonnegative("restitution", 1.0, "", "coefficient of restitution e"),
    number("initial.z", 1.0, "m", "drop height"),
    number("initial_rate.z", 0.0, "m/s", "initial vertical velocity"),
)


class LagrangianBall(LagrangianModel):
    id = "test_lagrangian_ball"
    title = "bouncing ball (test)"
    source = "test"
    parameters = PARAMS

    def declare(self, b: LagrangianBuilder) -> None:
        z, dz = b.coordinate("z", "m")
        m, g = b.param("mass"), b.param("gravity")
        b.kinetic = m * dz**2 / 2
        b.potential = m * g * z
        b.event("impact", z, direction=-1)
        b.event("apex", dz, direction=-1)  # recorded only: the handler leaves y unchanged
        b.frame("ball", "world", (0, 0, z))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array([self.value("initial.z")]), np.array([self.value("initial_rate.z")])

    def on_impact(self, t: float, y: np.ndarray) -> np.ndarray:
        y[1] = -self.value("restitution") * y[1]
        y[0] = 0.0
        return y

    def on_apex(self, t: float, y: np.ndarray) -> np.ndarray:
        return y


def rhs(t, y, p, dy):  # noqa: ANN001, ANN202 - numba kernel
    dy[0] = y[1]
    dy[1] = -p[P_GRAVITY]  # noqa: F821
    dy[2] = 0.0
    dy[3] = 0.0


def energy(t, y, p, out):  # noqa: ANN001, ANN202
    out[0] = 0.5 * p[P_MASS] * y[1] ** 2  # noqa: F821
    out[1] = p[P_MASS] * p[P_GRAVITY] * y[0]  # noqa: F821
    out[2] = out[0] + out[1]


def event(t, y, p, out):  # noqa: ANN001, ANN202
    out[0] = y[0]


class DirectBall(DirectModel):
    id = "test_direct_ball"
    title = "bouncing ball, hand-written kernels (test)"
    source = "test"
    parameters = PARAMS
    kernel_functions = (rhs, energy, event)

    @property
    def coordinates(self) -> tuple[Quantity, ...]:
        return (Quantity("z", "m"),)

    @property
    def structure(self) -> Structure:
        return Structure(separable=False)

    @property
    def events(self) -> tuple[Event, ...]:
        return (Event("impact", -1),)

    @property
    def modes(self) -> tuple[Quantity, ...]:
        return (Quantity("bounces"),)

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array([self.value("initial.z")]), np.array([self.value("initial_rate.z")])

    def on_impact(self, t: float, y: np.ndarray) -> np.ndarray:
        y[1] = -self.value("restitution") * y[1]
        y[4] += 1.0  # count bounces in the mode entry
        return y


def impact_times(h: float, g: float, e: float, count: int) -> np.ndarray:
    t1 = math.sqrt(2 * h / g)
    v1 = g * t1
    flights = [2 * e**k * v1 / g for k in range(1, count)]
    return t1 + np.concatenate([[0.0], np.cumsum(flights)])


@pytest.mark.parametrize("e", [1.0, 0.8])
def test_lagrangian_ball_impact_and_apex_times(e: float) -> None:
    m = LagrangianBall(restitution=e)
    r = mechsim.simulate(m, 4.0, 0.01, tolerance=1e-12)
    assert r.t.size == 401 and np.all(np.isfinite(r.q))
    hits = r.event_times("impact")
    expected = impact_times(1.0, 9.81, e, hits.size)
    assert hits.size == expected[expected <= 4.0].size >= 3
    np.testing.assert_allclose(hits, expected, rtol=1e-12, atol=0)
    apex = r.event_times("apex")
    flights = np.diff(expected)
    np.testing.assert_allclose(apex[: flights.size], expected[:-1] + flights / 2, rtol=1e-11)
    # Each event once, in time order; the ball never goes (visibly) below the floor.
    times = [t for t, _ in r.events]
    assert times == sorted(times) and len(set(times)) == len(times)
    assert r.q.min() > -1e-9
    if e == 1.0:
        assert np.max(np.abs(r.total - r.total[0])) < 1e-9 * r.total[0]


def test_direct_ball_counts_bounces_in_a_mode_entry() -> None:
    m = DirectBall()
    r = mechsim.simulate(m, 3.0, 0.05, tolerance=1e-12)
    hits = r.event_times()
    np.testing.assert_allclose(hits, impact_times(1.0, 9.81, 1.0, hits.size), rtol=1e-12)
    # The mode entry holds the number of bounces so far at each sample.
    counted = np.searchsorted(hits, r.t, side="left")
    np.testing.assert_array_equal(r.mode("bounces"), counted)
    assert r.modes is not None and r.modes.shape == (r.t.size, 1)


def test_advance_output_by_output_matches_one_call() -> None:
    m = LagrangianBall(restitution=0.9)
    t = np.linspace(0.0, 2.5, 251)
    one = make_stepper(m, "dop853", 1e-12)
    Y1 = one.advance(t)
    many = make_stepper(m, "dop853", 1e-12)
    Y2 = np.vstack([many.advance(t[i:i + 1]) for i in range(t.size)])
    assert Y1.shape == Y2.shape == (251, 4)
    np.testing.assert_allclose(Y1, Y2, atol=1e-9)
    assert [n for _, n in one.events] == [n for _, n in many.events]


def test_zeno_accumulation_is_an_error_not_a_hang() -> None:
    m = LagrangianBall(restitution=0.5)  # impacts accumulate at 3 √(2h/g) ≈ 1.355 s
    with pytest.raises(IntegrationError, match="test_lagrangian_ball"):
        mechsim.simulate(m, 2.0, 0.1)


def test_symplectic_methods_refuse_models_with_events() -> None:
    with pytest.raises(ParameterError, match="^method: yoshida8 does not handle events"):
        mechsim.simulate(LagrangianBall(), 1.0, 0.1, method="yoshida8")
    assert mechsim.simulate(LagrangianBall(), 0.2, 0.1).method == "dop853"


def test_steppers_pass_the_loops_the_types_set_up_compiled() -> None:
    """Every shared loop is called with exactly the argument types ``precompile`` compiles at
    set-up: events, restarts, constraints, radau15, the compositions and Gauss. Another type
    (a read-only array, say) would have numba compile a second specialization at run time,
    ≈ 20 s of CPU in every new environment, with no error."""
    from mechsim.systems import load_system

    ball = LagrangianBall(restitution=0.8)
    runs = [(ball, m) for m in ("dop853", "dopri5", "radau15")]
    runs += [(load_system("pendulum", formulation="multiplier"), "dop853"),
             (load_system("harmonic_oscillator"), "yoshida8"),
             (load_system("harmonic_oscillator"), "gauss6")]
    for model, method in runs:
        st = make_stepper(model, method, 1e-8)
        st.advance(np.linspace(0.0, 2.0, 5))
        if method in ("dop853", "dopri5", "radau15"):
            st.restart(st.t, st.y, st.p)  # a restart between advances (inputs, events)
            st.advance(np.array([2.5]))
        mechsim.simulate(model, 0.5, 0.1, method=method)  # the outputs' loop too
    for loop, types in loop_signatures().items():
        assert loop.signatures, f"{loop.__name__} never called"
        for sig in loop.signatures:
            assert tuple(sig) == types, f"{loop.__name__}: called with {sig}, compiled {types}"
