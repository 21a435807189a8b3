"""The diagnostics of a fast run are tracked once per chunk for all the reports inside it
(``track_prefixes``, ``DiagnosticsFeed.reports``): every law's state at each report must be
the one the piece-by-piece tracking gives (``track`` on each piece, ``feed_rows`` up to each
report), including across a new epoch and a non-finite sample, where the shortcut
steps aside."""

from __future__ import annotations

import copy
import math
from typing import Any

import numpy as np
import pytest

from mechsim.environment import import_rclpy

rclpy = import_rclpy()
from mechsim.outputs.messages import EnergyColumns  # noqa: E402
from mechsim.ros.diagnostics import DiagnosticsNode  # noqa: E402
from mechsim.ros.drift import LawState, track, track_prefixes  # noqa: E402
from mechsim.ros.feed import DiagnosticsFeed  # noqa: E402
from mechsim.systems.base import Law  # noqa: E402
from mechsim_msgs.msg import SystemInfo  # noqa: E402

S = 1_000_000_000
FIELDS = ("initial", "current", "drift", "max_drift", "samples", "nonfinite", "finite_now")


def _laws() -> list[LawState]:
    return [LawState(Law.from_key("energy"), 2.0), LawState(Law.from_key("invariant:a"), 1.5),
            LawState(Law.from_key("constraint:c"), 1.0)]


def _state(laws: list[LawState]) -> list[tuple[Any, ...]]:
    return [tuple(getattr(law, f) for f in FIELDS) for law in laws]


def test_prefixes_equal_piece_by_piece_tracking() -> None:
    rng = np.random.default_rng(7)
    values = 1.0 + 1e-6 * rng.standard_normal((3, 60))
    values[2] = 1e-9 * rng.standard_normal(60)  # a residual
    ends = [0, 7, 7, 20, 45, 55]
    for start in (0, 5):
        by_piece = _laws()
        if start:
            track(by_piece, values[:, :start])  # initial values and a worst drift so far
        by_prefix = copy.deepcopy(by_piece)
        rest = values[:, start:]
        expected, done = [], 0
        for end in ends:
            if end > done:
                track(by_piece, rest[:, done:end])
                done = end
            expected.append(_state(by_piece))
        if not start:
            assert track_prefixes(by_prefix, rest, ends) is None  # no initial values yet
            continue
        steps = track_prefixes(by_prefix, rest, ends)
        assert steps is not None
        got = []
        for _ in steps:
            got.append(_state(by_prefix))
        assert got == expected


def test_prefixes_step_aside_for_a_non_finite_sample() -> None:
    laws = _laws()
    values = np.ones((3, 10))
    track(laws, values[:, :2])
    values[1, 6] = math.nan
    assert track_prefixes(laws, values, [5, 10]) is None


def _feed(diag: DiagnosticsNode, reset: bool) -> DiagnosticsFeed:
    feed = DiagnosticsFeed(diag)
    feed.write("/toy/system_info", "mechsim_msgs/msg/SystemInfo", SystemInfo(
        instance="toy", system="toy", integrator="rk4",
        laws=["energy", "invariant:a", "constraint:c"], law_scales=[4.0, 2.0, 1.0]), None, 0)
    rng = np.random.default_rng(3)

    def chunk(stamps: np.ndarray, nan_at: int | None = None) -> None:
        n = len(stamps)
        total = 2.0 + 1e-7 * np.cumsum(rng.standard_normal(n))
        zero = np.zeros(n)
        feed.write_columns("/toy/energy", stamps,
                           EnergyColumns(total, zero, total, total, zero, zero))
        a = 4.0 + 1e-5 * rng.standard_normal(n)
        if nan_at is not None:
            a[nan_at] = math.nan
        feed.write_columns("/toy/invariants", stamps,
                           {"a": a, "c": 1e-9 * rng.standard_normal(n)})

    chunk(np.arange(1, 251, dtype=np.int64) * S // 100)  # t = 0.01 … 2.5 s
    chunk(np.arange(251, 501, dtype=np.int64) * S // 100)
    if reset:
        chunk(np.arange(0, 120, dtype=np.int64) * S // 100)  # a reset: a new epoch
        chunk(np.arange(120, 400, dtype=np.int64) * S // 100, nan_at=30)
    else:
        chunk(np.arange(501, 900, dtype=np.int64) * S // 100, nan_at=330)  # 8.31 s
    return feed


def _deliver_until(feed: DiagnosticsFeed, until: int) -> None:
    """The reference: every held run's samples stamped ``until`` or earlier fed piece by piece
    (``feed_rows``, the runs in order), the rest held."""
    keep = []
    for base, leaf, ns, laws, matrix in feed._runs():
        n = int(np.searchsorted(ns, until, "right"))
        if n:
            feed.diag.feed_rows(base, leaf, ns[:n], laws, matrix[:, :n])
        if n < len(ns):
            keep.append((base, leaf, ns[n:], laws, matrix[:, n:]))
    feed.pending = keep


@pytest.mark.parametrize("reset", [False, True])
def test_reports_equal_delivering_before_each_report(ros_context: Any, reset: bool) -> None:
    """Two diagnostics nodes fed the same chunks: one is fed piece by piece up to each report
    stamp (the reference), the other steps through ``reports``; every report's statuses are
    equal, and so are they after the rest is delivered. Without a reset the reports before
    the NaN take the shortcut (counted), the ones after it do not; with a reset a stream is
    held in two runs, fed in turns."""
    nodes = [DiagnosticsNode(context=ros_context, period=3600.0, stale_timeout=3600.0,
                             discover=False) for _ in range(2)]
    shortcuts: list[bool] = []
    feed_prefixes = nodes[1].feed_prefixes

    def counted(*args: Any) -> Any:
        step = feed_prefixes(*args)
        shortcuts.append(step is not None)
        return step

    nodes[1].feed_prefixes = counted  # type: ignore[method-assign]
    try:
        feeds = [_feed(d, reset) for d in nodes]
        rounds = [[1 * S, 2 * S], [3 * S, 4 * S, 5 * S], [int(5.5 * S)], [6 * S, 7 * S, 9 * S]]
        if reset:
            rounds[2:] = [[int(0.5 * S)], [1 * S, 2 * S, 3 * S]]
        for stamps in rounds:
            expected, got = [], []
            for s in stamps:
                _deliver_until(feeds[0], s)
                expected.append(nodes[0].status_rows())
            for _ in feeds[1].reports(stamps):
                got.append(nodes[1].status_rows())
            assert got == expected
        _deliver_until(feeds[0], int(np.iinfo(np.int64).max))
        feeds[1].deliver()
        assert nodes[0].status_rows() == nodes[1].status_rows()
        if not reset:
            assert ("nonfinite", "1") in [kv for row in nodes[1].status_rows()
                                          for kv in row[4]]  # the NaN was counted
            assert any(shortcuts) and not all(shortcuts)
    finally:
        for d in nodes:
            d.destroy_node()
