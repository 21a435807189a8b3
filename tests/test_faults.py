"""Faults: a node SIGKILLed in a multi-process scene (the others go on, diagnostics says STALE),
SIGINT/SIGTERM to ``mechsim record`` (complete bag, nothing recorded lost, exit 130), also the
moment the bag appears, a slow subscriber (the publisher never blocks), restarting the recorder
into a new bag, a full disk (what was recorded is kept), hostile parameter sets from another
process during a recording, and the process tree of ``run --processes``."""

from __future__ import annotations

import os
import re
import select
import signal
import subprocess
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterator
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


def _scene_file(tmp_path: Path, data: dict[str, Any]) -> str:
    """The scene as its node processes receive it from ``run --processes``."""
    import json

    from mechsim.scene import parse_scene, scene_data

    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene_data(parse_scene(data))))
    return str(path)


def _node(which: str) -> list[str]:
    """The verb and arguments of a node process of ``run --processes``."""
    return ["diagnostics"] if which == "diagnostics" else ["simulator", "--instance", which]


def test_sigkill_one_node_of_a_multiprocess_scene(ros_context: Any, ros_env: dict[str, str],
                                                  tmp_path: Path) -> None:
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sensor_msgs.msg import JointState

    scene = _scene_file(tmp_path, {"name": "two", "publish_rate": 20.0, "systems": [
        {"system": "pendulum", "name": "alive"}, {"system": "harmonic_oscillator",
                                                  "name": "victim"}]})
    procs = {w: subprocess.Popen([PY, "-m", "mechsim.cli", *_node(w), "--scene", scene],
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
        # subscription depth) may still arrive; after that, nothing more from the victim
        # while the living system publishes another 100 samples.
        assert counts["victim"] <= killed_at["victim"] + 100
        settled, alive_then = counts["victim"], counts["alive"]
        assert _spin_until(ex, lambda: counts["alive"] > alive_then + 100, 60)
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


_STARTED: list[subprocess.Popen[str]] = []


@pytest.fixture(autouse=True)
def _no_recorder_outlives_its_test() -> Iterator[None]:
    """A recorder of 1e6 s left running by a failed assertion would load the machine for the
    rest of the run: kill whatever a test started and did not stop."""
    yield
    while _STARTED:
        proc = _STARTED.pop()
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=60)


def _record(bag: Path, env: dict[str, str], *extra: str) -> subprocess.Popen[str]:
    proc = subprocess.Popen([PY, "-m", "mechsim.cli", "record", "pendulum", "--duration", "1e6",
                             "--bag", str(bag), *extra], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    _STARTED.append(proc)
    return proc


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
    assert proc.returncode == 130, err  # interrupted: not a success
    assert "interrupted at t =" in err and "Traceback" not in err
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
    assert again.returncode == 2 and last.startswith("mechsim: error: --bag: ") \
        and "not empty" in last
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


_SLOW_SUBSCRIBER = """
import select, sys, time
from mechsim.environment import import_rclpy
rclpy = import_rclpy()
from sensor_msgs.msg import JointState
rclpy.init()
n = rclpy.create_node("slow_sub")
got = [0]
def cb(m):
    got[0] += 1
    time.sleep(0.05)  # a slow consumer: 50 ms per message
sub = n.create_subscription(JointState, "/fast/state", cb, 10)
while n.count_publishers("/fast/state") == 0:
    rclpy.spin_once(n, timeout_sec=0.05)
print("matched", flush=True)
while True:  # answer "count" with the messages handled so far; stop at "quit"
    rclpy.spin_once(n, timeout_sec=0.01)
    if select.select([sys.stdin], [], [], 0)[0]:
        line = sys.stdin.readline().strip()
        if line == "count":
            print(got[0], flush=True)
        else:
            break
"""


def _line(proc: subprocess.Popen[str], timeout: float = 120.0) -> str:
    """The child's next line, waited for with a generous deadline (never forever)."""
    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], timeout)
    assert ready, f"no line from the child within {timeout:g} s"
    return proc.stdout.readline().strip()


def test_slow_subscriber_does_not_block_publisher(ros_context: Any, ros_env: dict[str, str]
                                                  ) -> None:
    """A subscriber in another process that takes 50 ms per message (reliable, depth 10): the
    simulator publishes 3000 samples without waiting for it (KEEP_LAST: the writer overwrites,
    never waits). Evidence without a clock: when publishing ends, the subscriber has handled
    only a few of them; a publisher that waited for it would have had each one acknowledged
    first (at least 3000 - 10 handled)."""
    from mechsim.ros.simulator import SimulatorNode
    from mechsim.scene import Instance

    node = SimulatorNode(Instance("pendulum", "fast"), context=ros_context,
                         real_time_factor=0.0, publish_rate=1000.0)
    slow = subprocess.Popen([PY, "-c", _SLOW_SUBSCRIBER], env=ros_env, stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    try:
        assert slow.stdout is not None and slow.stdin is not None
        assert _line(slow) == "matched"
        from rclpy.executors import SingleThreadedExecutor

        ex = SingleThreadedExecutor(context=ros_context)
        ex.add_node(node)
        pub = node.outlet.channels["/fast/state"].publisher
        assert _spin_until(ex, lambda: pub.get_subscription_count() > 0, 60)
        assert node.advance_to(3.0) == 3000
        slow.stdin.write("count\n")
        slow.stdin.flush()
        handled = int(_line(slow))
        assert 0 <= handled < 3000 - 10, handled
        slow.stdin.write("quit\n")
        slow.stdin.flush()
        slow.wait(timeout=60)
        ex.shutdown()
    finally:
        if slow.poll() is None:
            slow.kill()
            slow.wait()
        node.destroy_node()


def _tiny_tmpfs(path: Path) -> bool:
    path.mkdir()
    try:
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(path)],
                           capture_output=True, timeout=10)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return r.returncode == 0


def test_disk_full_while_recording(ros_env: dict[str, str], tmp_path: Path) -> None:
    """A 1 MiB tmpfs fills up mid-recording: exit 2, one line naming the bag and saying what
    was kept; the recording is never deleted: given space again, ``bag repair`` completes it
    and an independent reader gets every message of it back."""
    mnt = tmp_path / "full"
    if not _tiny_tmpfs(mnt):
        pytest.skip("cannot mount a tmpfs here (needs root)")
    try:
        r = subprocess.run([PY, "-m", "mechsim.cli", "record", "kepler", "--duration", "1e5",
                            "--bag", str(mnt / "bag")], env=ros_env, capture_output=True,
                           text=True, timeout=600)
        assert r.returncode == 2, r.stderr
        lines = r.stderr.strip().splitlines()
        assert lines[-1].startswith("mechsim: error: bag ") and "No space left" in lines[-1]
        assert "kept" in lines[-1] or "completed" in lines[-1], lines[-1]
        assert "Traceback" not in r.stderr
        assert any(f.stat().st_size > 0 for f in (mnt / "bag").glob("*.mcap"))
        subprocess.run(["mount", "-o", "remount,size=16m", str(mnt)], check=True,
                       capture_output=True, timeout=30)
        from mechsim.outputs.bag import repair_bag

        if not (mnt / "bag" / "metadata.yaml").exists():
            repair_bag(mnt / "bag")
        counts = _bag_counts(mnt / "bag")
        assert counts["/kepler/state"] > 100
        assert sum(counts.values()) == _meta(mnt / "bag")["message_count"]
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


def test_hostile_parameter_sets_during_a_recording(ros_env: dict[str, str], tmp_path: Path,
                                                   mechsim_graph: Any) -> None:
    """From another process, while ``mechsim record`` runs: a method the system cannot use
    (exact without a closed form, gauss6 on a constrained form), a real-time factor for a node
    the recorder steps, a hostile curve-like value: each is rejected with its reason and the
    recording goes on; a good value is accepted. The stopped recording is complete and
    readable, nothing lost (before: the first set stopped the scene and deleted the bag).
    The sets go through one participant (the plugin's graph), so the recording lasts seconds;
    a publish rate of 2 Hz keeps the fast recorder's bag small enough to read back whole."""
    from rcl_interfaces.srv import GetParameters

    def current(name: str) -> Any:
        value, = mechsim_graph.call(f"{node}/get_parameters",
                                    GetParameters.Request(names=[name])).values
        return value

    bag = tmp_path / "bag"
    proc = _record(bag, ros_env, "--set", "formulation=multiplier", "--publish-rate", "2")
    node = "/pendulum/simulator"
    try:
        _wait_recording(bag, proc)
        for name, value, why in (("method", "exact", "no closed form"),
                                 ("method", "gauss6", "needs a conservative unconstrained"),
                                 ("real_time_factor", 5.0, "read-only"),
                                 ("tolerance", 1.0e-30, "out of range Min: 1e-15"),
                                 ("formulation", "9**9**9", "formulation: must be one of")):
            result, = mechsim_graph.set_parameters(node, **{name: value})
            assert not result.successful and why in result.reason, (name, result.reason)
            assert proc.poll() is None, proc.communicate()
        assert current("method").string_value == "auto"
        result, = mechsim_graph.set_parameters(node, gravity=3.5)
        assert result.successful, result.reason
        assert current("gravity").double_value == 3.5
        assert proc.poll() is None
    finally:
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    reported = int(re.search(r"bag \S+: (\d+) messages", out).group(1))  # type: ignore[union-attr]
    counts = _bag_counts(bag)
    assert sum(counts.values()) == _meta(bag)["message_count"] == reported
    assert "failed" not in out and "integration stopped" not in out


def test_sigterm_as_the_bag_appears(ros_env: dict[str, str], tmp_path: Path) -> None:
    """SIGTERM the moment the bag directory exists: the recorder stops cleanly (exit 130, no
    traceback) and leaves a complete bag or none, never one without metadata."""
    bag = tmp_path / "bag"
    proc = _record(bag, ros_env)
    while not bag.exists() and proc.poll() is None:
        time.sleep(0.001)  # polling the condition tightly: the point is to be early
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    assert not bag.exists() or (bag / "metadata.yaml").exists(), sorted(bag.iterdir())
    if bag.exists():
        assert sum(_bag_counts(bag).values()) == _meta(bag)["message_count"]


def _children(pid: int) -> list[int]:
    out = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            out.append(int(stat.parent.name))
    return out


def _gone(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return True
    return state in ("Z", "X")  # a zombie waits for a reaper that may not exist here


def _wait(cond: Callable[[], bool], timeout: float = 120) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.05)
    return cond()


def test_processes_die_with_their_parent(ros_env: dict[str, str], tmp_path: Path) -> None:
    """``run --processes``: SIGKILL of the parent (no chance to clean up) still ends every
    child (PR_SET_PDEATHSIG)."""
    proc = subprocess.Popen([PY, "-m", "mechsim.cli", "run", "pendulum", "--processes"],
                            env=ros_env, cwd=tmp_path, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        assert _wait(lambda: len(_children(proc.pid)) == 2), _children(proc.pid)
        kids = _children(proc.pid)
        proc.kill()
        proc.wait(timeout=60)
        assert _wait(lambda: all(_gone(k) for k in kids)), kids
    finally:
        if proc.poll() is None:
            proc.kill()


def _answered(ask: Callable[[], Any]) -> Any:
    """``ask()`` (a call to a node's services), asked again while the node is still starting
    (a request sent the moment its service is discovered can lose its response)."""
    from mechsim.errors import MechsimError

    end = time.monotonic() + 300
    while True:
        try:
            return ask()
        except MechsimError:
            if time.monotonic() > end:
                raise


def _parameter(node: str, name: str) -> Any:
    from mechsim.ros.graph import get_parameter

    return _answered(lambda: get_parameter(node, name, timeout=20))


def _pause(node: str) -> None:
    """Pause a simulator through its ``pause`` service."""
    from mechsim.ros.graph import call_service

    ok, message = _answered(lambda: call_service(node, "pause", "true", timeout=20))
    assert ok, message


def test_processes_options_and_exit_status(ros_env: dict[str, str], tmp_path: Path) -> None:
    """``run --processes`` passes --publish-rate and --fast to its nodes (their parameters say so),
    stops at --duration by itself (exit 0) or on Ctrl-C (130), and exits with its children's
    status: a system that fails gives 1, a refused start (duplicate name) gives 2. Its own
    instance name: a pendulum another test left in this worker's graph must not answer."""
    first = subprocess.Popen([PY, "-m", "mechsim.cli", "run", "pendulum", "--processes",
                              "--name", "rated", "--fast", "--publish-rate", "40"], env=ros_env,
                             cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                             text=True)
    try:
        _pause("/rated/simulator")  # a fast run would load the machine for the whole test
        assert _parameter("/rated/simulator", "publish_rate") == 40.0
        assert _parameter("/rated/simulator", "real_time_factor") == 0.0
        # A discovery window long enough for a loaded machine: refused once seen.
        dup = subprocess.run([PY, "-m", "mechsim.cli", "run", "pendulum", "--processes",
                              "--name", "rated", "--fast", "--duration", "1"],
                             env=dict(ros_env, MECHSIM_GRAPH_WAIT="120"), cwd=tmp_path,
                             capture_output=True, text=True, timeout=300)
        assert dup.returncode == 2, dup.stderr
        assert "/rated/simulator is already running" in dup.stderr
    finally:
        first.send_signal(signal.SIGINT)
        _, err = first.communicate(timeout=120)
    assert first.returncode == 130, err  # interrupted
    ok = subprocess.run([PY, "-m", "mechsim.cli", "run", "kepler", "--processes", "--fast",
                         "--duration", "2"], env=ros_env, cwd=tmp_path, capture_output=True,
                        text=True, timeout=300)
    assert ok.returncode == 0, ok.stderr
    bad = subprocess.run([PY, "-m", "mechsim.cli", "run", "pendulum", "--processes", "--fast",
                          "--duration", "2", "--set", "gravity=1e300"], env=ros_env,
                         cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert bad.returncode == 1, bad.stderr
    assert "integration stopped" in bad.stderr and "Traceback" not in bad.stderr


def _loaded(pid: int, needle: str) -> bool:
    try:
        return needle in Path(f"/proc/{pid}/maps").read_text()
    except OSError:
        return True  # gone: nothing more to wait for


@pytest.mark.parametrize("stage", ["at once", "numpy", "librcl", "running"])
def test_node_process_stopped_while_starting_is_quiet(ros_env: dict[str, str],
                                                     tmp_path: Path, stage: str) -> None:
    """A node process (``run --processes`` child) stopped at any point of its start-up, during
    its imports included, or once running, exits without a traceback."""
    from mechsim.ros.graph import node_names

    scene = _scene_file(tmp_path, {"name": "quiet", "systems": [{"system": "pendulum",
                                                                  "name": "quiet"}]})
    proc = subprocess.Popen([PY, "-m", "mechsim.cli", *_node("quiet"), "--scene", scene],
                            env=ros_env, cwd=tmp_path,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    needle = {"numpy": "numpy", "librcl": "librcl"}.get(stage)
    if needle is not None:
        assert _wait(lambda: _loaded(proc.pid, needle), 300)
    if stage == "running":
        assert _wait(lambda: "/quiet/simulator" in node_names(), 300)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert "Traceback" not in err and "error" not in err, err
    assert proc.returncode in (0, 130, -signal.SIGTERM), (proc.returncode, err)


def test_a_stop_wrapped_by_compiled_code_stops_the_run(ros_context: Any,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """A Ctrl-C landing inside a compiled call surfaces as ``SystemError: ... returned a result
    with an exception set`` caused by the KeyboardInterrupt (seen in CI). It must end the run as
    an interruption, never mark the system failed and run on."""
    from mechsim.ros.launch import run_scene
    from mechsim.runcore import run as simulator
    from mechsim.scene import single_system_scene

    real = simulator.make_stepper
    calls = {"n": 0}

    def make(*args: Any, **kw: Any) -> Any:
        stepper = real(*args, **kw)
        advance = stepper.advance

        def interrupted_advance(times: Any) -> Any:
            calls["n"] += 1
            if calls["n"] == 3:
                try:
                    raise KeyboardInterrupt
                except KeyboardInterrupt as stop:
                    raise SystemError("CPUDispatcher(...) returned a result with an exception "
                                      "set") from stop
            return advance(times)

        stepper.advance = interrupted_advance
        return stepper

    monkeypatch.setattr(simulator, "make_stepper", make)
    run = run_scene(single_system_scene("pendulum"), fast=True, duration=1e6,
                    context=ros_context)
    assert run.interrupted and not run.failures, run.failures
    assert calls["n"] == 3 and 0 < run.sim_time < 1e6


def test_consumers_of_a_refused_run_do_not_drain(tmp_path: Path) -> None:
    """A multi-process run whose simulators published nothing (a refused start) leaves
    ``NOTHING_PUBLISHED`` beside its consumers' reports, and a consumer then stops without
    draining: what it still receives comes from another graph's nodes of the same names
    (seen: a refused ``run --processes`` waited the full drain limit for them)."""
    from mechsim.ros.process import NOTHING_PUBLISHED, drain
    from mechsim.ros.processes import _published_any

    class Executor:
        spins = 0

        def spin_once(self, timeout_sec: float) -> None:
            self.spins += 1

    (tmp_path / "system0.json").write_text('{"samples": 0}')
    (tmp_path / "diagnostics.json").write_text('{"samples": 5}')  # not a simulator's
    assert not _published_any(str(tmp_path))
    (tmp_path / "system1.json").write_text('{"samples": 3}')
    assert _published_any(str(tmp_path))
    (tmp_path / "system1.json").write_text("{trunc")
    assert _published_any(str(tmp_path))  # unreadable: drained, to be safe

    report = str(tmp_path / "recorder.json")
    spinning = Executor()
    drain(spinning, lambda: 0, report)
    assert spinning.spins > 0  # no marker: spins until nothing arrives
    (tmp_path / NOTHING_PUBLISHED).touch()
    idle = Executor()
    drain(idle, lambda: 0, report)
    assert idle.spins == 0



_STUCK_TEARDOWN = """
import sys, threading
from mechsim.ros.process import bounded_teardown
with bounded_teardown("the test's teardown", lambda: 7, limit=float(sys.argv[1])):
    if sys.argv[2] == "stuck":
        threading.Event().wait()  # what a DDS deadlock looks like from Python: never returns
    elif sys.argv[2] == "stuck holding the lock":
        # a C call that never returns and keeps the interpreter lock (as rclpy's destruction
        # of a publisher in a Fast DDS deadlock): pause(2) called through ctypes.PyDLL
        import ctypes
        ctypes.PyDLL(None).pause()
print("went on", flush=True)
sys.exit(3)
"""


@pytest.mark.parametrize("block", ["stuck", "stuck holding the lock", "returns"])
def test_a_stuck_teardown_ends_the_process(block: str) -> None:
    """A node process whose DDS teardown never returns (Fast DDS can deadlock there) ends
    with the status it was given and one line saying why; stuck in a call that holds the
    interpreter lock (no Python thread can run), it ends with status 1 and nothing on stderr;
    a teardown that returns goes on."""
    limit = "600" if block == "returns" else "0.5"
    r = subprocess.run([sys.executable, "-c", _STUCK_TEARDOWN, limit, block],
                       capture_output=True, text=True, timeout=300)
    if block == "stuck holding the lock":
        assert (r.returncode, r.stdout, r.stderr) == (1, "", "")
    elif block == "stuck":
        assert r.returncode == 7 and "went on" not in r.stdout
        assert r.stderr.strip().splitlines() == [
            "mechsim: the test's teardown did not return within 0.5 s (DDS teardown stuck); "
            "exiting"]
    else:
        assert (r.returncode, r.stdout, r.stderr) == (3, "went on\n", "")
