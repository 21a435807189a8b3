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
import sysconfig
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import pytest

ROOT = Path(__file__).resolve().parents[1]
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
                      "(tools/test_tools.py builds it where that folder exists)")
    # What ../shared/ros2cli/env.sh sets for the tools' venv over this checkout's venv, with
    # the test run's graph (domain, profile) kept.
    tools = TOOLS.parent.parent
    site = sysconfig.get_paths()["purelib"]
    libs = [str(tools / "lib"), str(Path(sys.prefix) / "lib"),
            *sorted(str(p) for p in Path(site).glob("ros_*.libs") if p.is_dir())]
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
    env.update(MECHSIM_PROJECT_SITE=site,
               AMENT_PREFIX_PATH=f"{tools}{os.pathsep}{sys.prefix}",
               LD_LIBRARY_PATH=os.pathsep.join([*libs, env.get("LD_LIBRARY_PATH", "")]),
               PATH=os.pathsep.join([str(tools / "bin"), str(Path(sys.prefix) / "bin"),
                                     env.get("PATH", "")]))
    return env, ""


@pytest.fixture(scope="session")
def ros2_env() -> dict[str, str]:
    """The environment of the real ``ros2`` command (the test skips, saying why, without)."""
    env, why = ros2_environment()
    if env is None:
        pytest.skip(why)
    return env


def ros2(env: dict[str, str], *args: str, timeout: float = DEADLINE,
         check: bool = True) -> subprocess.CompletedProcess[str]:
    """``ros2 ARGS`` run to its end; its output (an error with it if it failed and ``check``).
    It runs in a process group of its own: past ``timeout`` the whole group is stopped
    (``stop_group``), so that nothing it started (a launch's nodes) outlives the test on its
    graph, and the error carries what it printed."""
    with tempfile.TemporaryFile(mode="w+") as out, tempfile.TemporaryFile(mode="w+") as err:
        p = subprocess.Popen(["ros2", *args], env=env, stdout=out, stderr=err, text=True,
                             start_new_session=True)
        try:
            p.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            stop_group(p)
            raise AssertionError(f"ros2 {' '.join(args)} still running after {timeout:g} s; "
                                 f"it printed:\n{_read(out)}\n{_read(err)}") from None
        done = subprocess.CompletedProcess(["ros2", *args], p.returncode, _read(out), _read(err))
    if check and done.returncode != 0:
        raise AssertionError(f"ros2 {' '.join(args)} exited {done.returncode}:\n{done.stdout}"
                             f"\n{done.stderr}")
    return done


def _read(file: IO[str]) -> str:
    file.flush()
    file.seek(0)
    return file.read()


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
    """``cmd`` running for the block, in a process group of its own, its output to a file
    (``output(p)``: a pipe nobody reads would stall it); stopped after the block with SIGINT
    to that group, as Ctrl-C in a terminal stops ``ros2 run`` and its node (and as launch
    stops a node)."""
    log = tempfile.TemporaryFile(mode="w+")
    p = subprocess.Popen(cmd, env=env, cwd=cwd, stdout=log, stderr=subprocess.STDOUT,
                         text=True, start_new_session=True)
    p.log = log  # type: ignore[attr-defined]
    try:
        yield p
    finally:
        stop_group(p)
        log.close()


def stop_group(p: subprocess.Popen[str]) -> None:
    """Stop the process group that ``p`` leads: SIGINT (Ctrl-C), SIGKILL if ``p`` has not
    ended 60 s later; then wait until no process of the group is left."""
    try:
        os.killpg(p.pid, signal.SIGINT)
    except ProcessLookupError:
        pass  # the whole group has ended already
    try:
        p.wait(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.wait()
    _group_gone(p.pid)


def output(p: subprocess.Popen[str]) -> str:
    """What a ``process`` wrote so far (stdout and stderr)."""
    return _read(p.log)  # type: ignore[attr-defined]


def _group_gone(pgid: int, timeout: float = 60.0) -> None:
    """Wait until no process of group ``pgid`` is left (a child of the stopped process, such
    as the node ``ros2 run`` started, ends on the same SIGINT); SIGKILL at the deadline."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return
        time.sleep(0.05)
    try:
        os.killpg(pgid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def finished(p: subprocess.Popen[str], timeout: float = DEADLINE) -> tuple[int, str]:
    """(status, output) of a ``process`` once it ended by itself."""
    p.wait(timeout=timeout)
    return p.returncode, output(p)


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
