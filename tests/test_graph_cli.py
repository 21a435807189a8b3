"""The ros2-style verbs for users without a ROS install, against a running simulator in another
process: `node list`, `param list|get|set`, `service call`; and every verb's `--help`."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest

from mechsim.cli import NODE_VERBS, VERBS, build_parser

MECHSIM = [sys.executable, "-m", "mechsim.cli"]
NODE = "/pendulum/simulator"


def mechsim(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*MECHSIM, *args], env=env, capture_output=True, text=True,
                          timeout=300)


def _subcommands() -> list[list[str]]:
    """Every verb and sub-verb the parser knows, read from the parser itself."""
    import argparse

    out: list[list[str]] = []

    def walk(parser: argparse.ArgumentParser, prefix: list[str]) -> None:
        out.append(prefix)
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    walk(sub, [*prefix, name])

    walk(build_parser(), [])
    return out


def test_the_parser_knows_every_verb() -> None:
    assert {c[0] for c in _subcommands() if c} == set(VERBS) | set(NODE_VERBS)


def test_help_lists_only_the_verbs_users_run(ros_env: dict[str, str]) -> None:
    import re

    r = mechsim(["--help"], ros_env)
    usage = re.search(r"\{([a-z,]+)\}", r.stdout)
    assert usage is not None and usage.group(1).split(",") == list(VERBS), r.stdout
    assert set(re.findall(r"^    (\w+)", r.stdout, re.MULTILINE)) == set(VERBS), r.stdout


@pytest.mark.parametrize("argv", _subcommands(), ids=lambda c: " ".join(c) or "mechsim")
def test_every_help_works(argv: list[str], ros_env: dict[str, str]) -> None:
    r = mechsim([*argv, "--help"], ros_env)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("usage: mechsim") and "Traceback" not in r.stderr


@pytest.fixture(scope="module")
def running_pendulum(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, str]]:
    env = dict(os.environ)  # this run's ROS settings (conftest sets profile and domain)
    proc = subprocess.Popen([*MECHSIM, "run", "pendulum", "--duration", "1e6"], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            cwd=tmp_path_factory.mktemp("run"))
    try:
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline:  # a condition, polled: the node in the graph
            assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
            if NODE in mechsim(["node", "list"], env).stdout.split():
                break
        else:
            pytest.fail(f"{NODE} did not appear in the graph")
        yield env
    finally:
        proc.terminate()
        proc.wait(timeout=60)


def test_node_list_shows_the_simulator(running_pendulum: dict[str, str]) -> None:
    """Listed within a discovery wait a loaded machine allows (asked again until a generous
    deadline: discovery of a node already running can take longer than one wait)."""
    deadline = time.monotonic() + 120.0
    while True:
        r = mechsim(["node", "list", "--wait", "3"], running_pendulum)
        assert r.returncode == 0, r.stderr
        if NODE in r.stdout.split() or time.monotonic() > deadline:
            break
    assert NODE in r.stdout.split(), r.stdout


def test_param_list_get_set(running_pendulum: dict[str, str]) -> None:
    env = running_pendulum
    listed = mechsim(["param", "list", NODE], env)
    assert listed.returncode == 0, listed.stderr
    names = {line.split(":")[0].strip() for line in listed.stdout.splitlines()}
    assert {"mass", "length", "gravity", "initial.angle", "method", "tolerance"} <= names
    assert mechsim(["param", "get", NODE, "length"], env).stdout.strip() == "1.0"
    done = mechsim(["param", "set", NODE, "length", "2"], env)  # an int for a double: 2.0
    assert done.returncode == 0, done.stderr
    assert mechsim(["param", "get", NODE, "length"], env).stdout.strip() == "2.0"


def test_rejected_set_is_one_line_with_the_nodes_reason(running_pendulum: dict[str, str]) -> None:
    r = mechsim(["param", "set", NODE, "mass", "-1"], running_pendulum)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and "mass" in r.stderr
    assert mechsim(["param", "get", NODE, "mass"], running_pendulum).stdout.strip() == "1.0"


@pytest.mark.parametrize("argv,field", [
    (["param", "get", NODE, "colour"], "colour"),
    (["param", "set", NODE, "mass", "1" * 400], "value"),
    (["param", "set", NODE, "mass", ".nan"], "value"),
    (["param", "get", "/nobody/here", "mass", "--timeout", "1"], "/nobody/here"),
    (["service", "call", NODE, "pause", "maybe"], "value"),
])
def test_bad_requests_are_one_line(running_pendulum: dict[str, str], argv: list[str],
                                   field: str) -> None:
    r = mechsim(argv, running_pendulum)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1 and field in r.stderr


def test_services_pause_and_reset(running_pendulum: dict[str, str]) -> None:
    env = running_pendulum
    for argv in (["pause", "true"], ["pause", "false"], ["reset"]):
        r = mechsim(["service", "call", NODE, *argv], env)
        assert r.returncode == 0, r.stderr
        assert r.stdout.startswith(f"{argv[0]}: success")
