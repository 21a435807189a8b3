"""Pacing: how the simulated time of a run follows the wall clock.

A run stepped by its caller (fast mode, a scene's loop) has no pacing: the caller says how far
to integrate. A run that paces itself integrates, at each tick, up to the simulated time the
wall clock has made due, ``sim0 + real_time_factor · (wall − wall0)`` (:class:`Pacing`), and
computes up to ``lookahead`` samples ahead in one call of the kernels, released as they become
due (``SystemRun.advance_to``). Where the pacing restarts from is explicit: every start,
reset, resume and change of rate or factor makes a new :class:`Pacing` from the run's current
time and the wall clock's present, so the run never catches up on time it did not run.
"""

from __future__ import annotations

from dataclasses import dataclass

#: Samples integrated per call of the kernels (bounds the memory of a long advance).
BLOCK = 1000
#: Wall seconds of samples a paced run computes ahead (released when due): the cost of a call
#: into the kernels, and of a hand-off to the sinks, is shared by that many samples. A new
#: subscriber gets the outputs nobody consumed before within this time.
LOOKAHEAD = 1.0
#: Shortest tick of a paced run [s] (a high rate releases several samples per tick).
MIN_PERIOD = 0.005


def paced_lookahead(publish_rate: float, real_time_factor: float) -> int:
    """Samples a paced run computes ahead (``LOOKAHEAD`` wall seconds of them)."""
    return max(1, min(BLOCK, int(LOOKAHEAD * publish_rate * real_time_factor)))


@dataclass(frozen=True)
class Pacing:
    """Simulated time due at each wall-clock instant: ``sim0 + real_time_factor · (wall −
    wall0)``, from the run's state when the pacing (re)started."""

    real_time_factor: float
    publish_rate: float
    wall0: float  # time.monotonic() when the pacing (re)started
    sim0: float  # the run's simulated time then

    @property
    def period(self) -> float:
        """Wall seconds between two ticks: one sample period, at least ``MIN_PERIOD``."""
        return max(1.0 / (self.publish_rate * self.real_time_factor), MIN_PERIOD)

    @property
    def lookahead(self) -> int:
        return paced_lookahead(self.publish_rate, self.real_time_factor)

    def due(self, wall: float, t: float) -> float:
        """The simulated time to integrate to at wall time ``wall`` from the run's time ``t``:
        what the clock made due, at most one block of samples per tick (so that services and
        parameter sets are served in between)."""
        return min(self.sim0 + self.real_time_factor * (wall - self.wall0),
                   t + BLOCK / self.publish_rate)
