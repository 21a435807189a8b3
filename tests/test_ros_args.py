"""``--ros-args`` on mechsim's node executables and on ``mechsim run|record``, handled by rcl
itself (rclpy's ``init(args=...)``), without any ``ros2`` command: remaps, ``-p``, params files
with node names and ``/**`` wildcards, ``--log-level``; a simulator started alone is configured
entirely by its ROS parameters, and what it is given either takes effect or is refused."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import Any

import yaml

from mechsim_msgs.msg import SystemInfo
from rosuser import DEADLINE, Listener, finished, mechsim_command, output, process


def _env(**extra: str) -> dict[str, str]:
    return {**os.environ, "MECHSIM_GRAPH_WAIT": "0", **extra}


def _info(listener: Listener, topic: str) -> dict[str, Any]:
    from mechsim.ros.outlet import LATCHED_QOS

    infos = listener.listen(topic, SystemInfo, LATCHED_QOS)
    listener.wait(lambda: infos, f"{topic} received")
    return {"instance": infos[-1].instance, "system": infos[-1].system,
            **yaml.safe_load(infos[-1].parameters_yaml)}


def test_simulator_alone_is_configured_by_its_parameters(ros_context: Any) -> None:
    """The issue's command, without ros2: namespace remapped, system and mass given."""
    from sensor_msgs.msg import JointState

    listener = Listener(ros_context)
    states = listener.listen("/demo/state", JointState)
    cmd = mechsim_command("simulator", "--ros-args", "-r", "__ns:=/demo", "-p",
                          "system:=pendulum", "-p", "mass:=2.0", "-p", "initial.angle:=0.5")
    try:
        with process(cmd, _env()) as p:
            info = _info(listener, "/demo/system_info")
            assert info["instance"] == "demo" and info["system"] == "pendulum"
            assert info["mass"] == 2.0 and info["initial.angle"] == 0.5
            listener.wait(lambda: len(states) >= 5, "/demo/state published")
            assert states[0].name == ["angle"]
            assert p.poll() is None
    finally:
        listener.close()


def test_the_installed_executable_ends_at_its_duration(ros_context: Any) -> None:
    """``lib/mechsim/simulator`` of the package prefix (what ``ros2 run`` starts), kepler
    from a params file keyed by the node's name, a rate from a ``/**`` wildcard, and the
    duration: it ends by itself, status 0, having published every sample of it.

    The node waits for nobody, so it starts slow (2 s at 0.01× real time) and is sped up
    with ``mechsim param set`` once its latched system_info has arrived: on a loaded
    machine the test's subscription may match later than a fast run lasts."""
    from ament_index_python.packages import get_package_prefix
    from sensor_msgs.msg import JointState

    exe = Path(get_package_prefix("mechsim")) / "lib" / "mechsim" / "simulator"
    assert os.access(exe, os.X_OK), exe
    params = Path(os.environ.get("TMPDIR", "/tmp")) / f"mechsim_params_{os.getpid()}.yaml"
    params.write_text(yaml.safe_dump({
        "/**": {"ros__parameters": {"publish_rate": 50.0}},
        "/orbit/simulator": {"ros__parameters": {
            "system": "kepler", "eccentricity": 0.3, "duration": 2.0,
            "real_time_factor": 0.01}}}))
    listener = Listener(ros_context)
    states = listener.listen("/orbit/state", JointState)
    try:
        with process([str(exe), "--ros-args", "-r", "__ns:=/orbit", "--params-file",
                      str(params)], _env()) as p:
            try:
                info = _info(listener, "/orbit/system_info")
            except AssertionError as e:  # what the node said, to tell a stall from a failure
                raise AssertionError(f"{e}; the node wrote: {output(p)[-3000:]!r}") from None
            assert info["system"] == "kepler" and info["eccentricity"] == 0.3
            sped = subprocess.run(mechsim_command(
                "param", "set", "/orbit/simulator", "real_time_factor", "5", "--timeout",
                str(DEADLINE)), env=_env(), capture_output=True, text=True, timeout=DEADLINE)
            assert sped.returncode == 0, sped.stderr
            status, said = finished(p)
            assert status == 0, said
        def stamps() -> list[int]:
            return [s.header.stamp.sec * 10**9 + s.header.stamp.nanosec for s in states]

        # The last sample at t = 2 s (stamped 1 s + t); every sample matched after the
        # system_info, the test's subscription having matched before it.
        listener.wait(lambda: stamps() and stamps()[-1] == 3 * 10**9, "the sample at t = 2 s")
        grid = {10**9 + k * 20_000_000 for k in range(101)}  # 50 Hz
        assert set(stamps()) <= grid and len(stamps()) == len(set(stamps()))
    finally:
        params.unlink()
        listener.close()


def _refused(*args: str) -> str:
    """The one error line of a refused command (exit status 2); rcl's own warnings and a
    verb's progress line may come before it."""
    out = subprocess.run(mechsim_command(*args), env=_env(), capture_output=True, text=True,
                         timeout=DEADLINE)
    assert out.returncode == 2, (out.returncode, out.stderr)
    lines = out.stderr.strip().splitlines()
    errors = [line for line in lines if line.startswith("mechsim: error: ")]
    assert len(errors) == 1 and lines[-1] == errors[0], out.stderr
    assert "Traceback" not in out.stderr
    return errors[0]


def test_what_a_simulator_is_given_takes_effect_or_is_refused() -> None:
    line = _refused("simulator", "--ros-args", "-p", "masss:=2.0")
    assert "masss: not a parameter of /pendulum/simulator (did you mean mass?)" in line
    assert "mass: must be > 0" in _refused("simulator", "--ros-args", "-p", "mass:=-1.0")
    assert "unknown system 'pendulumm'" in _refused("simulator", "--ros-args", "-p",
                                                    "system:=pendulumm")
    assert "formulation: must be one of reduced, multiplier" in _refused(
        "simulator", "--ros-args", "-p", "formulation:=polar")
    assert "real_time_factor: must be > 0" in _refused(
        "simulator", "--ros-args", "-p", "real_time_factor:=0.0")
    assert "namespace" in _refused("simulator", "--ros-args", "-r", "__ns:=/a/b")
    assert "--ros-args: Couldn't parse parameter override rule" in _refused(
        "simulator", "--ros-args", "-p", "mass")
    assert "--instance: with --scene" in _refused("simulator", "--instance", "x")


def test_log_level_reaches_rcl() -> None:
    out = subprocess.run(mechsim_command("simulator", "--ros-args", "-p", "duration:=0.05",
                                         "--log-level", "debug"),
                         env=_env(), capture_output=True, text=True, timeout=DEADLINE)
    assert out.returncode == 0, out.stderr
    assert "[DEBUG]" in out.stderr


def _bag_parameters(bag: Path, instance: str) -> dict[str, Any]:
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())
    custom = meta["rosbag2_bagfile_information"]["custom_data"]
    return yaml.safe_load(custom[f"mechsim.{instance}.parameters"])


def test_run_and_record_hand_their_ros_args_to_rcl(tmp_path: Path) -> None:
    """``mechsim run|record ... --ros-args -p``: the model runs the given values (its
    recording says so); ``--processes`` hands them to every node process."""
    for verb, extra in (("run", ("--fast",)), ("record", ()), ("run", ("--processes", "--fast"))):
        bag = tmp_path / f"bag_{verb}_{len(extra)}"
        out = subprocess.run(mechsim_command(verb, "pendulum", *extra, "--duration", "0.5",
                                             "--bag", str(bag), "--ros-args", "-p",
                                             "mass:=2.0", "-p", "initial.angle:=0.25"),
                             env=_env(), capture_output=True, text=True, timeout=DEADLINE)
        assert out.returncode == 0, (verb, extra, out.stderr)
        values = _bag_parameters(bag, "pendulum")
        assert values["mass"] == 2.0 and values["initial.angle"] == 0.25, (verb, extra)


def test_run_of_one_system_takes_a_namespace_remap(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    out = subprocess.run(mechsim_command("run", "kepler", "--fast", "--duration", "0.2",
                                         "--bag", str(bag), "--ros-args", "-r", "__ns:=/orbit"),
                         env=_env(), capture_output=True, text=True, timeout=DEADLINE)
    assert out.returncode == 0, out.stderr
    topics = {t["topic_metadata"]["name"] for t in yaml.safe_load(
        (bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"][
            "topics_with_message_count"]}
    assert {"/orbit/state", "/orbit/system_info", "/orbit/markers"} <= topics, topics
    assert not any(t.startswith("/kepler/") for t in topics), topics
    two = tmp_path / "two.yaml"
    two.write_text("systems:\n  - {system: pendulum}\n  - {system: kepler}\n")
    assert "two simulator nodes named /x/simulator" in _refused(
        "run", str(two), "--fast", "--duration", "0.1", "--ros-args", "-r", "__ns:=/x")
    assert "masss: not a parameter of any node of the scene" in _refused(
        "run", str(two), "--fast", "--duration", "0.1", "--ros-args", "-p", "masss:=1.0")
