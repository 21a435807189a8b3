"""The bag writer holds single messages and hands them to its thread together (with whatever
is queued next): every message reaches the file, once, in the order it was given, whether a
chunk follows, many singles follow (more than are held at once), or the bag is closed right
after one."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mechsim.environment import import_rclpy

import_rclpy()

from mcap.reader import make_reader  # noqa: E402

from mechsim.outputs.bag.writer import HELD_MESSAGES, BagWriter  # noqa: E402
from mechsim.ros.outlet import DIAGNOSTICS_QOS, STATE_QOS  # noqa: E402

CLOCK = "rosgraph_msgs/msg/Clock"
DIAG = "diagnostic_msgs/msg/DiagnosticArray"


def _clock_rows(ns: np.ndarray) -> np.ndarray:
    rows = np.zeros((len(ns), 12), dtype=np.uint8)
    rows[:, 1] = 1
    rows[:, 4:8] = (ns // 1_000_000_000).astype("<u4").view(np.uint8).reshape(-1, 4)
    rows[:, 8:12] = (ns % 1_000_000_000).astype("<u4").view(np.uint8).reshape(-1, 4)
    return rows


def _single(k: int) -> bytes:
    return b"\x00\x01\x00\x00" + k.to_bytes(4, "little") + bytes(k % 5)


def _file_order(path: Path) -> list[tuple[str, int, bytes]]:
    (mcap,) = path.glob("*.mcap")
    with open(mcap, "rb") as f:
        return [(c.topic, m.log_time, bytes(m.data))
                for _, c, m in make_reader(f).iter_messages(log_time_order=False)]


def test_every_message_once_in_the_order_given(tmp_path: Path) -> None:
    w = BagWriter(tmp_path / "bag")
    given: list[tuple[str, int, bytes]] = []
    t = 1_000_000_000
    for block, singles in enumerate([3, 0, HELD_MESSAGES * 2 + 1, 1]):
        ns = t + 10_000_000 * np.arange(1, 51, dtype=np.int64)
        rows = _clock_rows(ns)
        w.write_rows(ns, [("/clock", CLOCK, STATE_QOS, rows)])
        given += [("/clock", int(s), r.tobytes()) for s, r in zip(ns, rows, strict=True)]
        t = int(ns[-1])
        for k in range(singles):
            t += 1
            data = _single(100 * block + k)
            w.write_bytes("/diagnostics", DIAG, DIAGNOSTICS_QOS, t, data)
            given.append(("/diagnostics", t, data))
    stats = w.close()
    assert stats.message_count == len(given)
    assert _file_order(tmp_path / "bag") == given


def test_a_single_message_then_close(tmp_path: Path) -> None:
    w = BagWriter(tmp_path / "bag")
    w.write_bytes("/diagnostics", DIAG, DIAGNOSTICS_QOS, 5, _single(7))
    assert w.close().message_count == 1
    assert _file_order(tmp_path / "bag") == [("/diagnostics", 5, _single(7))]
