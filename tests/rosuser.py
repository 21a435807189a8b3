"""What the tests of mechsim as a ROS user meets it share: the real ``ros2`` command where one
can be found (a ROS install on PATH, or the tools ``../shared/ros2cli/setup.sh`` builds into
``.ros2tools``, which the test command does where that folder exists), the node executables as
processes, and waiting for messages in the test's own graph (conditions with generous
deadlines, never fixed sleeps)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "ros2cli"
TOOLS = ROOT / ".ros2tools" / "venv" / "bin" / "ros2"
#: Generous deadline of every wait [s]: a loaded machine is slow, a condition ends it early.
DEADLINE = 120.0


def ros2_environment() -> tuple[dict[str, str] | None, str]:
    """(the environment in which ``ros2`` runs against this checkout, or None; why not)."""
    env = dict(os.environ)
    if shutil.which("ros2", path=env.get("PATH")):
        return env, ""
    if not TOOLS.exists():
        return None, ("no ros2 command: none on PATH, and none built from ../shared/ros2cli "
                      "(tools/test_tools.sh builds it where that folder exists)")
    if not (SHARED / "env.sh").exists():
        return None, f"{TOOLS} exists but {SHARED}/env.sh, which sets it up, does not"
    out = subprocess.run(["bash", "-c", f'. "{SHARED}/env.sh" "{ROOT}" >/dev/null && env -0'],
                         env=env, capture_output=True, check=False)
    if out.returncode != 0:
        return None, f"{SHARED}/env.sh failed: {out.stderr.decode()[-200:]}"
    made = dict(item.split("=", 1) for item in out.stdout.decode().split("\0") if "=" in item)
    # This session's graph, not env.sh's defaults.
    for key in ("ROS_DOMAIN_ID", "FASTDDS_DEFAULT_PROFILES_FILE"):
        made[key] = os.environ[key]
    return made, ""


@pytest.fixture(scope="session")
def ros2_env() -> dict[str, str]:
    """The environment of the real ``ros2`` command (the test skips, saying why, without)."""
    env, why = ros2_environment()
    if env is None:
        pytest.skip(why)
    return env


def ros2(env: dict[str, str], *args: str, timeout: float = DEADLINE,
         check: bool = True) -> subprocess.CompletedProcess[str]:
    """``ros2 ARGS`` run to its end; its output (an error with it if it failed and ``check``)."""
    out = subprocess.run(["ros2", *args], env=env, capture_output=True, text=True,
                         timeout=timeout, check=False)
    if check and out.returncode != 0:
        raise AssertionError(f"ros2 {' '.join(args)} exited {out.returncode}:\n{out.stdout}\n"
                             f"{out.stderr}")
    return out


def graph_verb(verb: str, *args: str) -> list[str]:
    """A ``ros2`` graph verb's arguments that discover without the daemon."""
    return [*verb.split(), "--no-daemon", "--spin-time", "3", *args]


def until(check: Callable[[], Any], what: str, timeout: float = DEADLINE) -> Any:
    """``check()`` again until it returns something true; that value (AssertionError naming
    ``what`` at the deadline)."""
    end = time.monotonic() + timeout
    while True:
        got = check()
        if got:
            return got
        if time.monotonic() > end:
            raise AssertionError(f"not within {timeout:g} s: {what}")


def mechsim_command(*args: str) -> list[str]:
    return [sys.executable, "-m", "mechsim.cli", *args]


@contextmanager
def process(cmd: list[str], env: dict[str, str], cwd: Path | None = None
            ) -> Iterator[subprocess.Popen[str]]:
    """``cmd`` running for the block; stopped with SIGINT (as launch stops a node) after it."""
    p = subprocess.Popen(cmd, env=env, cwd=cwd, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        yield p
    finally:
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
            try:
                p.wait(timeout=60)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        for stream in (p.stdout, p.stderr):
            if stream is not None:
                stream.close()


def finished(p: subprocess.Popen[str], timeout: float = DEADLINE) -> tuple[int, str, str]:
    """(status, stdout, stderr) of ``p`` once it ended by itself."""
    out, err = p.communicate(timeout=timeout)
    return p.returncode, out, err


class Listener:
    """Messages of some topics, in the test's own graph (a node on ``context``)."""

    def __init__(self, context: Any) -> None:
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        self.node = Node("ros_user_test", context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.got: dict[str, list[Any]] = {}

    def listen(self, topic: str, msg_type: Any, qos: Any = None) -> list[Any]:
        from mechsim.ros.outlet import STATE_QOS

        received = self.got.setdefault(topic, [])
        self.node.create_subscription(msg_type, topic, received.append, qos or STATE_QOS)
        return received

    def wait(self, done: Callable[[], Any], what: str, timeout: float = DEADLINE) -> Any:
        def check() -> Any:
            self.executor.spin_once(timeout_sec=0.05)
            return done()
        return until(check, what, timeout)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
