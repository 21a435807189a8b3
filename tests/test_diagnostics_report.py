"""The /diagnostics report as it leaves the node, bytes decoded by readers independent of the
project's encoder (rclpy's deserializer and rosbags'), against statuses written out by hand from
the samples fed: levels, names, messages, every key/value string and the header stamp; the
bytes equal rosbags' own (zero-padded) serialization of the expected message."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from mechsim.environment import import_rclpy

rclpy = import_rclpy()
from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from rclpy.serialization import deserialize_message  # noqa: E402

from mechsim.outputs.messages import EnergyColumns  # noqa: E402
from mechsim.outputs.sink import Capabilities, Takes  # noqa: E402
from mechsim.outputs.wire import typestore_with  # noqa: E402
from mechsim.ros.diagnostics import DiagnosticsNode  # noqa: E402
from mechsim_msgs.msg import SystemInfo  # noqa: E402

ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
S = 1_000_000_000


class _Capture:
    """A recorder-like sink: keeps the bytes of each /diagnostics report."""

    capabilities = Capabilities(Takes.BYTES)

    def __init__(self) -> None:
        self.reports: list[tuple[int, bytes]] = []

    def write_bytes(self, topic: str, type_name: str, qos: Any, ns: int, data: bytes) -> None:
        assert topic == "/diagnostics" and type_name == ARRAY
        self.reports.append((ns, bytes(data)))

    def write_rows(self, ns: Any, topics: list[Any]) -> None:
        raise AssertionError("the diagnostics node publishes no chunks")


def _values(drift: str, max_drift: str, initial: str, current: str, scale: str,
            samples: str, nonfinite: str, epoch: str) -> list[tuple[str, str]]:
    return [("drift", drift), ("max_drift", max_drift), ("initial", initial),
            ("current", current), ("scale", scale), ("samples", samples),
            ("nonfinite", nonfinite), ("epoch", epoch), ("system", "toy"),
            ("integrator", "rk4")]


def _expect_bytes(stamp: tuple[int, int], statuses: list[tuple[int, str, str, list[Any]]]
                  ) -> bytes:
    """rosbags' serialization of the expected message (its buffer starts zeroed)."""
    store = typestore_with(ARRAY)
    t = store.types
    msg = t[ARRAY](
        t["std_msgs/msg/Header"](t["builtin_interfaces/msg/Time"](*stamp), ""),
        [t["diagnostic_msgs/msg/DiagnosticStatus"](
            level, name, message, "toy",
            [t["diagnostic_msgs/msg/KeyValue"](k, v) for k, v in values])
         for level, name, message, values in statuses])
    return bytes(store.serialize_cdr(msg, ARRAY))


def _check(data: bytes, stamp: tuple[int, int],
           statuses: list[tuple[int, str, str, list[Any]]]) -> None:
    got = deserialize_message(data, DiagnosticArray)
    assert (got.header.stamp.sec, got.header.stamp.nanosec) == stamp
    assert [(s.level, s.name, s.message, s.hardware_id, [(kv.key, kv.value) for kv in s.values])
            for s in got.status] == [(bytes([lv]), n, m, "toy", v) for lv, n, m, v in statuses]
    back = typestore_with(ARRAY).deserialize_cdr(data, ARRAY)
    assert [s.message for s in back.status] == [m for _, _, m, _ in statuses]
    assert data == _expect_bytes(stamp, statuses)


def test_report_fields_and_bytes_match_hand_written_expectation(ros_context: Any) -> None:
    """Energy drifting 2^-20 of 2.0 (OK), an invariant 2^-11 of its scale (WARN), a
    constraint residual whose last sample is NaN (ERROR, one non-finite), a law never sampled
    (STALE, its scale 0 replaced by 1); then a reset (stamp back) re-bases the energy."""
    sink = _Capture()
    diag = DiagnosticsNode(context=ros_context, period=3600.0, stale_timeout=3600.0,
                           discover=False, sinks=[sink])
    try:
        diag.feed("/toy", "system_info", SystemInfo(
            instance="toy", system="toy", integrator="rk4",
            laws=["energy", "invariant:a", "constraint:constraint_r", "invariant:b"],
            law_scales=[4.0, 2.0, 1.0, 0.0]))
        stamps = np.array([1 * S, 2 * S, 3 * S + S // 2], dtype=np.int64)
        total = np.array([2.0, 2.0 + 2.0 ** -20, 2.0])
        zero = np.zeros(3)
        diag.feed_chunk("/toy", "energy", stamps,
                        EnergyColumns(total, zero, total, total, zero, zero))
        diag.feed_chunk("/toy", "invariants", stamps, {
            "a": np.array([4.0, 4.0 + 2.0 ** -10, 4.0 + 2.0 ** -11]),
            "constraint_r": np.array([0.0, 2.0 ** -30, math.nan])})
        diag.publish_now()
        assert len(sink.reports) == 1
        ns, data = sink.reports[0]
        assert ns == 3 * S + S // 2
        _check(data, (3, S // 2), [
            (0, "mechsim/toy/energy", "OK: relative drift 0, max 2.38e-07",
             _values("0.000000e+00", "2.384186e-07", "2.0", "2.0", "4.0", "3", "0", "0")),
            (1, "mechsim/toy/invariant/a", "WARN: relative drift 0.000244, max 0.000488",
             _values("2.441406e-04", "4.882812e-04", "4.0", "4.00048828125", "2.0", "3", "0",
                     "0")),
            (2, "mechsim/toy/constraint/constraint_r",
             "ERROR: relative drift inf, max 9.31e-10, 1 non-finite sample(s)",
             _values("inf", "9.313226e-10", "0.0", "nan", "1.0", "3", "1", "0")),
            (3, "mechsim/toy/invariant/b", "no samples yet",
             _values("0.000000e+00", "0.000000e+00", "None", "0.0", "1.0", "0", "0", "0")),
        ])
        # A reset: the energy stamp goes back; the energy re-bases on 3.0 (its drift from the
        # old epoch is gone), the system's epoch counts 1 for every law.
        total, zero = np.array([3.0, 2.0]), np.zeros(2)
        diag.feed_chunk("/toy", "energy", np.array([0, S // 4], dtype=np.int64),
                        EnergyColumns(total, zero, total, total, zero, zero))
        diag.publish_now()
        ns, data = sink.reports[1]
        assert ns == S // 4  # the report is stamped with the latest energy sample
        _check(data, (0, S // 4), [
            (2, "mechsim/toy/energy", "ERROR: relative drift 0.25, max 0.25",
             _values("2.500000e-01", "2.500000e-01", "3.0", "2.0", "4.0", "5", "0", "1")),
            (1, "mechsim/toy/invariant/a", "WARN: relative drift 0.000244, max 0.000488",
             _values("2.441406e-04", "4.882812e-04", "4.0", "4.00048828125", "2.0", "3", "0",
                     "1")),
            (2, "mechsim/toy/constraint/constraint_r",
             "ERROR: relative drift inf, max 9.31e-10, 1 non-finite sample(s)",
             _values("inf", "9.313226e-10", "0.0", "nan", "1.0", "3", "1", "1")),
            (3, "mechsim/toy/invariant/b", "no samples yet",
             _values("0.000000e+00", "0.000000e+00", "None", "0.0", "1.0", "0", "0", "1")),
        ])
    finally:
        diag.destroy_node()
