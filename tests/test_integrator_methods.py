"""The methods table is the one list of methods: every name in ``METHODS`` makes a stepper of
that method through ``make_stepper``, and what scenes and the simulator node accept is exactly
that list. ``auto`` decides a stepper's settings when it makes it: nothing is set on a stepper
after its constructor returns."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import mechsim
from mechsim.errors import IntegrationError, ParameterError
from mechsim.integrators import (
    DOP853,
    METHODS,
    Auto,
    ClosedForm,
    Composition,
    Gauss6,
    Radau15,
    Stepper,
    choose_method,
    make_stepper,
)
from mechsim.integrators.fixed_step import FixedStep
from mechsim.integrators.state import Status
from mechsim.scene import parse_scene

#: A system every method fits: separable, with a canonical form and a closed form, no events.
EVERY_METHOD = "harmonic_oscillator"


@pytest.mark.parametrize("method", list(METHODS))
def test_every_listed_method_makes_its_stepper(method: str) -> None:
    model = mechsim.load_system(EVERY_METHOD)
    st = make_stepper(model, method, 1e-8)
    assert isinstance(st, Stepper)
    if method != "auto":
        assert type(st) is METHODS[method] and st.method == method
    Y = st.advance(np.linspace(0.0, model.time_scale(), 11)[1:])
    assert Y.shape == (10, model.initial_y().size) and np.isfinite(Y).all()


def test_the_table_holds_auto_and_every_stepper_once() -> None:
    assert list(METHODS)[0] == "auto" and METHODS["auto"] is Auto
    steppers = [cls for cls in METHODS.values() if cls is not Auto]
    assert all(issubclass(cls, Stepper) for cls in steppers)
    assert len(set(steppers)) == len(steppers) == len(METHODS) - 1
    assert {cls.method for cls in steppers} | {"auto"} == set(METHODS)
    assert Stepper.TAKES_INPUTS == ("dop853", "dopri5", "radau15")


def test_an_unknown_method_is_refused_with_the_list() -> None:
    listed = ", ".join(METHODS)
    model = mechsim.load_system("pendulum")
    for call in (lambda: make_stepper(model, "rk4"), lambda: choose_method(model, "rk4")):
        with pytest.raises(ParameterError, match=f"^method: must be one of {listed} "):
            call()


def test_scenes_accept_exactly_the_listed_methods() -> None:
    for method in METHODS:
        scene = parse_scene({"systems": [{"system": "pendulum", "method": method}]})
        assert scene.systems[0].method == method
    with pytest.raises(ParameterError) as e:
        parse_scene({"systems": [{"system": "pendulum", "method": "rk45"}]})
    assert e.value.field == "systems[0].method"
    assert e.value.reason == f"must be one of {', '.join(METHODS)} (got 'rk45')"


def test_the_simulator_node_lists_and_knows_exactly_the_listed_methods(
        ros_context: Any) -> None:
    """The node's ``method`` parameter: its descriptor lists the table, and each listed name
    is either taken or refused for not fitting the system (never as unknown)."""
    from rclpy.parameter import Parameter

    from mechsim.ros.simulator import SimulatorNode
    from mechsim.scene import Instance

    node = SimulatorNode(Instance("pendulum", "methods", {}), context=ros_context,
                         real_time_factor=0.0)
    try:
        description = node.describe_parameter("method").description
        assert f"({', '.join(METHODS)})" in description
        for method in METHODS:
            result = node.set_parameters([Parameter("method", value=method)])[0]
            assert result.successful or "must be one of" not in result.reason, method
            if result.successful:
                assert node.get_parameter("method").value == method
        bad = node.set_parameters([Parameter("method", value="rk45")])[0]
        assert not bad.successful and f"must be one of {', '.join(METHODS)}" in bad.reason
    finally:
        node.destroy_node()


def _sealed_after_construction(monkeypatch: pytest.MonkeyPatch) -> list[tuple[type, dict]]:
    """Make every stepper refuse attribute assignments once its constructor has returned,
    except inside its own ``advance`` (which moves its state on), and record each construction
    (class, keyword options)."""
    made: list[tuple[type, dict]] = []

    def guarded(self: Stepper, name: str, value: object) -> None:
        if self.__dict__.get("_sealed") and not self.__dict__.get("_advancing"):
            raise AttributeError(f"{type(self).__name__}.{name} set after construction")
        object.__setattr__(self, name, value)

    def sealing(init: Any) -> Any:
        def wrapped(self: Stepper, *args: Any, **kwargs: Any) -> None:
            init(self, *args, **kwargs)
            made.append((type(self), kwargs))
            object.__setattr__(self, "_sealed", True)
        return wrapped

    def advancing(advance: Any) -> Any:
        def wrapped(self: Stepper, t_out: np.ndarray) -> np.ndarray:
            object.__setattr__(self, "_advancing", True)
            try:
                return advance(self, t_out)  # type: ignore[no-any-return]
            finally:
                object.__setattr__(self, "_advancing", False)
        return wrapped

    monkeypatch.setattr(Stepper, "__setattr__", guarded)
    for cls in (DOP853, Radau15, Composition, Gauss6, ClosedForm):  # each defines __init__
        monkeypatch.setattr(cls, "__init__", sealing(cls.__init__))
    for cls in (DOP853, Radau15, FixedStep, ClosedForm):  # each defines advance
        monkeypatch.setattr(cls, "advance", advancing(cls.advance))
    return made


def test_auto_passes_its_choice_when_it_makes_the_stepper(monkeypatch: pytest.MonkeyPatch
                                                          ) -> None:
    """The chaotic double pendulum: the probe finds DOP853's error outgrowing the tolerance and
    ``auto`` makes radau15 at the finest ε of its range, as a constructor option; the other
    choices likewise come out of the constructor as they are."""
    made = _sealed_after_construction(monkeypatch)
    chaotic = make_stepper(mechsim.load_system("double_pendulum"), "auto", 1e-8)
    assert type(chaotic) is Radau15 and chaotic.eps == Radau15.EPS_RANGE[0]
    assert made[-1] == (Radau15, {"eps": Radau15.EPS_RANGE[0]})
    with pytest.raises(AttributeError, match="set after construction"):
        chaotic.eps = 1e-4  # what ``auto`` did before: retune from outside

    cases = [("pendulum", {}, 1e-8, DOP853, {"work_terms": True}),
             ("kepler", {}, 1e-12, Radau15, {}),
             ("damped_oscillator", {}, 1e-12, DOP853, {"work_terms": True})]
    for system, extra, tol, cls, options in cases:
        st = make_stepper(mechsim.load_system(system), "auto", tol, **extra)
        assert type(st) is cls and made[-1] == (cls, options), system
    exact = make_stepper(mechsim.load_system(EVERY_METHOD), "auto", 1e-8, closed_form=True)
    assert type(exact) is ClosedForm and made[-1] == (ClosedForm, {"check_state": False})


def test_errors_are_typed_by_the_loops_status() -> None:
    """A loop's status reaches the caller as an integration error of its own type."""
    from mechsim.integrators import errors

    for status, cls in ((Status.MAX_STEPS, errors.StepLimitError),
                        (Status.STEP_UNDERFLOW, errors.StepUnderflowError),
                        (Status.NOT_FINITE, errors.NonFiniteStateError),
                        (Status.STIFF, errors.StiffnessError),
                        (Status.NOT_CONVERGED, errors.NotConvergedError)):
        e = errors.for_status(status, "x")
        assert type(e) is cls and isinstance(e, IntegrationError)
    model = mechsim.load_system("kepler")
    st = Radau15(model, model.initial_y(), 0.0, 1e-10, max_steps=2)
    with pytest.raises(errors.StepLimitError, match="kepler: radau15 stopped"):
        st.advance(np.array([10.0]))
