"""Paired timing of the runs each matched-error comparison rests on.

A shared host runs slower in stretches, from tens of milliseconds to seconds. A sweep times
one contestant's settings after another's, so two contestants compared at one error level
may each have met a different stretch. After the sweeps, the runs the comparisons are read
from are timed again together: at every error level, for mechsim and for the other
families, the front points around the level (:func:`~mechsim.bench.front.bracket`) of each
contestant whose time there is within ``CONTENDERS`` of its side's fastest. They run in
rounds, each round starting one further along, so all of them meet the same stretches. In
a round each runs ``BURST`` times back to back, and only the last is timed: it finds the
caches as its own runs leave them, as in a sweep, not as another contestant's run left them.
A run's time becomes the median over the rounds; its sweep time stays beside it
(``sweep_time_s``), and ``paired_times_s`` holds the rounds' times.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable, Iterable
from typing import Any

from mechsim.bench.front import bracket, front_rows, points, time_at

#: A contestant whose time at a level is within this factor of its side's fastest there is
#: timed again with it.
CONTENDERS = 1.5
#: Rounds: as many as fit in ``BUDGET_S`` of run time, within these bounds.
MIN_ROUNDS, MAX_ROUNDS = 5, 21
BUDGET_S = 3.0
#: Runs slower than this are not timed again: their sweep times stand.
LONGEST_S = 0.5
#: Runs of one contestant back to back in a round, the last of them timed.
BURST = 3

Rows = list[dict[str, Any]]


def _contestant_fronts(rows: Rows) -> dict[str, Rows]:
    """Each contestant's front (rows copying another contestant's run are that one's)."""
    names = sorted({r["contestant"] for r in rows})
    return {n: front_rows([r for r in rows if r["contestant"] == n and not r.get("same_as")])
            for n in names}


def contested_runs(rows: Rows, levels: Iterable[float]) -> Rows:
    """The runs the comparisons at ``levels`` are read from, on both sides (see the module
    docstring), in the order of ``rows``."""
    fronts = _contestant_fronts(rows)
    family = {r["contestant"]: r["family"] for r in rows}
    chosen: set[int] = set()
    for level in levels:
        for mine in (True, False):
            side = {n: f for n, f in fronts.items() if (family[n] == "mechsim") == mine and f}
            times = {n: time_at(points(f), level) for n, f in side.items()}
            reached = {n: t[0] for n, t in times.items() if t is not None}
            if not reached:
                continue
            fastest = min(reached.values())
            for n, t in reached.items():
                if t <= CONTENDERS * fastest:
                    f = side[n]
                    chosen.update(id(r) for r in bracket(f, [r["end_error"] for r in f], level))
    return [r for r in rows if id(r) in chosen and r["time_s"] <= LONGEST_S]


def timed_in_rounds(calls: list[Callable[[], Any]], rounds: int, burst: int = 1,
                    clock: Callable[[], float] = time.perf_counter) -> list[list[float]]:
    """Each call's times, one a round: ``calls`` run in ``rounds`` rounds, each round starting
    one call further on, each call ``burst`` times back to back with only the last timed."""
    got: list[list[float]] = [[] for _ in calls]
    k = len(calls)
    for n in range(rounds):
        for j in range(k):
            i = (n + j) % k
            for _ in range(burst - 1):
                calls[i]()
            t0 = clock()
            calls[i]()
            got[i].append(clock() - t0)
    return got


def retime(runs: Rows, runner_of: Callable[[dict[str, Any]], Callable[[], Any]],
           clock: Callable[[], float] = time.perf_counter) -> int:
    """Time ``runs`` again in rounds (module docstring); ``runner_of(row)`` gives a row's
    callable run. Returns the number of rounds (0: nothing to time)."""
    if not runs:
        return 0
    calls = [runner_of(r) for r in runs]
    for call in calls:  # warm: caches, allocations, branch history of this stretch
        call()
    per_round = BURST * sum(r["time_s"] for r in runs)
    rounds = int(min(MAX_ROUNDS, max(MIN_ROUNDS, BUDGET_S / per_round)))
    got = timed_in_rounds(calls, rounds, BURST, clock)
    for r, times in zip(runs, got, strict=True):
        r["sweep_time_s"] = r["time_s"]
        r["paired_times_s"] = times
        r["time_s"] = statistics.median(times)
    return rounds
