"""``gauss6``: three-stage Gauss–Legendre collocation (order 6), symplectic, on Hamilton's
equations in canonical variables (q, p = ∂L/∂q̇) generated from the Lagrangian, for
conservative systems whose Hamiltonian is not separable (double pendulum, spherical pendulum,
charged particle in B): bounded energy error, no drift. Fixed step (``fixed_step``), stage
equations by fixed-point iteration; a step that does not converge is halved."""

from __future__ import annotations

import numpy as np

from mechsim.errors import ParameterError
from mechsim.integrators.compiled import load as loops
from mechsim.integrators.errors import NotConvergedError
from mechsim.integrators.fixed_step import FixedStep
from mechsim.integrators.model import SteppableModel as Model
from mechsim.integrators.state import FIXED_STATE, Status, new_state


class Gauss6(FixedStep):
    """Gauss–Legendre (order 6) on canonical variables z = [q, p, ...]. Option: ``step``
    (fixed; else sized from the tolerance)."""

    method = "gauss6"
    order = 6

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float, *,
                 step: float | None = None) -> None:
        super().__init__(model, y0, t0, tolerance)
        self.ks = self.kernels.kernel_set("to_momenta", "from_momenta", "canonical_rhs")
        self._canonical()
        self._start(step)

    @classmethod
    def check(cls, model: Model) -> None:
        if not model.has_canonical_form():
            raise ParameterError("method", f"gauss6 needs a conservative unconstrained system "
                                 f"without events; {model.id} ({model.formulation}) is not: "
                                 "use dop853 or auto")

    def _guess(self) -> float:
        return self.time_scale() * 0.2 * self.tolerance ** (1.0 / 6.0)

    def _stages(self, y: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """z from y, and stage guesses f(z) for the fixed-point iteration."""
        z = np.empty_like(y)
        self.kernels.to_momenta(t, y, self.p, z)
        f = np.empty_like(z)
        self.kernels.canonical_rhs(t, z, self.p, f)
        return z, np.ascontiguousarray(np.repeat(f[None, :], 3, axis=0))

    def _canonical(self) -> None:
        self.z, self.K = self._stages(self.y, self.t)
        self.comp[:] = 0.0

    def _probe(self, y0: np.ndarray, t0: float, h: float, n: int) -> np.ndarray | None:
        z, K = self._stages(y0, t0)
        state, Y = new_state(FIXED_STATE, t0), np.empty((1, y0.size))
        status, _ = loops().gauss_advance(self.ks, state, z, self.p, 1, n, h, Y, K,
                                          np.zeros(z.size))
        self.state["n_evaluations"] += state["n_evaluations"][0] + 1
        return Y[0] if status == Status.OK else None

    def set_parameters(self, p: np.ndarray) -> None:
        super().set_parameters(p)
        self._canonical()
        self._check()

    def _block(self, Y: np.ndarray, n_sub: int, h: float) -> tuple[Status, int]:
        return loops().gauss_advance(  # type: ignore[no-any-return]
            self.ks, self.state, self.z, self.p, len(Y), n_sub, h, Y, self.K,
            self.comp)

    def _recover(self, status: Status) -> bool:
        """Stage iteration did not converge: restart from the last written state with
        fresh stages and halved steps (up to 2¹⁰ times smaller)."""
        if status != Status.NOT_CONVERGED:
            return False
        if self.refine > 2**10:
            raise NotConvergedError(f"{self.model.id}: gauss6 stage equations do not "
                                    f"converge near t = {self.t:.6g}: use dop853")
        self.state["t"] = self.t
        self._canonical()
        self.refine *= 2
        return True
