"""One system instance run sample by sample: the run core under every node, without ROS.

A :class:`SystemRun` owns a model, its stepper and the state last released; it integrates to a
simulated time in blocks of samples (``pacing.BLOCK`` per call of the kernels), checks every
sample against the guards (``guards``), evaluates in one compiled call the outputs something
consumes (``simulate.evaluate_arrays``), and releases the samples in order to its
:class:`Observer` (the node that publishes them, a test that collects them). Around that: the
effort hold (``effort``), parameter changes as transactions (``change``), resets and pauses,
and, for a paced run, samples computed ahead and released as the wall clock makes them due
(``pacing``). Samples always leave in time order; a reset or a model change starts a new epoch
(``change``), a failed guard stops this system only (last good state kept).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from mechsim.errors import IntegrationError, MechsimError, ParameterError
from mechsim.integrators import Stepper, make_stepper
from mechsim.runcore import guards
from mechsim.runcore.change import Change, Settings, plan, reason
from mechsim.runcore.effort import MAX_MISSED, EffortHold
from mechsim.runcore.equations import PREPARE_TIMEOUT
from mechsim.runcore.pacing import BLOCK, Pacing
from mechsim.runcore.stops import held_signals, raise_if_stop
from mechsim.simulate import OUTPUTS, OutputShape, evaluate_arrays
from mechsim.systems.base import Model

_COLUMN = {name: i for i, name in enumerate(OUTPUTS)}  # in evaluate_arrays' result
#: Most samples one ``SystemRun.step`` takes: a request is served in bounded time.
MAX_STEP = 100_000


class NextBlock:
    """The rows of the next block of an unpaced run, integrated on a thread of its own while
    the run evaluates, encodes and releases the block before (the compiled loops release the
    interpreter lock). Taken by :meth:`SystemRun.advance_to` only if nothing changed in
    between: the same stepper and parameters, the same output times."""

    def __init__(self, stepper: Stepper, p: np.ndarray, times: np.ndarray) -> None:
        self.stepper, self.p, self.times = stepper, p, times
        self._rows: np.ndarray | None = None
        self.error: BaseException | None = None
        self.seconds = 0.0
        self._thread = threading.Thread(target=self._integrate, name="mechsim-next-block",
                                         daemon=True)
        self._thread.start()

    def _integrate(self) -> None:
        t0 = time.perf_counter()
        try:
            self._rows = self.stepper.advance(self.times)
        except BaseException as e:  # noqa: BLE001 - raised where the rows are taken
            self.error = e
        self.seconds = time.perf_counter() - t0

    def finish(self) -> None:
        """Wait until the integration has ended (the stepper is the caller's again)."""
        self._thread.join()

    def rows(self) -> np.ndarray:
        """The rows, as ``stepper.advance(times)`` returns them (or its error raised)."""
        self.finish()
        if self.error is not None:
            raise self.error
        assert self._rows is not None
        return self._rows

    def matches(self, stepper: Stepper, p: np.ndarray, times: np.ndarray) -> bool:
        return stepper is self.stepper and p is self.p and np.array_equal(times, self.times)


@dataclass
class Block:
    """Consecutive samples that passed the guards, with the outputs evaluated for them (only
    those something consumed when the block was made: ``energy`` (m, 3: kinetic, potential,
    energy function), ``invariants`` (m, k), ``observables`` (m, k), ``frames`` (m, f, 7)).
    Released in order, all at once or, computed ahead, as the wall clock makes them due."""

    times: np.ndarray
    Y: np.ndarray  # state rows: q, v (or p: ``Model.rates``), work terms, modes
    outputs: dict[str, np.ndarray]
    reason: str | None  # why the system stops after the last row (a guard), if it does
    rates: np.ndarray  # q̇ of each row (``Model.rates``)
    released: int = 0
    #: What the observer made of the samples for its consumers (``Observer.encode``).
    encoded: Any = None

    @property
    def left(self) -> int:
        return self.times.size - self.released


class Observer(Protocol):
    """What a run tells about itself, and asks of whoever consumes its samples."""

    def wanted(self) -> tuple[str, ...]:
        """The outputs (of ``simulate.OUTPUTS``) something consumes now; asked once per
        block."""

    def encode(self, block: Block) -> None:
        """Prepare ``block`` for release (its ``encoded``), once, before any of it leaves."""

    def release(self, block: Block, a: int, b: int) -> None:
        """Samples ``a`` to ``b`` (exclusive) of ``block`` leave, in order; once ``b`` is the
        block's end, everything released goes on to the consumers at once."""

    def flush(self) -> None:
        """Everything released goes on to the consumers now (a change applies next)."""

    def model_changed(self, model: Model, structural: bool) -> None:
        """A new model (``structural``: new equations, the run restarts at t = 0)."""

    def laws_changed(self) -> None:
        """What runs and which laws hold changed (a start, a change, a first effort)."""

    def effort_applied(self, u: np.ndarray) -> None:
        """The effort applied from the current sample on changed to ``u``."""

    def stopped(self, reason: str) -> None:
        """A guard or a failed step stopped the system (``SystemRun.failed``)."""

    def effort_notice(self, message: str) -> None:
        """Something about the effort input a user must know (a dropped effort, a silent
        controller); the run goes on."""

    def controller_present(self) -> bool:
        """A controller sends effort commands (the run then steps sample by sample)."""


class SystemRun:
    """One system instance run sample by sample (see the module docstring).

    ``advance_to(t)`` integrates and releases every sample up to ``t``; ``step(n)`` advances
    a paused run by n samples; ``plan``/``commit`` change parameters as one transaction;
    ``reset`` restarts at t = 0; ``offer`` takes an effort command. ``start()`` releases the
    first sample (t = 0): call it once the observer is ready."""

    #: Unpaced, integrate each block's successor while the block is released (``NextBlock``);
    #: off: one after the other, which ``mechsim bench --streaming`` measures faster beside it
    #: on two cores (the thread's hand-offs cost more than the overlap gains).
    integrates_ahead = False

    def __init__(self, model: Model, method: str, settings: Settings, observer: Observer, *,
                 stepped: bool, end_time: float | None = None,
                 prepare_timeout: float = PREPARE_TIMEOUT) -> None:
        """``stepped``: the caller says how far to integrate (no pacing of its own);
        ``end_time``: never integrate past this simulated time (a scene's duration)."""
        self.observer = observer
        self.settings = settings
        self.method = method
        self.stepped = stepped
        self.end_time = end_time
        self.prepare_timeout = prepare_timeout
        self.spec = {p.name: p for p in type(model).parameter_spec()}
        self.values: dict[str, Any] = dict(model.values)
        self.model = model
        self.stepper = make_stepper(model, method, settings.tolerance)
        self.p = model.parameter_vector()
        self.shape = OutputShape.of(model)
        self.constraints: list[int] = []
        self.t = 0.0
        self.y = self.stepper.y.copy()  # the state of the last released sample
        self.epoch = 0
        self.failed: str | None = None
        self.paused = False
        self.samples_published = 0
        self.effort = EffortHold(settings.effort_timeout, settings.effort_limit)
        # Commands are judged from construction on (a controller may say it is there before
        # the first sample); ``start`` empties the inbox, the controller stays answered.
        self.effort.reset(model.effort_slice(), new_epoch=True)
        #: Samples computed ahead of the wall clock by a paced run (0: only the due ones),
        #: and by how many samples this run's blocks are shifted (a scene spreads its runs'
        #: blocks over the ticks instead of computing them all in one).
        self.lookahead = 0
        self.stagger = 0
        #: How this run follows the wall clock, set by whoever paces it (its node's timer, a
        #: scene's loop); None: stepped as fast as possible. Restarted from the current
        #: sample by every reset, resume and change of rate (``pacing``).
        self.pacing: Pacing | None = None
        #: Set by a runner that steps this run: serve its callbacks (an effort command among
        #: them) once, waiting up to the given wall seconds.
        self.serve: Callable[[float], None] | None = None
        self.computed = {name: 0 for name in OUTPUTS}
        #: Wall seconds spent integrating and evaluating.
        self.costs = {"integrate": 0.0, "evaluate": 0.0}
        self._ahead: Block | None = None
        self._ahead_failed = False

    # --- start, reset, change ---------------------------------------------------------------
    def start(self) -> None:
        """Release the first sample (t = 0) of the model given."""
        self._install(self.model, self.stepper, structural=True)

    def reset(self) -> None:
        """Restart at t = 0 from the initial state of the current values (a new epoch)."""
        model = self.model if self.model.values == self.values \
            else type(self.model)(**self.values)  # (only after a change that failed)
        stepper = make_stepper(model, self.method, self.settings.tolerance)
        self.epoch += 1
        self._install(model, stepper, structural=True)
        self.restart_pacing()

    def set_paused(self, paused: bool) -> None:
        """Pause, or resume with the pacing restarted from the current sample."""
        self.paused = paused
        if not paused:
            self.restart_pacing()

    def restart_pacing(self) -> None:
        """The pacing (if any) restarts from the current sample and the wall clock's present,
        at the current publish rate: what the run did not run is never caught up on."""
        if self.pacing is not None:
            self.pacing = self.pacing.restarted(self.t, self.settings.publish_rate)

    def _install(self, model: Model, stepper: Stepper, structural: bool) -> None:
        """Run ``model`` with ``stepper`` (at its initial state, t = 0)."""
        self.model, self.stepper = model, stepper
        self.observer.model_changed(model, structural)
        self._set_model(model)
        self.t = 0.0
        self.y = stepper.y.copy()
        self.failed = None
        self._ahead, self._ahead_failed = None, False
        self._reset_effort(new_epoch=True)
        self.observer.laws_changed()
        self._emit(np.zeros(1), stepper.y.copy()[None, :])

    def _set_model(self, model: Model) -> None:
        self.model = model
        self.p = model.parameter_vector()
        self.shape = OutputShape.of(model)
        self.constraints = guards.enforced_constraints(model)

    def _reset_effort(self, new_epoch: bool) -> None:
        """A new model or stepper starts without effort (``EffortHold.reset``)."""
        self.effort.reset(self.model.effort_slice(), new_epoch)
        if self.effort.at is not None:
            self.p[self.effort.at] = 0.0

    def plan(self, updates: list[tuple[str, Any]]) -> Change:
        """The change ``updates`` ((name, value), in order) would make, built and checked;
        MechsimError with the reason otherwise (``change.plan``)."""
        return plan(self, updates)

    def commit(self, c: Change) -> bool:
        """Apply a planned change from the next sample. True when the pacing must restart
        (a new rate, factor or a restart at t = 0)."""
        self._drop_ahead()  # every change applies from the next sample
        s = self.settings
        repace = (c.settings.publish_rate != s.publish_rate
                  or c.settings.real_time_factor != s.real_time_factor)
        self.values, self.method, self.settings = c.values, c.method, c.settings
        self.effort.timeout = c.settings.effort_timeout
        self.effort.limit = c.settings.effort_limit
        if c.structural:
            assert c.model is not None and c.stepper is not None
            self.epoch += 1
            self._install(c.model, c.stepper, structural=True)
            self.restart_pacing()
            return True
        if c.model is not None:
            self.observer.model_changed(c.model, structural=False)
            self._set_model(c.model)
            self.epoch += 1
        if c.stepper is not None:
            self.stepper = c.stepper
        if c.model is not None or c.stepper is not None:
            self._reset_effort(new_epoch=c.model is not None)
            self.observer.laws_changed()
        if c.model is not None:
            # The current sample again, with the new parameters and the same time: a time
            # not later than the previous one's is a consumer's signal of a new epoch.
            self._emit(np.array([self.t]), self.y.copy()[None, :])
        if repace:
            self.restart_pacing()
        return repace

    def apply(self, c: Change) -> bool:
        """``commit``; an error there (which planning should have made impossible) stops
        this system instead of escaping. True when the pacing must restart."""
        try:
            return self.commit(c)
        except Exception as e:  # noqa: BLE001 - never out of the caller: this system stops
            raise_if_stop(e)
            self.fail(f"applying {', '.join(c.names)} failed: {reason(e)}")
            return False

    def fail(self, reason: str) -> None:
        """Stop this system: last good state kept; the observer says why."""
        self.failed = reason
        self.observer.stopped(reason)

    # --- effort -------------------------------------------------------------------------------
    def offer(self, u: np.ndarray) -> tuple[str, str] | None:
        """An effort command (``effort``): accepted for the next sample, or refused with
        (kind, reason). Safe from another thread."""
        return self.effort.offer(u, self.model, self.stepper.method, self.samples_published)

    def _effort_step(self) -> bool:
        """Before the next sample period (from ``self.t``): apply the newest command, or zero
        once the held effort has timed out. True when the run must step sample by sample: an
        effort is held (its timeout falls on a sample) or a controller that has answered is
        present (``EffortHold``: one that never did is not waited for)."""
        at = self.effort.at
        if at is None:
            return False
        closed = self.observer.controller_present()
        if closed and not self.effort.responsive:
            self.effort.unwaited += 1
            closed = False
        if closed:
            self._await_command()
        u = self.effort.next(self.t, self.settings.publish_rate)
        if u is not None and u.size == at.stop - at.start and not np.array_equal(u, self.p[at]):
            self._apply_effort(at, u)
        return self.effort.held_until is not None or closed

    def _apply_effort(self, at: slice, u: np.ndarray) -> None:
        """The effort ``u`` from the current sample on: the stepper restarts there with it
        (no step crosses a change of the held value)."""
        if self.stepper.method not in Stepper.TAKES_INPUTS:
            return  # the method changed after the command was accepted: dropped with it
        p = self.p.copy()
        p[at] = u
        self.stepper.restart(self.t, self.y, p)
        self.p = p
        self.observer.effort_applied(u)
        if u.any() and not self.effort.acted:
            self.effort.acted = True
            self.observer.laws_changed()  # only the laws that hold under an effort

    def _await_command(self) -> None:
        """Stepped closed loop: unless a command arrived since the last sample was released,
        serve the runner's callbacks until one does (the controller's answer to that sample,
        applied from it on), at most ``effort_wait`` wall seconds."""
        if self.serve is None or self.settings.effort_wait <= 0:
            return
        end = time.monotonic() + self.settings.effort_wait
        if self.effort.answered < self.samples_published:
            self.effort.waits += 1
        while self.effort.answered < self.samples_published:
            left = end - time.monotonic()
            if left <= 0 or self.failed:
                if not self.failed:
                    last = self.effort.miss()
                    self.observer.effort_notice(
                        f"the controller did not answer within effort_wait "
                        f"{self.settings.effort_wait:g} s: not waited for until it answers "
                        f"again" + (f" (the last wait of this run: {MAX_MISSED} missed)"
                                    if last else ""))
                break
            self.serve(min(left, 0.05))

    def _effort_failed(self, why: str) -> bool:
        """A step failed (``why``): if an effort was acting, drop it and go on from the last
        good sample without it (True); False if none was (the failure is the system's)."""
        at = self.effort.at
        if at is None or not self.p[at].any() or \
                self.stepper.method not in Stepper.TAKES_INPUTS:
            return False
        zeros = np.zeros(at.stop - at.start)
        self.effort.drop()
        self._ahead, self._ahead_failed = None, False
        p = self.p.copy()
        p[at] = zeros
        self.stepper.restart(self.t, self.y, p)
        self.p = p
        self.observer.effort_applied(zeros)
        self.observer.effort_notice(f"effort dropped at t = {self.t:.9g} s: {why}; the run "
                                    "goes on from the last good sample without it")
        return True

    # --- samples ------------------------------------------------------------------------------
    def static_frames(self) -> np.ndarray:
        """The model's frames (frames, 7) at the stepper's state: what the static ones hold."""
        out = evaluate_arrays(self.model, self.shape, np.zeros(1), self.stepper.y[None, :],
                              self.p, ("frames",))
        return out[3][0]

    def _emit(self, times: np.ndarray, Y: np.ndarray) -> int:
        """Check the rows of ``Y`` against the guards and release them, in order, up to the
        first bad one (which stops the system). Returns the number of rows released."""
        block = self._prepare(times, Y)
        return self._release(block, block.left)

    def _prepare(self, times: np.ndarray, Y: np.ndarray) -> Block:
        """The rows of ``Y`` up to the first that fails a guard, evaluated (only the outputs
        something consumes) and encoded by the observer, not yet released."""
        t0 = time.perf_counter()
        good, why = guards.finite_rows(times, Y)
        want = self.observer.wanted()
        which = want + (("invariants",) if self.constraints and "invariants" not in want
                        else ())
        out = evaluate_arrays(self.model, self.shape, times[:good], Y[:good], self.p, which) \
            if good and which else None
        if self.constraints and good and out is not None:
            breach = guards.within_limit(times, Y[:good, self.model.layout.q], out[1],
                                         self.constraints, self.shape.invariants,
                                         self.settings.constraint_limit)
            if breach is not None:
                good, why = breach
        self.costs["evaluate"] += time.perf_counter() - t0
        outputs = {name: out[_COLUMN[name]][:good] for name in want} \
            if out is not None and good else {}
        for name in outputs:
            self.computed[name] += good
        block = Block(times[:good], Y[:good], outputs, why,
                      self.model.rates(times[:good], Y[:good], self.p))
        self.observer.encode(block)
        return block

    def _release(self, block: Block, k: int) -> int:
        """Release the next ``k`` samples of ``block``; after its last one, stop the system if
        a guard failed there. Returns ``k``."""
        a, b = block.released, block.released + k
        if k:
            # A stop waits for the samples: what was released and self.t agree.
            with held_signals():
                self.observer.release(block, a, b)
                block.released = b
                self.samples_published += k
                self.t = float(block.times[b - 1])
                self.y = block.Y[b - 1].copy()
        if block.left == 0 and block.reason is not None and not self._effort_failed(
                block.reason):
            self.fail(block.reason)
        return k

    def _drop_ahead(self) -> None:
        """Forget the samples computed ahead and not released (a change applies from the
        next sample)."""
        block, self._ahead = self._ahead, None
        self.observer.flush()
        if block is not None and block.left and not self.failed:
            self._rewind()

    def _rewind(self) -> None:
        """The stepper, which ran ahead, goes on from the last released sample."""
        if self.stepper.method in Stepper.TAKES_INPUTS:
            self.stepper.restart(self.t, self.y, self.p)
        else:
            self.stepper = make_stepper(self.model, self.method, self.settings.tolerance,
                                        t0=self.t, y0=self.y.copy())

    # --- advancing ----------------------------------------------------------------------------
    def advance_to(self, t_target: float) -> int:
        """Integrate to ``t_target`` (simulated time; never past ``end_time``), releasing
        every sample on the way. Returns the number of samples released. A failed or paused
        run releases none. With ``lookahead`` > 0 (a paced run) up to that many samples are
        computed in one go and released as they become due; any change (a parameter set, a
        reset, an effort command) drops the ones not yet released. Unpaced, each block's
        successor is integrated while the block is evaluated, encoded and released
        (:class:`NextBlock`)."""
        if self.end_time is not None:
            t_target = min(t_target, self.end_time)
        released = 0
        following: NextBlock | None = None
        try:
            while not (self.failed or self.paused):
                if following is not None:
                    following.finish()  # (the stepper is this thread's again)
                due = min(self._samples_to(t_target), BLOCK)
                if due <= 0:
                    break
                ahead = self._ahead
                if ahead is not None and ahead.left:
                    if not self.effort.pending:
                        released += self._release(ahead, min(due, ahead.left))
                        continue
                    self._drop_ahead()  # a command applies from the next sample
                n = 1 if self._effort_step() else self._block_size(due)
                times = self._times_after(self.t, n)
                if following is not None and not following.matches(self.stepper, self.p,
                                                                    times):
                    self._drop_following(following)
                    following = None
                Y = self._integrate(times, n > due, following)
                following = None
                if Y is None:
                    if self.failed:
                        break
                    continue  # computing ahead failed: the due samples only, from the last one
                if n == due:
                    following = self._integrate_next(times, t_target)
                block = self._prepare(times, Y)
                if n > due:
                    self._ahead = block
                released += self._release(block, min(due, block.left))
        finally:
            if following is not None:
                self._drop_following(following)
        return released

    def _integrate_next(self, times: np.ndarray, t_target: float) -> NextBlock | None:
        """Start integrating the block after ``times`` (to ``t_target``), unless the run is
        paced, an effort may change before it, or the model has events (then each block is
        integrated as it comes). (An event is handled in Python, between two calls of the
        compiled loop: integrated meanwhile, each handler would wait for the interpreter
        lock while this thread encodes, up to a switch interval of 5 ms.)"""
        effort = self.effort
        if not self.integrates_ahead or self.lookahead or self.model.events or (
                effort.at is not None and (effort.held_until is not None or effort.pending
                                           or effort.responsive)):
            return None
        last = float(times[-1])  # self.t once this block is released
        n = min(self._samples_to(t_target, last), BLOCK)
        if n <= 0:
            return None
        return NextBlock(self.stepper, self.p, self._times_after(last, n))

    def _drop_following(self, following: NextBlock) -> None:
        """Something changed after the next block was started (a guard stopped the system, an
        effort came, ...): its rows are dropped and the stepper, unless the system stopped,
        goes on from the last released sample."""
        following.finish()
        if not self.failed and self.stepper is following.stepper:
            self._rewind()

    def step(self, samples: int) -> int:
        """Advance a paused run by ``samples`` samples of its grid (released as any others:
        the same times, stamps and /clock as a running system's), then stay paused. Returns
        the samples taken: fewer where ``end_time`` comes first. Refused (MechsimError) unless
        paused, for a stopped system, and for ``samples`` outside 1 … ``MAX_STEP``."""
        if not 1 <= samples <= MAX_STEP:
            raise ParameterError("samples", f"must be in 1 … {MAX_STEP} (got {samples})")
        if self.failed:
            raise MechsimError(f"stopped ({self.failed}); reset first")
        if not self.paused:
            raise MechsimError("running: pause it first (~/pause true), then step")
        taken = 0
        self.paused = False
        try:
            while taken < samples and not self.failed:
                got = self.advance_to(self.t + (samples - taken) / self.settings.publish_rate)
                if got == 0:
                    break  # the end of the run
                taken += got
        finally:
            self.paused = True
        return taken

    def _samples_to(self, t: float, start: float | None = None) -> int:
        """Whole sample periods from ``start`` (the current time) to ``t``."""
        start = self.t if start is None else start
        return int(math.floor((t - start) / (1.0 / self.settings.publish_rate) + 1e-9))

    def _times_after(self, start: float, n: int) -> np.ndarray:
        """The ``n`` sample times after ``start``."""
        return start + (1.0 / self.settings.publish_rate) * np.arange(1, n + 1)

    def _block_size(self, due: int) -> int:
        """Samples to integrate now: the due ones, or (paced) to the next block boundary
        (every ``lookahead`` samples, shifted by ``stagger``), never past ``end_time``."""
        if self.lookahead <= due or self._ahead_failed:
            return due
        last = BLOCK if self.end_time is None else self._samples_to(self.end_time)
        ahead = self.lookahead - (self.samples_published + self.stagger) % self.lookahead
        return max(due, min(ahead, last, BLOCK))

    def _integrate(self, times: np.ndarray, ahead: bool,
                   following: NextBlock | None = None) -> np.ndarray | None:
        """The state rows at ``times`` (those ``following`` integrated, if given); None if the
        step failed (then either computing ahead failed and the stepper went back to the last
        released sample, or the system stopped)."""
        try:
            t0 = time.perf_counter()
            if following is None:
                Y = self.stepper.advance(times)
                seconds = time.perf_counter() - t0
            else:
                Y, seconds = following.rows(), following.seconds
            # (the events' record is simulate()'s result; a run that may go on for ever
            # keeps none: memory stays flat however many bounces)
            self.stepper.events.clear()
            self.costs["integrate"] += seconds
            return Y
        except Exception as e:  # noqa: BLE001 - e.g. numba errors from extreme values
            raise_if_stop(e)
            error: BaseException = e
        if ahead:
            # Go on with the due samples only, from the last released one, so the failure
            # stops the system where it would anyway.
            self._ahead_failed = True
            try:
                self._rewind()
                return None
            except Exception as again:  # noqa: BLE001 - as above
                raise_if_stop(again)
                error = again
        why = str(error) if isinstance(error, IntegrationError) \
            else f"integration failed: {reason(error)}"
        if not self._effort_failed(why):
            self.fail(why)  # this system only
        return None

    @property
    def finished(self) -> bool:
        """No sample left before ``end_time``, or stopped by a failure."""
        return bool(self.failed) or (self.end_time is not None and math.floor(
            (self.end_time - self.t) * self.settings.publish_rate + 1e-9) <= 0)
