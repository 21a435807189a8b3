"""``ros2 launch mechsim FILE.launch.py`` for each launch file of ``launch_scripts/``: its nodes
start and publish (recorded by the launch's own recorder node where it has one, by a bag the
test asks for otherwise), and every launch file describes the scene file ``mechsim run`` reads,
never a second description of it."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest
import yaml

import mechsim
from mechsim.outputs.messages import DEFAULT_TIME_OFFSET
from mechsim.scene import load_scene
from rosuser import DEADLINE, ROOT, ros2

LAUNCH_FILES = sorted(p.name for p in (ROOT / "launch_scripts").glob("*.launch.py"))


def _bag(bag: Path) -> dict[str, list[Any]]:
    from rosbags.highlevel import AnyReader

    got: dict[str, list[Any]] = {}
    with AnyReader([bag]) as reader:
        for con, _, data in reader.messages():
            got.setdefault(con.topic, []).append(reader.deserialize(data, con.msgtype))
    return got


def test_the_launch_files_are_the_ones_documented() -> None:
    assert LAUNCH_FILES == ["default.launch.py", "recorder.launch.py",
                            "side_by_side.launch.py", "swing_up.launch.py"]
    doc = (ROOT / "docs" / "ros2.md").read_text()
    for name in LAUNCH_FILES:
        assert f"ros2 launch mechsim {name}" in doc, name


def test_a_launched_simulator_runs_what_the_scene_says() -> None:
    """The parameters a launch file gives each simulator node are the scene's, as
    ``mechsim run`` parses it (one source: the scene file)."""
    from mechsim.ros.launch_description import simulator_parameters

    scene = load_scene(ROOT / "scenes" / "side_by_side.yaml")
    for i, inst in enumerate(scene.systems):
        p = simulator_parameters(scene, i)
        model = mechsim.load_system(inst.system, **inst.parameters)
        assert p["system"] == inst.system and p["origin"] == list(inst.origin)
        assert {k: p[k] for k in model.values} == model.values
        assert p["publish_rate"] == scene.publish_rate and p["duration"] == scene.duration
        assert p["real_time_factor"] == scene.real_time_factor
        assert p["publish_clock"] == (i == 0)


@pytest.mark.parametrize("launch_file", LAUNCH_FILES)
def test_ros2_launch_starts_nodes_that_publish(launch_file: str, ros2_env: dict[str, str],
                                               tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    out = ros2(ros2_env, "launch", "mechsim", launch_file, "duration:=3", f"bag:={bag}",
               "rrd:=none", timeout=DEADLINE * 2)
    said = out.stdout + out.stderr
    # (ros2 launch exits 0 whatever its processes did: their lines tell)
    assert "Traceback" not in said and "error" not in said.lower(), said
    started = [line for line in said.splitlines() if "process started" in line]
    scene_file = {"default.launch.py": "default.yaml", "side_by_side.launch.py":
                  "side_by_side.yaml", "swing_up.launch.py": "swing_up.yaml"}.get(launch_file)
    instances = ["pendulum"] if scene_file is None else [
        i.name for i in load_scene(ROOT / "scenes" / scene_file).systems]
    controllers = len(instances) if launch_file == "swing_up.launch.py" else 0
    # simulators, diagnostics, controllers, recorder
    assert len(started) == len(instances) + 1 + controllers + 1, said
    assert said.count("process has finished cleanly") == len(started), said
    got = _bag(bag)
    for name in instances:
        # every sample of 3 s at 100 Hz: the recorder was waited for
        states = got[f"/{name}/state"]
        ticks = {round((s.header.stamp.sec - DEFAULT_TIME_OFFSET) * 100
                       + s.header.stamp.nanosec * 1e-7) for s in states}
        missing = sorted(set(range(301)) - ticks)
        assert len(states) == 301 and not missing, (
            f"/{name}/state: {len(states)} samples; missing t/10 ms: {missing[:20]}")
        assert got[f"/{name}/markers"] and got[f"/{name}/system_info"]
        assert len(got[f"/{name}/markers_static"]) == 1
    assert got["/diagnostics"] and got["/clock"]
    if launch_file == "swing_up.launch.py":
        assert got["/pendulum/effort"]  # the controller answered


def test_the_swing_up_launch_holds_the_pendulum_up(ros2_env: dict[str, str],
                                                    tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    ros2(ros2_env, "launch", "mechsim", "swing_up.launch.py", "duration:=12", f"bag:={bag}",
         timeout=DEADLINE * 2)
    got = _bag(bag)
    last = [s.position[0] for s in got["/pendulum/state"][-100:]]
    assert all(abs(math.remainder(a - math.pi, 2 * math.pi)) < 0.05 for a in last), last[-5:]
    infos = got["/pendulum/system_info"]
    assert list(infos[-1].laws) == ["work_balance"]  # under the controller's effort
    levels = {s.name: s.level for d in got["/diagnostics"][-3:] for s in d.status}
    assert levels.get("mechsim/pendulum/work_balance") == 0, levels
    assert yaml.safe_load(infos[-1].parameters_yaml)["initial.angle"] == 0.1
