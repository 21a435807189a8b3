"""``mechsim topic list | echo | hz`` against a live graph (the committed bag, replayed in a
loop by another process), and their output formats."""

from __future__ import annotations

import math
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]
MECHSIM = [sys.executable, "-m", "mechsim.cli"]


def test_message_yaml_layout() -> None:
    from mechsim.environment import import_rclpy

    import_rclpy()
    from builtin_interfaces.msg import Time
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Header

    from mechsim.ros.topic_tools import message_yaml

    msg = JointState(header=Header(stamp=Time(sec=1, nanosec=250000000), frame_id="a/b"),
                     name=["x", "true", "k: v"], position=[0.5, -1e-12, math.nan],
                     velocity=[], effort=[2.0])
    text = message_yaml(msg)
    assert text == (
        "header:\n"
        "  stamp:\n"
        "    sec: 1\n"
        "    nanosec: 250000000\n"
        "  frame_id: a/b\n"
        "name:\n"
        "- x\n"
        "- \"true\"\n"
        "- \"k: v\"\n"
        "position:\n"
        "- 0.5\n"
        "- -1e-12\n"
        "- .nan\n"
        "velocity: []\n"
        "effort:\n"
        "- 2.0")
    back = yaml.safe_load(text)
    assert back["name"] == ["x", "true", "k: v"] and back["header"]["frame_id"] == "a/b"


def test_rate_window_statistics() -> None:
    from mechsim.ros.topic_tools import RateWindow, format_hz

    w = RateWindow(window=3)
    assert w.stats() is None
    for t in (0.0, 0.1, 0.3, 0.4, 0.5):  # keeps the last 3 intervals: 0.2, 0.1, 0.1
        w.add(t)
    rate, lo, hi, std, n = w.stats()  # type: ignore[misc]
    assert n == 3 and rate == pytest.approx(3 / 0.4) and (lo, hi) == pytest.approx((0.1, 0.2))
    assert std == pytest.approx(math.sqrt(((0.2 - 0.4 / 3) ** 2 + 2 * (0.1 - 0.4 / 3) ** 2) / 3))
    assert format_hz((100.0, 0.009, 0.011, 0.0005, 100)) == (
        "average rate: 100.000\n\tmin: 0.009s max: 0.011s std dev: 0.00050s window: 100")


@pytest.fixture(scope="module")
def live_graph(ros_env_module: dict[str, str]) -> Any:
    proc = subprocess.Popen([*MECHSIM, "replay", str(REPO / "bags" / "reference"), "--loop",
                             "--delay", "0"], env=ros_env_module, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    yield proc
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()


@pytest.fixture(scope="module")
def ros_env_module() -> dict[str, str]:
    import os

    return dict(os.environ)


def _start(*args: str, env: dict[str, str]) -> subprocess.Popen[str]:
    return subprocess.Popen([*MECHSIM, "topic", *args], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=REPO)


def test_list_echo_hz_on_a_live_graph(live_graph: Any, ros_env_module: dict[str, str]) -> None:
    env = ros_env_module
    procs = {
        "list": _start("list", "-t", "--wait", "4", env=env),
        "echo": _start("echo", "/pendulum/state", "--once", "--timeout", "20", env=env),
        "echo_static": _start("echo", "tf_static", "--count", "3", "--timeout", "20",
                              env=env),
        "echo_clock": _start("echo", "/clock", "--count", "2", "--timeout", "20", env=env),
        "hz": _start("hz", "/pendulum/state", "--duration", "5", "--timeout", "20", env=env),
        "missing": _start("echo", "/no_such_topic", "--timeout", "2", env=env),
    }
    res = {k: (p.communicate(timeout=60), p.returncode) for k, p in procs.items()}
    assert live_graph.poll() is None, live_graph.stderr.read()

    (out, err), rc = res["list"]
    assert rc == 0, err
    lines = out.splitlines()
    assert "/pendulum/state [sensor_msgs/msg/JointState]" in lines
    assert "/tf_static [tf2_msgs/msg/TFMessage]" in lines
    assert "/clock [rosgraph_msgs/msg/Clock]" in lines
    assert lines == sorted(lines)

    (out, err), rc = res["echo"]
    assert rc == 0, err
    assert out.endswith("\n---\n") and out.count("---") == 1
    msg = yaml.safe_load(out.split("---")[0])
    assert msg["name"] == ["angle"] and msg["header"]["frame_id"].startswith("pendulum/")
    assert len(msg["position"]) == 1 and msg["effort"] == []

    (out, err), rc = res["echo_static"]  # transient local: every system's static frames
    assert rc == 0, err
    docs = [yaml.safe_load(d) for d in out.split("\n---\n") if d.strip()]
    assert len(docs) == 3
    assert all(t["header"]["frame_id"] for d in docs for t in d["transforms"])

    (out, err), rc = res["echo_clock"]  # best-effort publisher
    assert rc == 0, err
    clocks = [yaml.safe_load(d)["clock"] for d in out.split("\n---\n") if d.strip()]
    assert len(clocks) == 2 and all(c["sec"] >= 1 for c in clocks)

    (out, err), rc = res["hz"]
    assert rc == 0, err
    rates = [float(ln.split(":")[1]) for ln in out.splitlines()
             if ln.startswith("average rate:")]
    assert rates and rates[-1] == pytest.approx(100.0, rel=0.25)  # 100 Hz at rate 1
    assert any(ln.startswith("\tmin: ") and "std dev:" in ln and "window:" in ln
               for ln in out.splitlines())

    (out, err), rc = res["missing"]
    assert rc == 2 and err.strip().splitlines()[-1].startswith("mechsim: error: topic "
                                                               "/no_such_topic")
    assert "Traceback" not in err


@pytest.mark.parametrize("args, field", [
    (["echo", "/x", "--timeout", "nan"], "--timeout"),
    (["echo", "/x", "--timeout", "inf"], "--timeout"),
    (["echo", "/x", "--duration", "-1"], "--duration"),
    (["echo", "/x", "--count", "0"], "--count"),
    (["hz", "/x", "--timeout", "nan"], "--timeout"),
    (["list", "--wait", "nan"], "--wait"),
])
def test_wall_clock_options_that_would_wait_for_ever_are_refused(
        args: list[str], field: str, ros_env: dict[str, str]) -> None:
    """``--timeout nan`` once waited for ever (no comparison with nan is true): every
    wall-clock option is a finite number of seconds, refused in one line before the graph."""
    r = subprocess.run([*MECHSIM, "topic", *args], env=ros_env, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert r.stderr.startswith(f"mechsim: error: {field}: ") and r.stderr.count("\n") == 1
