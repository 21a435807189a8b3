"""Steppers: one contract, interchangeable methods (shape after scipy's ``OdeSolver``).

A stepper owns the integration state of one model and advances it to requested output times:
``advance(t_out) -> Y`` with one row ``[q, v, work_external, work_dissipated]`` per time. The
loops are compiled into the model's kernel module; this module only holds their state.

Methods:
- ``dop853``: adaptive explicit Runge-Kutta 8(5,3), dense output, constraint projection after
  every step (keeps constraint residuals at round-off). Works for every model.
- ``yoshida8`` / ``yoshida6`` / ``verlet``: symmetric compositions of velocity Verlet (orders
  8, 6, 2), symplectic and time-reversible, for separable Hamiltonians (bounded energy error).
- ``gauss6``: three-stage Gauss–Legendre collocation (order 6), symplectic, on Hamilton's
  equations in canonical variables (q, p = ∂L/∂q̇) generated from the Lagrangian, for
  conservative systems whose Hamiltonian is not separable (double pendulum, spherical
  pendulum, charged particle in B): bounded energy error, no drift. Fixed step, stage
  equations by fixed-point iteration; a step that does not converge is halved.
- ``exact``: closed-form propagation (``Model.propagate``) where the model has one for its
  parameters (harmonic, damped and driven oscillators, planar and coupled oscillators, Kepler
  via Kepler's equation): exact to round-off at any output times, no steps.
- ``auto``: ``yoshida8`` for separable models, ``gauss6`` for other conservative
  unconstrained ones, else ``dop853`` (always for constraints, events, dissipation, drive or
  explicit time dependence); with ``closed_form=True``, ``exact`` wherever the model has it.

Stiffness (``dop853``): Hairer's stiffness test runs inside the loop (see ``kernels.py``); when
it fires and the stability-limited step is also crawling — more than ``stiff_steps_per_output``
(1000) steps per output interval — the stepper raises ``StiffnessError`` (an IntegrationError
naming the system, with what to change) instead of crawling on. A stiff but cheap phase (a
damped system settled at rest, big steps) goes on. Read-only otherwise: non-stiff runs are bit
for bit unchanged.

Events (``dop853`` only). A model may declare state events (``Model.events``, each an
``Event(name, direction)``), computed by the kernel function ``event(t, y, p, out)``, and
discrete modes (``Model.modes``), extra state entries after the work terms that stay constant
between events. The kernel checks the event functions after every accepted step, locates the
earliest sign change (in the event's direction) on the dense output to ~1e-14 relative in t,
writes the outputs up to it and stops there with status EVENT. ``DOP853.advance`` then calls
``model.handle_event(index, t, y) -> y_new`` (a velocity jump, a new mode, or y unchanged to
record a time), restarts the integration at (t, y_new) (projection, new first stage and
initial step; counters kept) and goes on, so ``advance(t_out)`` still returns every requested
row (rows before an event come from the dense output of the step that crossed it, even when
a later call asks for them; a row at exactly the event time holds the state after the
handler). Events are handled when met, also past the last requested time. Each event is
recorded in ``stepper.events`` as (t, name). Models without events compile the event code out
and behave bit for bit as before.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np

from mechsim.errors import IntegrationError, ParameterError
from mechsim.integrators.model import SteppableModel as Model

STATUS = {0: "ok", 1: "too many steps", 2: "step size underflow", 3: "non-finite state",
          4: "event", 5: "stiff", 6: "stage equations did not converge"}
EVENT = 4
STIFF = 5

# Yoshida (1990), symmetric compositions of a 2nd-order symmetric method; each tuple lists
# w_m ... w_1 and the central weight is 1 - 2 Σ w_i.
_YOSHIDA6 = (0.784513610477560, 0.235573213359357, -1.17767998417887)
_YOSHIDA8 = (1.04242620869991, 1.82020630970714, 0.157739928123617, 2.44002732616735,
             -0.716989419708120e-2, -2.44699182370524, -1.61582374150097)


def _symmetric(outer: tuple[float, ...]) -> np.ndarray:
    w0 = 1.0 - 2.0 * sum(outer)
    return np.array([*outer, w0, *reversed(outer)], dtype=np.float64)


COMPOSITIONS: dict[str, tuple[np.ndarray, int]] = {
    "verlet": (np.array([1.0]), 2),
    "yoshida6": (_symmetric(_YOSHIDA6), 6),
    "yoshida8": (_symmetric(_YOSHIDA8), 8),
}
METHODS = ("auto", "dop853", "gauss6", "exact", *COMPOSITIONS)


class StiffnessError(IntegrationError):
    """DOP853's stiffness test fired (status STIFF): the state is kept at the last accepted
    step, whose outputs were all written."""


def choose_method(model: Model, method: str, closed_form: bool = False) -> str:
    if method not in METHODS:
        raise ParameterError("method", f"must be one of {', '.join(METHODS)} (got {method!r})")
    if method == "exact" or (method == "auto" and closed_form):
        if model.has_closed_form():
            return "exact"
        if method == "exact":
            raise ParameterError("method", f"exact: {model.id} ({model.formulation}) has no "
                                 "closed form for these parameters: use auto or dop853")
    if method == "auto":
        if model.structure.separable and not model.events:
            return "yoshida8"
        return "gauss6" if model.has_canonical_form() else "dop853"
    if method == "gauss6" and not model.has_canonical_form():
        raise ParameterError("method", f"gauss6 needs a conservative unconstrained system "
                             f"without events; {model.id} ({model.formulation}) is not: "
                             "use dop853 or auto")
    if method in COMPOSITIONS and model.events:
        raise ParameterError("method", f"{method} does not handle events; {model.id} has "
                             "events: use dop853 or auto")
    if method in COMPOSITIONS and not model.structure.separable:
        raise ParameterError("method", f"{method} needs a separable Hamiltonian; "
                             f"{model.id} ({model.formulation}) is not: use dop853 or auto")
    return method


class Stepper(ABC):
    """Integration state of one model; see the module docstring."""

    method: str

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float) -> None:
        if not (0.0 < tolerance < 1.0):
            raise ParameterError("tolerance", f"must be in (0, 1) (got {tolerance!r})")
        self.model = model
        self.kernels = model.kernels
        self.p = model.parameter_vector()
        self.tolerance = float(tolerance)
        self.y = np.array(y0, dtype=np.float64)
        self.t = float(t0)
        self.events: list[tuple[float, str]] = []  # (time, event name), in order

    @abstractmethod
    def advance(self, t_out: np.ndarray) -> np.ndarray: ...

    @property
    @abstractmethod
    def n_steps(self) -> int: ...

    def set_parameters(self, p: np.ndarray) -> None:
        """New parameter values, same structure (runtime ROS parameter changes)."""
        self.p = np.array(p, dtype=np.float64)

    def set_model(self, model: Model) -> None:
        """The same system with new parameter values; the state carries over."""
        self.model = model
        self.set_parameters(model.parameter_vector())


class ClosedForm(Stepper):
    """Exact propagation from an anchor state (t₀, y₀) with ``Model.propagate``."""

    method = "exact"

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float) -> None:
        super().__init__(model, y0, t0, tolerance)
        self.t0, self.y0 = self.t, self.y.copy()
        self.calls = 0

    @property
    def n_steps(self) -> int:
        return 0

    def set_model(self, model: Model) -> None:
        super().set_model(model)
        self.t0, self.y0 = self.t, self.y.copy()

    def advance(self, t_out: np.ndarray) -> np.ndarray:
        t_out = np.asarray(t_out, dtype=np.float64)
        if t_out.size == 0:
            return np.empty((0, self.y.size))
        Y = self.model.propagate(self.t0, self.y0, t_out)
        if Y is None:
            raise IntegrationError(f"{self.model.id}: no closed form for these parameters")
        if not np.all(np.isfinite(Y)):
            raise IntegrationError(f"{self.model.id}: exact: non-finite state")
        self.calls += 1
        self.t, self.y = float(t_out[-1]), Y[-1].copy()
        return Y


class DOP853(Stepper):
    method = "dop853"
    # A stiff phase is an error only when it crawls: more steps than this per output interval.
    stiff_steps_per_output = 1000.0

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float,
                 max_step: float = math.inf, max_steps: int = 10_000_000) -> None:
        super().__init__(model, y0, t0, tolerance)
        n = self.y.size
        self.K = np.zeros((16, n))
        self.F = np.zeros((7, n))
        self.y_old = self.y.copy()
        self.max_step = max_step
        self.max_steps = max_steps
        self.atol = self.tolerance
        self.ev_dir = np.array([e.direction for e in model.events] or [0], dtype=np.int64)
        self.g_old = np.zeros(self.ev_dir.size)
        self._stalled = 0
        self._reset(self.t, self.y)

    def _reset(self, t: float, y: np.ndarray, keep_dense: bool = False) -> None:
        """Start afresh at (t, y); step, rejection, evaluation and event counters are kept.
        ``keep_dense``: the last step's dense output still serves outputs before t (after an
        event at t, for output times a later ``advance`` asks for)."""
        k = self.kernels
        self.y[:] = y
        k.project(t, self.y, self.p)
        k.rhs(t, self.y, self.p, self.K[12])
        h0 = k.dop853_initial_step(t, self.y, self.p, self.K[12].copy(), self.tolerance,
                                   self.atol)
        counts = self.st[5:8] if hasattr(self, "st") else (0.0, 0.0, 2.0)
        n_events = self.st[9] if hasattr(self, "st") else 0.0
        last = self.st[2:5].copy() if keep_dense else (t, 0.0, 0.0)
        # Last three: stiffness test counters (positive, negative in a row) and last h|λ|.
        self.st = np.array([t, h0, *last, *counts, -1.0, n_events, 0.0, 0.0, 0.0])
        if self.model.events:
            k.event(t, self.y, self.p, self.g_old)

    def set_parameters(self, p: np.ndarray) -> None:
        super().set_parameters(p)
        self._reset(float(self.st[0]), self.y)

    @property
    def n_steps(self) -> int:
        return int(self.st[5])

    def advance(self, t_out: np.ndarray) -> np.ndarray:
        t_out = np.ascontiguousarray(t_out, dtype=np.float64)
        Y = np.empty((t_out.size, self.y.size))
        gap = (t_out[-1] - self.t) / t_out.size if t_out.size else 0.0
        done = 0
        while True:
            status, written = self.kernels.dop853_advance(
                self.st, self.y, self.y_old, self.K, self.F, self.p, t_out[done:], Y[done:],
                self.tolerance, self.atol, self.max_step, self.max_steps, self.g_old,
                self.ev_dir)
            done += written
            self.t = float(self.st[0])
            if status == STIFF and self.st[3] * self.stiff_steps_per_output >= gap:
                self.st[10] = 0.0  # stiff but not crawling: go on, test again later
                continue
            if status != EVENT:
                break
            self._handle_event(int(self.st[8]))
        if status == STIFF:
            raise StiffnessError(
                f"{self.model.id}: dop853 stopped at t = {self.st[0]:.6g}: the problem is "
                f"stiff (h·|λ| ≈ {self.st[12]:.3g} > 6.1 on 15 tests: the step, "
                f"{self.st[3]:.3g} s, is limited by stability, not accuracy, "
                f"{gap / self.st[3]:.3g} steps per output interval; {int(self.st[5])} steps so "
                "far); the system's time "
                "scales are far apart (huge spring constant or damping?): soften those "
                "parameters, use a looser tolerance or a lower publish rate, or integrate it "
                "with a stiff (implicit) method such as scipy's Radau or BDF")
        if status != 0:
            raise IntegrationError(f"{self.model.id}: dop853 stopped at t = {self.st[0]:.6g}: "
                                   f"{STATUS[status]}", ) from None
        return Y[:done]

    def _handle_event(self, index: int) -> None:
        """Apply the model's event handler at the event time and restart there."""
        t = self.t
        y_new = np.array(self.model.handle_event(index, t, self.y.copy()), dtype=np.float64)
        if y_new.shape != self.y.shape or not np.all(np.isfinite(y_new)):
            raise IntegrationError(f"{self.model.id}: handler of event "
                                   f"{self.model.events[index].name} returned a bad state")
        if self.events and t - self.events[-1][0] <= 1e-12 * max(1.0, abs(t)):
            self._stalled += 1
            if self._stalled > 100:
                raise IntegrationError(f"{self.model.id}: events accumulate at t = {t:.6g} "
                                       "(Zeno behaviour); the model must change mode there")
        else:
            self._stalled = 0
        self.events.append((t, self.model.events[index].name))
        self._reset(t, y_new, keep_dense=True)


class FixedStep(Stepper):
    """Fixed-step methods: the step is the largest ≤ ``h_max`` dividing each output gap; a
    run of equal gaps goes to the kernel in one call (``_block``). A subclass may recover
    from a failed block (``_recover``: e.g. smaller steps); otherwise the run stops."""

    h_max: float

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float) -> None:
        super().__init__(model, y0, t0, tolerance)
        self.st = np.array([self.t, 0.0, 0.0])  # [t, n_steps, n_force_evaluations]
        self.refine = 1

    @property
    def n_steps(self) -> int:
        return int(self.st[1])

    @abstractmethod
    def _block(self, Y: np.ndarray, n_sub: int, h: float) -> tuple[int, int]:
        """Integrate len(Y) output intervals of n_sub steps of h; (status, rows written)."""

    def _recover(self, status: int) -> bool:
        return False

    def advance(self, t_out: np.ndarray) -> np.ndarray:
        t_out = np.asarray(t_out, dtype=np.float64)
        Y = np.empty((t_out.size, self.y.size))
        k = 0
        while k < t_out.size:
            gap = t_out[k] - self.t
            if gap < 0:
                raise IntegrationError(f"{self.method}: output time {t_out[k]} is in the past")
            if gap == 0.0:
                Y[k] = self.y
                k += 1
                continue
            j = k + 1
            while j < t_out.size and abs((t_out[j] - t_out[j - 1]) - gap) <= 1e-12 * gap:
                j += 1
            n_sub = self.refine * max(1, math.ceil(gap / self.h_max - 1e-9))
            status, written = self._block(Y[k:j], n_sub, gap / n_sub)
            if written:
                # Snap the clock to the requested times so round-off does not accumulate in t.
                self.t = float(t_out[k + written - 1])
                self.st[0] = self.t
                self.y = Y[k + written - 1].copy()
            if status != 0:
                if self._recover(status):
                    k += written
                    continue
                raise IntegrationError(f"{self.model.id}: {self.method} stopped near "
                                       f"t = {self.st[0]:.6g}: {STATUS[status]}")
            k = j
        return Y


class Composition(FixedStep):
    """Symplectic composition of velocity Verlet (separable systems)."""

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float,
                 method: str = "yoshida8", step: float | None = None) -> None:
        super().__init__(model, y0, t0, tolerance)
        self.method = method
        self.weights, order = COMPOSITIONS[method]
        # Error per unit time ~ (h/τ)^order: pick h so that it is about the tolerance.
        self.h_max = step if step is not None else (
            model.time_scale() * 0.07 * self.tolerance ** (1.0 / order))
        self.a = np.empty(len(model.coordinates))
        self.kernels.accel_q(self.t, self.y[: self.a.size], self.p, self.a)

    def set_parameters(self, p: np.ndarray) -> None:
        super().set_parameters(p)
        self.kernels.accel_q(self.t, self.y[: self.a.size], self.p, self.a)

    def _block(self, Y: np.ndarray, n_sub: int, h: float) -> tuple[int, int]:
        status, written = self.kernels.composition_advance(
            self.st, self.y, self.p, len(Y), n_sub, h, self.weights, Y, self.a)
        return int(status), int(written)


class Gauss(FixedStep):
    """Gauss–Legendre (order 6) on canonical variables z = [q, p, ...]."""

    method = "gauss6"

    def __init__(self, model: Model, y0: np.ndarray, t0: float, tolerance: float,
                 step: float | None = None) -> None:
        super().__init__(model, y0, t0, tolerance)
        self.h_max = step if step is not None else (
            model.time_scale() * 0.2 * self.tolerance ** (1.0 / 6.0))
        self._canonical()

    def _canonical(self) -> None:
        """z from the current y, and stage guesses f(z) for the fixed-point iteration."""
        self.z = np.empty_like(self.y)
        self.kernels.to_momenta(self.t, self.y, self.p, self.z)
        f = np.empty_like(self.z)
        self.kernels.canonical_rhs(self.t, self.z, self.p, f)
        self.K = np.repeat(f[None, :], 3, axis=0)

    def set_parameters(self, p: np.ndarray) -> None:
        super().set_parameters(p)
        self._canonical()

    def _block(self, Y: np.ndarray, n_sub: int, h: float) -> tuple[int, int]:
        status, written = self.kernels.gauss_advance(
            self.st, self.z, self.p, len(Y), n_sub, h, Y, self.K)
        return int(status), int(written)

    def _recover(self, status: int) -> bool:
        """Stage iteration did not converge: restart from the last written state with
        fresh stages and halved steps (up to 2¹⁰ times smaller)."""
        if status != 6:
            return False
        if self.refine > 2**10:
            raise IntegrationError(f"{self.model.id}: gauss6 stage equations do not "
                                   f"converge near t = {self.t:.6g}: use dop853")
        self.st[0] = self.t
        self._canonical()
        self.refine *= 2
        return True


def make_stepper(model: Model, method: str = "auto", tolerance: float = 1e-10,
                 t0: float = 0.0, y0: np.ndarray | None = None,
                 step: float | None = None, closed_form: bool = False) -> Stepper:
    chosen = choose_method(model, method, closed_form)
    y = model.initial_y() if y0 is None else y0
    if chosen == "exact":
        return ClosedForm(model, y, t0, tolerance)
    if chosen == "gauss6":
        return Gauss(model, y, t0, tolerance, step=step)
    if chosen == "dop853":
        return DOP853(model, y, t0, tolerance)
    return Composition(model, y, t0, tolerance, method=chosen, step=step)
