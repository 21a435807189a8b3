"""Run settings go by the names of the nodes' ROS parameters everywhere: ``--set`` (several
after one), scene files, ``mechsim.load_system``/``simulate`` and ``param set`` all take
``method``, ``tolerance``, ``publish_rate`` and the others, and honour them: checked in what
the run did (the bag's integrator, tolerance and sample times; simulate's result), not in
what it was told."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import mechsim
from mechsim.errors import ParameterError
from mechsim.scene import parse_scene

MECHSIM = [sys.executable, "-m", "mechsim.cli"]
SETS = ["--set", "method=dop853", "tolerance=1e-10", "publish_rate=50"]


def _cli(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*MECHSIM, *args], env=env, capture_output=True, text=True,
                          timeout=300)


def _what_ran(bag: Path) -> tuple[str, float, np.ndarray]:
    """(integrator, tolerance, state sample times) recorded in ``bag``."""
    from rclpy.serialization import deserialize_message

    from mechsim.environment import import_rclpy
    from mechsim.outputs.bag import message_class, read_messages
    from mechsim.outputs.messages import DEFAULT_TIME_OFFSET

    import_rclpy()
    info = [deserialize_message(m.data, message_class(m.type_name))
            for m in read_messages(bag, ["/pendulum/system_info"])][-1]
    stamps = np.array([m.log_time for m in read_messages(bag, ["/pendulum/state"])])
    return info.integrator, info.tolerance, stamps / 1e9 - DEFAULT_TIME_OFFSET


@pytest.mark.parametrize("verb", [["run", "--fast"], ["record"]])
def test_set_run_settings_are_honoured(verb: list[str], ros_env: dict[str, str],
                                       tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    r = _cli([verb[0], "pendulum", *verb[1:], "--duration", "1", *SETS, "--bag", str(bag)],
             ros_env)
    assert r.returncode == 0, r.stderr
    integrator, tolerance, t = _what_ran(bag)
    assert integrator == "dop853" and tolerance == 1e-10
    np.testing.assert_allclose(np.diff(t), 1 / 50, rtol=1e-9)
    assert t[-1] == pytest.approx(1.0)


def test_scene_takes_run_settings_by_the_same_names() -> None:
    scene = parse_scene({"publish_rate": 50, "systems": [
        {"system": "pendulum", "name": "keys", "method": "dop853", "tolerance": "1e-9",
         "effort_timeout": 2.0},
        {"system": "pendulum", "name": "inside",
         "parameters": {"method": "radau15", "tolerance": 1e-11, "constraint_limit": 0.1}}]})
    keys, inside = scene.systems
    assert scene.publish_rate == 50.0
    assert (keys.method, keys.tolerance, keys.settings) == ("dop853", 1e-9,
                                                           {"effort_timeout": 2.0})
    assert (inside.method, inside.tolerance, inside.settings) == ("radau15", 1e-11,
                                                                 {"constraint_limit": 0.1})
    assert "method" not in inside.parameters  # a setting, not a model parameter
    with pytest.raises(ParameterError, match=r"systems\[0\]\.parameters\.publish_rate: a "
                       "setting of the whole scene"):
        parse_scene({"systems": [{"system": "pendulum", "parameters": {"publish_rate": 5}}]})
    with pytest.raises(ParameterError, match="given twice"):
        parse_scene({"systems": [{"system": "pendulum", "method": "dop853",
                                  "parameters": {"method": "radau15"}}]})


def test_load_system_and_simulate_take_run_settings() -> None:
    model = mechsim.load_system("pendulum", method="dop853", tolerance=1e-10, publish_rate=50,
                                **{"initial.angle": 1.0})
    run = mechsim.simulate(model, t_end=1.0)
    assert (run.method, run.tolerance) == ("dop853", 1e-10)
    np.testing.assert_allclose(np.diff(run.t), 1 / 50, rtol=1e-12)
    # Given to simulate, they win; a model without settings keeps simulate's defaults.
    run = mechsim.simulate(model, t_end=1.0, output_dt=0.1, method="radau15", tolerance=1e-12)
    assert (run.method, run.tolerance, run.t.size) == ("radau15", 1e-12, 11)
    plain = mechsim.simulate(mechsim.load_system("pendulum"), t_end=0.1)
    assert (plain.tolerance, plain.t.size) == (1e-10, 11)
    with pytest.raises(ParameterError, match="^real_time_factor: a setting of a running node"):
        mechsim.load_system("pendulum", real_time_factor=2.0)
    with pytest.raises(ParameterError, match="^tolerance: must be"):
        mechsim.load_system("pendulum", tolerance=2.0)


def test_param_set_takes_run_settings(mechsim_graph: Any, ros_env: dict[str, str]) -> None:
    from mechsim.outputs.messages import DEFAULT_TIME_OFFSET

    mechsim_graph.start("pendulum", diagnostics=False)
    node = "/pendulum/simulator"
    for name, value in (("method", "dop853"), ("tolerance", "1e-10"), ("publish_rate", "50")):
        r = _cli(["param", "set", node, name, value, "--timeout", "120"], ros_env)
        assert r.returncode == 0, r.stderr
    info = mechsim_graph.collect("/pendulum/system_info").wait_for(
        predicate=lambda ms: bool(ms) and ms[-1].integrator == "dop853"
        and ms[-1].tolerance == 1e-10)
    assert info[-1].integrator == "dop853"

    def stamps(ms: list[Any]) -> list[float]:
        return [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 - DEFAULT_TIME_OFFSET
                for m in ms]

    state = mechsim_graph.collect("/pendulum/state").wait_for(
        predicate=lambda ms: len(ms) >= 5 and np.allclose(np.diff(stamps(ms[-5:])), 1 / 50))
    assert np.allclose(np.diff(stamps(state[-5:])), 1 / 50)
    r = _cli(["param", "set", node, "tolernce", "1e-9", "--timeout", "120"], ros_env)
    assert r.returncode == 2
    assert "did you mean 'tolerance'?" in r.stderr, r.stderr
