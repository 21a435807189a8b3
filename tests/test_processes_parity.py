"""``run --processes`` equals the in-process run: the same conservation table and the same
outputs, recorded by a recorder node in its own process from what crosses DDS."""

from __future__ import annotations

import math
import re
import subprocess
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np

PY = sys.executable
SCENE = "name: parity\nsystems:\n  - {system: pendulum}\n  - {system: kepler}\n"


def _run(tmp: Path, env: dict[str, str], tag: str, *extra: str) -> tuple[str, Path]:
    bag = tmp / f"bag_{tag}"
    out = subprocess.run([PY, "-m", "mechsim.cli", "run", str(tmp / "scene.yaml"), "--fast",
                          "--duration", "2", "--bag", str(bag), "--rrd", str(tmp / f"{tag}.rrd"),
                          *extra], env=env, cwd=tmp, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    assert "Traceback" not in out.stderr
    return out.stdout, bag


def _table(stdout: str) -> dict[tuple[str, str], str]:
    rows = re.findall(r"^  (\w+)\s+(\S+)\s+\S+e[-+]\d+\s+(OK|WARN|ERROR|STALE)$", stdout,
                      re.MULTILINE)
    return {(system, law): level for system, law, level in rows}


def _fields(msg: Any) -> list[Any]:
    """Every leaf value of a message decoded by rosbags, depth first."""
    if hasattr(msg, "__dataclass_fields__"):
        return [v for name in msg.__dataclass_fields__ for v in _fields(getattr(msg, name))]
    if isinstance(msg, (list, tuple, np.ndarray)):
        return [v for item in msg for v in _fields(item)]
    return [msg]


def _messages(bag: Path) -> dict[str, list[tuple[int, list[Any]]]]:
    """Each topic's (log time, leaf values) in time order. Decoded, not bytes: alignment
    padding carries no value and rmw leaves it uninitialised."""
    from rosbags.highlevel import AnyReader

    got: dict[str, list[tuple[int, list[Any]]]] = defaultdict(list)
    with AnyReader([bag]) as reader:
        for con, t, data in reader.messages():
            got[con.topic].append((t, _fields(reader.deserialize(data, con.msgtype))))
    return {topic: sorted(rows, key=lambda r: (r[0], repr(r[1]))) for topic, rows in got.items()}


def _same(a: list[Any], b: list[Any]) -> bool:
    """Equal leaves; floats to round-off (the nodes step in chunks of another size, so sums
    run in another order)."""
    return len(a) == len(b) and all(
        math.isclose(x, y, rel_tol=1e-12, abs_tol=1e-12) if isinstance(x, float) else x == y
        for x, y in zip(a, b, strict=True))


def test_processes_record_what_in_process_records(ros_env: dict[str, str],
                                                  tmp_path: Path) -> None:
    (tmp_path / "scene.yaml").write_text(SCENE)
    inproc, bag_a = _run(tmp_path, ros_env, "in")
    procs, bag_b = _run(tmp_path, ros_env, "procs", "--processes")
    table = _table(inproc)
    assert len(table) >= 8 and set(table.values()) == {"OK"}, inproc
    assert _table(procs) == table, procs
    assert "every message of the reliable topics recorded" in procs, procs
    a, b = _messages(bag_a), _messages(bag_b)
    assert set(a) == set(b)
    for topic in a:
        if topic == "/diagnostics":  # each diagnostics node reports on its own schedule
            assert b[topic], topic
        else:  # every sample, every value, at the same times (best-effort /clock included:
            # the recorder's reader holds the simulator's bursts)
            assert [t for t, _ in b[topic]] == [t for t, _ in a[topic]], topic
            bad = [t for (t, x), (_, y) in zip(a[topic], b[topic], strict=True)
                   if not _same(x, y)]
            assert not bad, (topic, bad[:3])
    for tag in ("in", "procs"):
        assert (tmp_path / f"{tag}.rrd").stat().st_size > 10_000
