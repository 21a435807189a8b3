"""What the launch files start, without any ros2 command: the node executables alone, each
configured by ``--ros-args`` (``mechsim NAME`` is what ``lib/mechsim/NAME`` runs), and the
documented ``mechsim`` commands that run the launch files' scenes."""

from __future__ import annotations

import math
import os
import subprocess
from pathlib import Path
from typing import Any

import yaml

from rosuser import DEADLINE, ROOT, finished, mechsim_command, process


def _bag(bag: Path) -> dict[str, list[Any]]:
    from rosbags.highlevel import AnyReader

    got: dict[str, list[Any]] = {}
    with AnyReader([bag]) as reader:
        for con, _, data in reader.messages():
            got.setdefault(con.topic, []).append(reader.deserialize(data, con.msgtype))
    return got


def test_simulator_diagnostics_and_recorder_alone(tmp_path: Path) -> None:
    """As recorder.launch.py starts them: the simulator waits for the recorder, ends at its
    duration; the diagnostics node checks it; the recorder, stopped, completes a bag with
    every sample and the diagnostics' verdicts."""
    bag = tmp_path / "bag"
    env = {**os.environ, "MECHSIM_GRAPH_WAIT": "0"}
    with process(mechsim_command("recorder", "--ros-args", "-p", f"bag:={bag}"), env), \
            process(mechsim_command("diagnostics", "--ros-args", "-p", "period:=0.5"), env):
        with process(mechsim_command(
                "simulator", "--ros-args", "-r", "__ns:=/spring", "-p",
                "system:=spring_pendulum", "-p", "duration:=4.0", "-p",
                "real_time_factor:=2.0", "-p", "wait_for_recorder:=true"), env) as sim:
            status, said = finished(sim)
            assert status == 0, said
    got = _bag(bag)
    assert len(got["/spring/state"]) == 401  # 0 … 4 s at 100 Hz: waited for, none lost
    assert got["/spring/markers"] and got["/spring/system_info"] and got["/tf"]
    assert len(got["/spring/markers_static"]) == 1  # latched: the recorder got it once
    verdicts = {s.name: s.level for d in got["/diagnostics"] for s in d.status}
    assert verdicts and all(level == 0 for name, level in verdicts.items()
                            if name.startswith("mechsim/spring/")), verdicts


def test_the_swing_up_without_a_ros_install(tmp_path: Path) -> None:
    """docs/ros2.md's commands for swing_up.launch.py: the scene run by ``mechsim run``, the
    controller executable beside it in the pendulum's namespace."""
    bag = tmp_path / "bag"
    with process(mechsim_command("swing_up_controller", "--ros-args", "-r", "__ns:=/pendulum"),
                 os.environ):
        out = subprocess.run(mechsim_command("run", str(ROOT / "scenes" / "swing_up.yaml"),
                                             "--duration", "12", "--bag", str(bag)),
                             capture_output=True, text=True, timeout=DEADLINE * 2)
    assert out.returncode == 0, out.stderr
    got = _bag(bag)
    last = [s.position[0] for s in got["/pendulum/state"][-100:]]
    assert all(abs(math.remainder(a - math.pi, 2 * math.pi)) < 0.05 for a in last), last[-5:]
    assert got["/pendulum/effort"]  # the controller's input, recorded with the samples
    assert yaml.safe_load(got["/pendulum/system_info"][-1].parameters_yaml)["mass"] == 1.0
