"""The diagnostics report as the node encodes it (``DiagnosticsNode.status_rows``: the
statuses as tuples of their fields, through the wire encoder): equal byte for byte to rclpy's
serialization of the same DiagnosticArray (its padding aside) and decoded by rclpy into exactly
the statuses given, for strings of every length modulo 4 (each padding), multi-byte text, no
values, no statuses, repeated reports (strings remembered)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from mechsim.environment import import_rclpy

import_rclpy()

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue  # noqa: E402
from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402

from mechsim.outputs.wire import encode  # noqa: E402
from mechsim.ros.diagnostics import StatusRow  # noqa: E402

TYPE = "diagnostic_msgs/msg/DiagnosticArray"


def _rows(seed: int) -> list[StatusRow]:
    """Statuses whose strings take every length modulo 4, with ASCII and multi-byte text."""
    texts = ["", "a", "ab", "abc", "abcd", "drift 1.5e-09", "Δ énergie", "максимум", "🙂x"]
    k = seed % len(texts)
    cycle = itertools.cycle(texts[k:] + texts[:k])
    rows: list[StatusRow] = []
    for i in range(7):
        values = [(next(cycle), next(cycle)) for _ in range((i + seed) % 4)]
        rows.append((i % 4, next(cycle), next(cycle), next(cycle), values))
    return rows


def _message(sec: int, nanosec: int, frame_id: str, rows: list[StatusRow]) -> DiagnosticArray:
    msg = DiagnosticArray(status=[
        DiagnosticStatus(level=bytes([level]), name=name, message=message,
                         hardware_id=hardware_id,
                         values=[KeyValue(key=k, value=v) for k, v in values])
        for level, name, message, hardware_id, values in rows])
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    msg.header.frame_id = frame_id
    return msg


def _equal_to_rclpy(data: bytes, msg: DiagnosticArray) -> None:
    theirs = serialize_message(msg)
    assert len(data) <= len(theirs)
    ours = np.frombuffer(data, np.uint8)
    differ = ours != np.frombuffer(theirs[:len(data)], np.uint8)
    assert not ours[differ].any()  # only padding differs (rclpy leaves it uninitialised)


@pytest.mark.parametrize("seed", range(9))
@pytest.mark.parametrize("frame_id", ["", "w", "world"])
def test_report_equals_rclpy_and_rclpy_reads_it(seed: int, frame_id: str) -> None:
    rows = _rows(seed)
    sec, nanosec = 1_000_000 + seed, 999_999_999 - seed
    for _ in range(2):  # the second time from remembered strings
        data = encode(TYPE, (((sec, nanosec), frame_id), rows))
        _equal_to_rclpy(data, _message(sec, nanosec, frame_id, rows))
        msg = deserialize_message(data, DiagnosticArray)
        assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (sec, nanosec)
        assert msg.header.frame_id == frame_id
        got = [(s.level[0] if isinstance(s.level, bytes) else int(s.level), s.name,
                s.message, s.hardware_id, [(kv.key, kv.value) for kv in s.values])
               for s in msg.status]
        assert got == rows


def test_empty_report() -> None:
    data = encode(TYPE, (((0, 0), ""), []))
    _equal_to_rclpy(data, _message(0, 0, "", []))
    assert list(deserialize_message(data, DiagnosticArray).status) == []
