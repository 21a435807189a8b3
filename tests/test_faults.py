"""Faults: a node SIGKILLed in a multi-process scene (the others go on, diagnostics says STALE),
SIGINT/SIGTERM to ``mechsim record`` (complete bag, nothing recorded lost), a slow subscriber
(the publisher never blocks), restarting the recorder into a new bag, a full disk."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

PY = sys.executable


def _bag_counts(path: Path) -> Counter[str]:
    from rosbags.highlevel import AnyReader

    counts: Counter[str] = Counter()
    with AnyReader([path]) as reader:
        for con, _, _ in reader.messages():
            counts[con.topic] += 1
    return counts


def _meta(path: Path) -> dict[str, Any]:
    return yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]


def _spin_until(ex: Any, cond: Callable[[], bool], timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        ex.spin_once(timeout_sec=0.05)
        if cond():
            return True
    return cond()


def test_sigkill_one_node_of_a_multiprocess_scene(ros_context: Any, ros_env: dict[str, str],
                                                  tmp_path: Path) -> None:
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sensor_msgs.msg import JointState

    scene = tmp_path / "two.yaml"
    scene.write_text(yaml.safe_dump({"name": "two", "publish_rate": 20.0, "systems": [
        {"system": "pendulum", "name": "alive"}, {"system": "harmonic_oscillator",
                                                  "name": "victim"}]}))
    procs = {w: subprocess.Popen([PY, "-m", "mechsim.ros.launch", str(scene), "--node", w],
                                 env=ros_env, stdout=subprocess.DEVNULL,
                                 stderr=subprocess.PIPE)
             for w in ("alive", "victim", "diagnostics")}
    probe = Node("fault_probe", context=ros_context)
    counts: Counter[str] = Counter()
    levels: dict[str, int] = {}
    for name in ("alive", "victim"):
        probe.create_subscription(JointState, f"/{name}/state",
                                  lambda m, n=name: counts.update([n]), 100)

    def on_diag(m: Any) -> None:
        for s in m.status:
            levels[s.name] = s.level[0] if isinstance(s.level, bytes) else int(s.level)
    probe.create_subscription(DiagnosticArray, "/diagnostics", on_diag, 100)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(probe)
    try:
        assert _spin_until(ex, lambda: counts["alive"] > 20 and counts["victim"] > 20, 60), counts
        assert _spin_until(ex, lambda: any(k.startswith("mechsim/victim/") for k in levels), 30)
        procs["victim"].send_signal(signal.SIGKILL)
        procs["victim"].wait(timeout=10)
        killed_at = dict(counts)
        # Others keep publishing; diagnostics marks the killed system STALE (5 s timeout).
        assert _spin_until(ex, lambda: all(
            v == 3 for k, v in levels.items() if k.startswith("mechsim/victim/")) and
            counts["alive"] > killed_at["alive"] + 100, 30), (levels, counts)
        # Messages already queued for the probe when the victim died (at most the
        # subscription depth) may still arrive; after that, nothing more from the victim.
        assert counts["victim"] <= killed_at["victim"] + 100
        settled = counts["victim"]
        _spin_until(ex, lambda: False, 1.0)
        assert counts["victim"] == settled
        alive = [v for k, v in levels.items() if k.startswith("mechsim/alive/")]
        assert alive and all(v != 3 for v in alive), levels
        for w in ("alive", "diagnostics"):
            assert procs[w].poll() is None, f"{w} died with the victim"
    finally:
        ex.shutdown()
        probe.destroy_node()
        for p in procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for p in procs.values():
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()


def _record(bag: Path, env: dict[str, str], *extra: str) -> subprocess.Popen[str]:
    return subprocess.Popen([PY, "-m", "mechsim.cli", "record", "pendulum", "--duration", "1e6",
                             "--bag", str(bag), *extra], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _wait_recording(bag: Path, proc: subprocess.Popen[str], timeout: float = 60) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if any(f.stat().st_size > 100_000 for f in bag.glob("*.mcap")):
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.1)
    raise AssertionError("recorder never wrote")


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_to_recorder_completes_the_bag(ros_env: dict[str, str], tmp_path: Path,
                                              sig: int) -> None:
    bag = tmp_path / "bag"
    proc = _record(bag, ros_env)
    _wait_recording(bag, proc)
    proc.send_signal(sig)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "interrupted at t =" in err
    # Reported count == metadata == what an independent reader finds: nothing lost.
    reported = int(re.search(r"bag \S+: (\d+) messages", out).group(1))  # type: ignore[union-attr]
    counts = _bag_counts(bag)
    assert sum(counts.values()) == _meta(bag)["message_count"] == reported
    t_stop = float(re.search(r"interrupted at t = (\S+) s", err).group(1))  # type: ignore[union-attr]
    # Every sample up to the stop (the reported t may lag the last published sample by one
    # step when the signal lands between publishing and the clock update).
    assert round(t_stop * 100) + 1 <= counts["/pendulum/state"] <= round(t_stop * 100) + 2


def test_restart_recorder_after_kill_into_new_bag(ros_env: dict[str, str],
                                                  tmp_path: Path) -> None:
    first = tmp_path / "first"
    proc = _record(first, ros_env)
    _wait_recording(first, proc)
    proc.kill()
    proc.communicate(timeout=30)
    assert not (first / "metadata.yaml").exists()
    # Same directory again: refused with one line; a new one works.
    again = subprocess.run([PY, "-m", "mechsim.cli", "record", "pendulum", "--duration", "1",
                            "--bag", str(first)], env=ros_env, capture_output=True, text=True,
                           timeout=120)
    last = again.stderr.strip().splitlines()[-1]
    assert again.returncode == 2 and last.startswith("mechsim: error: bag ") and "not empty" in last
    second = tmp_path / "second"
    ok = subprocess.run([PY, "-m", "mechsim.cli", "record", "pendulum", "--duration", "1",
                         "--bag", str(second)], env=ros_env, capture_output=True, text=True,
                        timeout=120)
    assert ok.returncode == 0, ok.stderr
    assert _bag_counts(second)["/pendulum/state"] == 101
    # The killed bag is repaired from its flushed chunks and reads back.
    from mechsim.outputs.bag import repair_bag

    r = repair_bag(first)
    assert r.messages > 0 and sum(_bag_counts(first).values()) == r.messages


def test_slow_subscriber_does_not_block_publisher(ros_context: Any, ros_env: dict[str, str]
                                                  ) -> None:
    """A subscriber in another process that takes 50 ms per message (reliable, depth 10): the
    simulator's publish loop keeps its pace (KEEP_LAST: the writer overwrites, never waits)."""
    from mechsim.ros.simulator import SimulatorNode
    from mechsim.scene import Instance

    node = SimulatorNode(Instance("pendulum", "fast"), context=ros_context,
                         real_time_factor=0.0, publish_rate=1000.0)
    try:
        def timed(n: int) -> float:
            t0 = time.perf_counter()
            node.advance_to(node.t + n / 1000.0)
            return time.perf_counter() - t0

        timed(500)  # warm-up
        baseline = timed(3000)
        code = ("import sys, time\n"
                "from mechsim.environment import import_rclpy\n"
                "rclpy = import_rclpy()\n"
                "from sensor_msgs.msg import JointState\n"
                "rclpy.init()\n"
                "n = rclpy.create_node('slow_sub')\n"
                "got = [0]\n"
                "def cb(m):\n"
                "    got[0] += 1\n"
                "    time.sleep(0.05)\n"
                "n.create_subscription(JointState, '/fast/state', cb, 10)\n"
                "print('ready', flush=True)\n"
                "end = time.time() + 20\n"
                "while time.time() < end:\n"
                "    rclpy.spin_once(n, timeout_sec=0.1)\n"
                "    if got[0] and time.time() > end - 20 + 8: break\n"
                "print(got[0], flush=True)\n")
        slow = subprocess.Popen([PY, "-c", code], env=ros_env, stdout=subprocess.PIPE,
                                text=True)
        try:
            assert slow.stdout is not None and slow.stdout.readline().strip() == "ready"
            pub = node.outlet.channels["/fast/state"].publisher
            end = time.monotonic() + 30
            while pub.get_subscription_count() == 0 and time.monotonic() < end:
                time.sleep(0.05)
            assert pub.get_subscription_count() > 0
            time.sleep(0.5)  # matched both ways
            loaded = timed(3000)
            got = int(slow.communicate(timeout=60)[0].strip() or 0)
        finally:
            if slow.poll() is None:
                slow.kill()
        # 3000 messages at 50 ms each would take 150 s if the publisher waited.
        assert loaded < max(3 * baseline, baseline + 1.5), (baseline, loaded)
        assert 0 < got < 3000
    finally:
        node.destroy_node()


def _tiny_tmpfs(path: Path) -> bool:
    path.mkdir()
    try:
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(path)],
                           capture_output=True, timeout=10)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return r.returncode == 0


def test_disk_full_while_recording(ros_env: dict[str, str], tmp_path: Path) -> None:
    """A 64 KiB tmpfs fills up mid-recording: exit 2, one line naming the bag, partial bag
    removed (an error bag never looks complete)."""
    mnt = tmp_path / "full"
    if not _tiny_tmpfs(mnt):
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        r = subprocess.run([PY, "-m", "mechsim.cli", "record", "kepler", "--duration", "200",
                            "--bag", str(mnt / "bag")], env=ros_env, capture_output=True,
                           text=True, timeout=180)
        assert r.returncode == 2, r.stderr
        lines = r.stderr.strip().splitlines()
        assert lines[-1].startswith("mechsim: error: bag ") and "No space left" in lines[-1]
        assert not (mnt / "bag").exists() or not any((mnt / "bag").iterdir())
    finally:
        subprocess.run(["umount", str(mnt)], capture_output=True, timeout=10)


def test_unwritable_outputs_one_line(ros_env: dict[str, str], tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    for argv in (["record", "pendulum", "--duration", "1", "--bag", str(blocker / "bag")],
                 ["stress", "pendulum", "--quick", "--case", "hamilton", "--out",
                  str(blocker / "out")]):
        r = subprocess.run([PY, "-m", "mechsim.cli", *argv], env=ros_env, capture_output=True,
                           text=True, timeout=120)
        assert r.returncode == 2, (argv, r.stderr)
        last = r.stderr.strip().splitlines()[-1]
        assert last.startswith("mechsim: error:") and "Not a directory" in last, last
    assert blocker.read_text() == "x"
    assert os.listdir(tmp_path) == ["file"]
