"""``yoshida8``, ``yoshida6``, ``verlet``: symmetric compositions of velocity Verlet (orders 8,
6, 2), symplectic and time-reversible, for separable Hamiltonians H = T(p) + V(q): bounded
energy error, no drift. Fixed step (``fixed_step``); they refuse models with events or without
a separable Hamiltonian."""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from mechsim.errors import ParameterError
from mechsim.integrators.compiled import load as loops
from mechsim.integrators.fixed_step import FixedStep
from mechsim.integrators.model import SteppableModel as Model
from mechsim.integrators.state import FIXED_STATE, Status, new_state


def _symmetric(outer: tuple[float, ...]) -> np.ndarray:
    """The weights w_m … w_1, w_0, w_1 … w_m of a symmetric composition from w_m … w_1, the
    central weight w_0 = 1 − 2 Σ w_i."""
    w0 = 1.0 - 2.0 * sum(outer)
    return np.array([*outer, w0, *reversed(outer)], dtype=np.float64)


class Composition(FixedStep):
    """Symplectic composition of velocity Verlet with the weights ``WEIGHTS`` (order
    ``order``), for separable systems. Option: ``step`` (fixed; else sized from the
    tolerance)."""

    WEIGHTS: ClassVar[np.ndarray]

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float, *,
                 step: float | None = None) -> None:
        super().__init__(model, y0, t0, tolerance)
        self.weights = self.WEIGHTS
        self.a = np.empty(self.kernels.n_q)
        self.ks = self.kernels.kernel_set("accel_q")
        self.kernels.accel_q(self.t, self.y[: self.a.size], self.p, self.a)
        self._start(step)

    @classmethod
    def check(cls, model: Model) -> None:
        if model.events:
            raise ParameterError("method", f"{cls.method} does not handle events; {model.id} "
                                 "has events: use dop853 or auto")
        if not model.structure.separable:
            raise ParameterError("method", f"{cls.method} needs a separable Hamiltonian; "
                                 f"{model.id} ({model.formulation}) is not: use dop853 or auto")

    def _guess(self) -> float:
        return self.time_scale() * 0.07 * self.tolerance ** (1.0 / self.order)

    def _probe(self, y0: np.ndarray, t0: float, h: float, n: int) -> np.ndarray | None:
        y = y0.copy()
        a = np.empty(self.a.size)
        self.kernels.accel_q(t0, y[: a.size], self.p, a)
        state, Y = new_state(FIXED_STATE, t0), np.empty((1, y.size))
        status, _ = loops().composition_advance(self.ks, state, y, self.p, 1, n, h,
                                                self.weights, Y, a, np.zeros(y.size))
        self.state["n_evaluations"] += state["n_evaluations"][0] + 1
        return Y[0] if status == Status.OK else None

    def set_parameters(self, p: np.ndarray) -> None:
        super().set_parameters(p)
        self.kernels.accel_q(self.t, self.y[: self.a.size], self.p, self.a)
        self._check()

    def _block(self, Y: np.ndarray, n_sub: int, h: float) -> tuple[Status, int]:
        return loops().composition_advance(  # type: ignore[no-any-return]
            self.ks, self.state, self.y, self.p, len(Y), n_sub, h, self.weights, Y,
            self.a, self.comp)


class Verlet(Composition):
    """Velocity Verlet itself (kick-drift-kick), order 2."""

    method = "verlet"
    order = 2
    WEIGHTS = np.array([1.0])


# The weights of H. Yoshida, "Construction of higher order symplectic integrators", Phys.
# Lett. A 150 (1990) 262–268, from its tables of solutions for orders 6 and 8 (w_m … w_1).
class Yoshida6(Composition):
    """Yoshida's symmetric composition of order 6 (7 stages)."""

    method = "yoshida6"
    order = 6
    WEIGHTS = _symmetric((0.784513610477560, 0.235573213359357, -1.17767998417887))


class Yoshida8(Composition):
    """Yoshida's symmetric composition of order 8 (15 stages)."""

    method = "yoshida8"
    order = 8
    WEIGHTS = _symmetric((1.04242620869991, 1.82020630970714, 0.157739928123617,
                          2.44002732616735, -0.716989419708120e-2, -2.44699182370524,
                          -1.61582374150097))
