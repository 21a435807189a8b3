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

from rosuser import DEADLINE, ROOT, finished, mechsim_command, output, process, until


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


def test_a_simulator_under_the_name_of_a_running_one_is_refused() -> None:
    """A simulator executable started under the name of one that runs (its node made before
    the graph check, never begun): one line naming the running node, exit 2; the running one
    goes on."""
    name = ["--ros-args", "-r", "__ns:=/twin_alone"]
    with process(mechsim_command("simulator", *name), os.environ) as first:
        until(lambda: subprocess.run(mechsim_command("param", "get", "/twin_alone/simulator",
                                                     "system"), capture_output=True,
                                     text=True, timeout=DEADLINE).returncode == 0,
              "the first simulator answers")
        # (two starts at the same moment can both pass: neither answers the other's check)
        with process(mechsim_command("simulator", *name, "-p", "duration:=1.0"),
                     {**os.environ, "MECHSIM_GRAPH_WAIT": "120"}) as second:  # refused once seen
            status, said = finished(second, timeout=DEADLINE * 2)
        assert status == 2, said
        assert said.strip().splitlines() == [
            f"mechsim: error: /twin_alone/simulator is already running on ROS domain "
            f"{os.environ['ROS_DOMAIN_ID']}; stop it or start this node under another name "
            "(-r __ns:=/NAME)"], said
        assert first.poll() is None, output(first)


#: Loaded by every Python process of a test (``sitecustomize`` on PYTHONPATH): once
#: ``rclpy.node`` is imported, each node made or destroyed writes the number of the process's
#: nodes alive after it to ``$MECHSIM_TEST_NODE_LOG/<pid>``.
_NODE_COUNTER = '''
import importlib.abc, importlib.util, os, sys

def _count(module):
    node, made, destroy, alive = module.Node, module.Node.__init__, module.Node.destroy_node, set()
    log = open(os.path.join(os.environ["MECHSIM_TEST_NODE_LOG"], str(os.getpid())), "a")

    def init(self, *args, **kwargs):
        made(self, *args, **kwargs)
        alive.add(id(self))
        log.write(f"{len(alive)}\\n"); log.flush()

    def destroy_node(self):
        if id(self) in alive:
            alive.discard(id(self))
            log.write(f"{len(alive)}\\n"); log.flush()
        return destroy(self)

    node.__init__, node.destroy_node = init, destroy_node

class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name != "rclpy.node":
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        run = spec.loader.exec_module
        spec.loader.exec_module = lambda module: (run(module), _count(module))
        return spec

sys.meta_path.insert(0, _Finder())
'''


def test_a_node_process_keeps_its_dds_participant_from_its_first_node_to_its_last(
        tmp_path: Path) -> None:
    """No node executable (alone, with its graph check, or a child of ``mechsim run
    --processes``) lets its node count fall to 0 before its end: the DDS participant ends
    with a context's last node, and one ending while a launch's other nodes discover it can
    crash the process (SIGSEGV) or deadlock."""
    hook, log = tmp_path / "hook", tmp_path / "nodes"
    hook.mkdir(), log.mkdir()
    (hook / "sitecustomize.py").write_text(_NODE_COUNTER)
    env = {**os.environ, "MECHSIM_GRAPH_WAIT": "0.5", "MECHSIM_TEST_NODE_LOG": str(log),
           "PYTHONPATH": os.pathsep.join([str(hook), os.environ.get("PYTHONPATH", "")])}
    with process(mechsim_command("recorder", "--ros-args", "-p", f"bag:={tmp_path / 'a'}"),
                 env), process(mechsim_command("diagnostics"), env):
        with process(mechsim_command(
                "simulator", "--ros-args", "-p", "duration:=0.5", "-p",
                "wait_for_recorder:=true"), env) as sim:
            status, said = finished(sim)
            assert status == 0, said
    out = subprocess.run(mechsim_command("run", "pendulum", "--processes", "--duration", "0.5",
                                         "--bag", str(tmp_path / "b")),
                         env=env, capture_output=True, text=True, timeout=DEADLINE * 2)
    assert out.returncode == 0, out.stderr
    counts = {f.name: [int(n) for n in f.read_text().split()] for f in log.iterdir()}
    # the three alone, and of the run: its simulator, diagnostics and recorder processes
    assert len([c for c in counts.values() if c]) >= 6, counts
    for pid, seen in counts.items():
        assert 0 not in seen[:-1], f"process {pid}: nodes alive {seen}"


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
