"""The contract between hand-written kernel functions and the generated kernel module: every
upper-case constant a kernel reads is generated, with the same value as in its Python module
(checked when the kernel source is made, before anything compiles), so the functions compute
the same called from Python as compiled; and the one status enum the loops return."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mechsim
from mechsim.errors import IntegrationError
from mechsim.integrators import DOP853, StepLimitError, make_stepper
from mechsim.integrators.state import Status
from mechsim.params import number, positive
from mechsim.systems import symmetric_top
from mechsim.systems.base import Quantity, Structure
from mechsim.systems.direct import DirectModel, KernelContractError

P_MASS = 1  # right for _MassSecond (length, mass), wrong for _MassFirst (mass, length)
P_SPRING = 0  # no model below has a parameter "spring"


def rhs(t, y, p, dy):  # type: ignore[no-untyped-def]
    """A mass on a spring of unit stiffness: ẍ = −x / m."""
    dy[0] = y[1]
    dy[1] = -y[0] / p[P_MASS]
    dy[2] = 0.0
    dy[3] = 0.0


def energy(t, y, p, out):  # type: ignore[no-untyped-def]
    out[0] = 0.5 * p[P_SPRING] * y[1] ** 2
    out[1] = 0.0
    out[2] = out[0]


class _Oscillator(DirectModel):
    title = "test oscillator"
    source = "tests"
    kernel_functions = (rhs,)

    @property
    def coordinates(self) -> tuple[Quantity, ...]:
        return (Quantity("x", "m"),)

    @property
    def structure(self) -> Structure:
        return Structure(separable=False)

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array([1.0]), np.array([0.0])


class _MassSecond(_Oscillator):
    id = "contract_mass_second"
    parameters = (positive("length", 1.0, "m", "unused"), positive("mass", 4.0, "kg", "m"),
                  number("initial.x", 1.0, "m", "x₀"))


class _MassFirst(_Oscillator):
    id = "contract_mass_first"
    parameters = (positive("mass", 4.0, "kg", "m"), positive("length", 1.0, "m", "unused"))


class _UnknownConstant(_MassSecond):
    id = "contract_unknown"
    kernel_functions = (rhs, energy)


def test_python_constant_must_equal_the_generated_one() -> None:
    assert _MassSecond().kernel_source().constants["P_MASS"] == P_MASS  # consistent: builds
    with pytest.raises(KernelContractError, match=r"rhs reads P_MASS = 1 .* P_MASS = 0"):
        _MassFirst().kernel_source()


def test_constant_the_module_does_not_define() -> None:
    with pytest.raises(KernelContractError, match="energy reads P_SPRING, which its kernel"):
        _UnknownConstant().kernel_source()


def test_hand_written_kernel_runs_compiled() -> None:
    """The consistent model integrates to the closed form x = cos(t/√m)."""
    model = _MassSecond()
    Y = make_stepper(model, "dop853", 1e-12).advance(np.array([3.0]))
    assert Y[0, 0] == pytest.approx(math.cos(3.0 / 2.0), abs=1e-10)


def test_python_call_of_a_hand_written_kernel_matches_the_compiled_one() -> None:
    """symmetric_top's frames kernel reads P_CM_DISTANCE: called as plain Python with the
    model's parameter vector it gives what the compiled kernel gives (the centre of mass at
    cm_distance along the body axis)."""
    model = mechsim.load_system("symmetric_top", cm_distance=0.37)
    y, p = model.initial_y(), model.parameter_vector()
    compiled = np.zeros((3, 7))
    python = np.zeros((3, 7))
    model.kernels.frames(0.0, y, p, compiled)
    symmetric_top.frames(0.0, y, p, python)
    assert python[2, 2] == compiled[2, 2] == 0.37
    assert np.allclose(python, compiled, rtol=0, atol=1e-15)


def test_loops_return_the_shared_status() -> None:
    """The status a loop returns is a ``Status`` member; its reason reaches the user, in the
    integration error of its own type."""
    model = mechsim.load_system("kepler")
    st = DOP853(model, model.initial_y(), 0.0, 1e-10, max_steps=3)
    with pytest.raises(StepLimitError, match=Status.MAX_STEPS.reason) as e:
        st.advance(np.array([10.0]))
    assert isinstance(e.value, IntegrationError)
    assert st.n_steps == 3
