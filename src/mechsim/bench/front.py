"""A contestant's work-precision front: its runs that no faster run beats on error, and the
time to reach an error level (or the error reached in a time) interpolated log-log along it."""

from __future__ import annotations

import math
from typing import Any


def front_rows(rows: list[dict[str, Any]], key: str = "end_error") -> list[dict[str, Any]]:
    """The runs of the front: faster ones first, each more accurate than all the faster ones
    (failed runs and runs without a finite error are not on it)."""
    ok = sorted((r for r in rows if r["status"] == "ok" and r[key] is not None
                 and math.isfinite(r[key])), key=lambda r: (r["time_s"], r[key]))
    front: list[dict[str, Any]] = []
    for r in ok:
        if not front or r[key] < front[-1][key]:
            front.append(r)
    return front


def points(front: list[dict[str, Any]], key: str = "end_error") -> list[tuple[float, float]]:
    """(time, error) of each run of a front (an error of 0 as the smallest positive one, for
    the log-log interpolation)."""
    return [(r["time_s"], max(r[key], 1e-300)) for r in front]


def pareto(rows: list[dict[str, Any]], key: str = "end_error") -> list[tuple[float, float]]:
    """(time, error) points of the front (:func:`front_rows`)."""
    return points(front_rows(rows, key), key)


def bracket(front: list[Any], errors: list[float], level: float) -> list[Any]:
    """The points of ``front`` (with their ``errors``) that the time at ``level`` is read
    from: the two around it, the cheapest alone where it is already more accurate, none
    where the front does not reach the level."""
    if not errors or errors[-1] > level:
        return []
    if errors[0] <= level:
        return [front[0]]
    for i in range(len(errors) - 1):
        if errors[i] > level >= errors[i + 1]:
            return [front[i], front[i + 1]]
    return []


def time_at(front: list[tuple[float, float]], level: float) -> tuple[float, bool] | None:
    """Time to reach error ``level`` on the front (log-log interpolation); (time, bound)."""
    pts = bracket(front, [e for _, e in front], level)
    if not pts:
        return None
    if len(pts) == 1:
        return pts[0][0], True
    (t0, e0), (t1, e1) = pts
    f = math.log(e0 / level) / math.log(e0 / e1)
    return math.exp(math.log(t0) + f * math.log(t1 / t0)), False


def error_at(front: list[tuple[float, float]], t: float) -> float | None:
    """Best error reachable within time ``t`` on the front (log-log interpolation)."""
    if not front or t < front[0][0]:
        return None
    if t >= front[-1][0]:
        return front[-1][1]
    for (t0, e0), (t1, e1) in zip(front, front[1:], strict=False):
        if t0 <= t < t1:
            f = math.log(t / t0) / math.log(t1 / t0)
            return math.exp(math.log(e0) + f * math.log(e1 / e0))
    return None
