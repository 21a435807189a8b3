"""mechsim's pytest plugin, used as a user would: fixtures from the installed entry point, no
launch files, no sleeps. The numbers are checked against physics, not against the plugin."""

from __future__ import annotations

import math
import os
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import pytest


def test_plugin_is_registered(pytestconfig: pytest.Config) -> None:
    assert pytestconfig.pluginmanager.has_plugin("mechsim")


def test_pendulum_in_process(mechsim_graph: Any) -> None:
    mechsim_graph.start("pendulum", **{"initial.angle": 1.0})
    energy = mechsim_graph.collect("/pendulum/energy").wait_for(count=30)
    e0 = energy[0].total
    # E = m g R (1 − cos θ₀) with m = R = 1, g = 9.81, released at rest from θ₀ = 1 rad
    assert e0 == pytest.approx(9.81 * (1 - math.cos(1.0)), rel=1e-9)
    assert max(abs(m.total - e0) for m in energy) < 1e-9 * e0
    mechsim_graph.assert_laws_ok("pendulum")


def test_parameters_and_services(mechsim_graph: Any) -> None:
    from std_srvs.srv import SetBool

    mechsim_graph.start("pendulum", diagnostics=False)
    node = "/pendulum/simulator"
    bad, = mechsim_graph.set_parameters(node, mass=-1.0)
    assert not bad.successful and "mass" in bad.reason
    good, = mechsim_graph.set_parameters(node, mass=2.0)
    assert good.successful
    answer = mechsim_graph.call(f"{node}/pause", SetBool.Request(data=True))
    assert answer.success


def test_system_in_a_child_process(mechsim_graph: Any) -> None:
    mechsim_graph.start("harmonic_oscillator", process=True, diagnostics=False)
    state = mechsim_graph.collect("/harmonic_oscillator/state").wait_for(count=5)
    assert all(len(m.position) == 1 for m in state)


def test_a_timeout_reports_what_arrived_by_the_deadline(mechsim_graph: Any) -> None:
    """The failure names the messages seen when the wait gave up (it named the count at the
    start, always 0 for a new collector: a predicate never met read as "nothing arrived")."""
    mechsim_graph.start("pendulum")
    states = mechsim_graph.collect("/pendulum/state")
    with pytest.raises(pytest.fail.Exception) as failed:
        states.wait_for(predicate=lambda messages: len(messages) >= 3 and False, timeout=5.0)
    first = str(failed.value).splitlines()[0]
    assert f"{len(states.messages)} message(s)" in first and "predicate=given: not met" in first
    assert states.messages  # the pendulum published meanwhile: the count is not 0


def test_workers_get_their_own_domain_and_a_nested_run_keeps_it(tmp_path: Path) -> None:
    """Two xdist workers: two ROS domains. A pytest run started by a test of a worker (it
    inherits ``PYTEST_XDIST_WORKER`` and the worker's domain id) stays on that worker's
    domain; moved again, the nested run of worker gw1 landed on worker gw2's graph, where a
    pendulum of that nested run made another test's refused ``--processes`` run fail. A nested
    run with workers of its own: its gw0 on the worker's domain, its gw1 on none of the outer
    workers' domains (moved as a top-level gw1, the nested gw1 of outer gw0 landed on outer
    gw1's graph)."""
    (tmp_path / "test_outer.py").write_text(textwrap.dedent("""\
        import os, subprocess, sys
        import pytest

        INNER = (
            "import os, pytest\\n"
            "@pytest.mark.parametrize('j', range(2))\\n"
            "def test_in(j):\\n"
            "    with open(os.environ['SEEN'] + f'-{j}', 'w') as f:\\n"
            "        f.write(os.environ.get('PYTEST_XDIST_WORKER', '-') + ' '\\n"
            "                + os.environ['ROS_DOMAIN_ID'])\\n")

        @pytest.mark.parametrize("k", range(4))
        def test_outer(k, tmp_path):
            seen = os.path.abspath("seen")
            with open(f"{seen}/outer-{k}", "w") as f:
                f.write(os.environ["PYTEST_XDIST_WORKER"] + " " + os.environ["ROS_DOMAIN_ID"])
            (tmp_path / "test_in.py").write_text(INNER)
            env = dict(os.environ, SEEN=f"{seen}/inner-{k}")
            workers = ["-n", "2"] if k in (1, 2) else []
            done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p",
                                   "no:cacheprovider", *workers, "test_in.py"],
                                  cwd=tmp_path, env=env)
            assert done.returncode == 0
        """))
    (tmp_path / "seen").mkdir()
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTEST_XDIST_WORKER", "PYTEST_XDIST_WORKER_COUNT",
                        "_MECHSIM_DOMAIN_SET_BY", "_MECHSIM_TAKEN_DOMAINS", "PYTEST_ADDOPTS")}
    env["ROS_DOMAIN_ID"] = "7"
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                          "-n", "2", "test_outer.py"], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]

    def seen(name: str) -> tuple[str, str]:
        worker, domain = (tmp_path / "seen" / name).read_text().split()
        return worker, domain

    outer = {k: seen(f"outer-{k}") for k in range(4)}
    domains = dict(outer.values())
    assert set(domains) == {"gw0", "gw1"}, outer  # xdist hands 4 tests to 2 workers 2 / 2
    assert len(set(domains.values())) == 2, domains  # one domain per worker
    # Tests 1 and 2 (nested runs with workers) went to different workers, in chunks or in turn.
    assert {outer[1][0], outer[2][0]} == {"gw0", "gw1"}, outer
    for k, (_worker, domain) in outer.items():
        inner = [seen(f"inner-{k}-{j}") for j in range(2)]
        if k in (0, 3):  # a plain nested run: on its worker's domain
            assert all(d == domain for _, d in inner), (k, outer, inner)
        else:  # a nested run with two workers (one test each), in either outer worker
            mine = dict(inner)
            assert set(mine) == {"gw0", "gw1"}, inner
            assert mine["gw0"] == domain and mine["gw1"] not in domains.values(), (
                outer, inner)


PROBE_TEST = """\
import json, os
def test_env():
    with open(os.environ["SEEN"], "w") as f:
        json.dump({k: os.environ.get(k) for k in ("ROS_DOMAIN_ID",
                                                 "FASTDDS_DEFAULT_PROFILES_FILE")}, f)
"""


@pytest.mark.parametrize("opt_out", [None, "-p no:mechsim", "ini", "-o"])
def test_the_plugin_can_be_told_to_leave_dds_alone(tmp_path: Path, opt_out: str | None) -> None:
    """By default a pytest session gets the loopback profile and a domain of its own; with
    ``-p no:mechsim`` or the ``mechsim_isolation = false`` option (ini file or ``-o``) it keeps
    the environment's DDS settings: a test against a real robot sees its graph."""
    (tmp_path / "test_probe.py").write_text(PROBE_TEST)
    ini = tmp_path / "pytest.ini"
    ini.write_text("[pytest]\n" + ("mechsim_isolation = false\n" if opt_out == "ini" else ""))
    args = {None: [], "-p no:mechsim": ["-p", "no:mechsim"], "ini": [],
            "-o": ["-o", "mechsim_isolation=false"]}[opt_out]
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTEST_XDIST_WORKER", "PYTEST_XDIST_WORKER_COUNT", "PYTEST_ADDOPTS",
                        "_MECHSIM_DOMAIN_SET_BY", "_MECHSIM_TAKEN_DOMAINS", "ROS_DOMAIN_ID",
                        "FASTDDS_DEFAULT_PROFILES_FILE")}
    env["SEEN"] = str(tmp_path / "seen.json")
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                          "-c", str(ini), *args, "test_probe.py"], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
    import json

    seen = json.loads((tmp_path / "seen.json").read_text())
    if opt_out is None:
        assert seen["ROS_DOMAIN_ID"] is not None
        assert seen["FASTDDS_DEFAULT_PROFILES_FILE"].endswith("fastdds_loopback.xml")
    else:
        assert seen == {"ROS_DOMAIN_ID": None, "FASTDDS_DEFAULT_PROFILES_FILE": None}
