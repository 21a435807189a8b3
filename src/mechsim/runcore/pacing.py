"""Pacing: how the simulated time of a run follows the wall clock.

A run stepped as fast as possible has no pacing: its caller says how far to integrate. A paced
run (a node's own timer, or the loop of an in-process scene) integrates, at each tick, up to the
simulated time the wall clock has made due, ``sim0 + real_time_factor · (wall − wall0)``
(:class:`Pacing`, held by the run: ``SystemRun.pacing``), and computes up to ``lookahead``
samples ahead in one call of the kernels, released as they become due
(``SystemRun.advance_to``). Where the pacing restarts from is explicit: every start, reset,
resume and change of rate or factor makes a new :class:`Pacing` from the run's current time
and the wall clock's present (:meth:`Pacing.restarted`), so the run never catches up on time
it did not run: after a reset to t = 0 or a pause, samples are due one period after another
from there, not all at once.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

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

    def restarted(self, sim: float, publish_rate: float | None = None,
                  wall: float | None = None) -> Pacing:
        """This pacing restarted from the run's simulated time ``sim`` at ``wall`` (default:
        now), at ``publish_rate`` if it changed."""
        return replace(self, wall0=time.monotonic() if wall is None else wall, sim0=sim,
                       publish_rate=self.publish_rate if publish_rate is None
                       else publish_rate)

    def next_due(self, t: float) -> float:
        """The wall time at which the sample after the run's time ``t`` becomes due."""
        return self.wall0 + (t + 1.0 / self.publish_rate - self.sim0) / self.real_time_factor

    def due(self, wall: float, t: float) -> float:
        """The simulated time to integrate to at wall time ``wall`` from the run's time ``t``:
        what the clock made due, at most one block of samples per tick (so that services and
        parameter sets are served in between)."""
        return min(self.sim0 + self.real_time_factor * (wall - self.wall0),
                   t + BLOCK / self.publish_rate)
