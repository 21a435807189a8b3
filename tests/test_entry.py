"""One scene object and one entry point: a start parses its scene once and builds each
instance's model once; the node processes of ``run --processes`` receive the parsed scene as
data; every process goes through ``mechsim`` with the same exit statuses, and an error that is
not the user's is said to be an internal one."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

PY = sys.executable

#: Runs ``mechsim`` (argv after the script name) counting parses, YAML reads and model
#: constructions; prints the counts as JSON on the last line of stdout.
COUNTING = """if True:
    import json, sys
    import mechsim.scene as scene
    from mechsim.systems.base import Model
    counts = {"parse_scene": 0, "parse_instance": 0, "load_yaml": 0, "models": 0}

    def counted(name, f):
        def g(*a, **k):
            counts[name] += 1
            return f(*a, **k)
        return g

    for name in ("parse_scene", "parse_instance", "load_yaml"):
        setattr(scene, name, counted(name, getattr(scene, name)))
    init = Model.__init__

    def model_init(self, **kw):
        counts["models"] += 1
        init(self, **kw)

    Model.__init__ = model_init
    from mechsim.cli import main
    code = main(sys.argv[1:])
    print(json.dumps(counts))
    sys.exit(code)
"""

SCENE = {"name": "two", "publish_rate": 20.0, "systems": [
    {"system": "pendulum", "name": "a"}, {"system": "pendulum", "name": "b",
                                          "parameters": {"formulation": "multiplier"}}]}


def _counted(args: list[str], env: dict[str, str], cwd: Path) -> tuple[Any, dict[str, int]]:
    r = subprocess.run([PY, "-c", COUNTING, *args], env=env, cwd=cwd, capture_output=True,
                       text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    return r, json.loads(r.stdout.strip().splitlines()[-1])


def test_a_start_parses_its_scene_once_and_builds_each_model_once(
        ros_env: dict[str, str], tmp_path: Path) -> None:
    import yaml

    (tmp_path / "two.yaml").write_text(yaml.safe_dump(SCENE))
    env = dict(ros_env, MECHSIM_GRAPH_WAIT="0")
    r, counts = _counted(["run", "two.yaml", "--set", "a:mass=2", "--set", "gravity=9",
                          "--fast", "--duration", "0.5"], env, tmp_path)
    # The file and each --set value read once; the scene and each instance parsed once;
    # each instance's model built once (the scene's validation), then handed to its node.
    assert counts == {"parse_scene": 1, "parse_instance": 2, "load_yaml": 3, "models": 2}
    assert re.search(r"^  a\s+energy\s", r.stdout, re.MULTILINE), r.stdout


def test_a_reset_keeps_the_model(ros_context: Any) -> None:
    from rclpy.parameter import Parameter
    from std_srvs.srv import Trigger

    from mechsim.ros.simulator import SimulatorNode
    from mechsim.scene import single_system_scene

    inst = single_system_scene("pendulum").systems[0]
    node = SimulatorNode(inst, context=ros_context, real_time_factor=0.0)
    try:
        assert node.model is inst.build()  # the one the scene built
        node.advance_to(0.2)
        node._on_reset(Trigger.Request(), Trigger.Response())
        assert node.t == 0.0 and node.model is inst.build()
        assert node.set_parameters([Parameter("gravity", value=3.0)])[0].successful
        node._on_reset(Trigger.Request(), Trigger.Response())
        assert node.model.value("gravity") == 3.0  # a changed model is kept as changed
    finally:
        node.destroy_node()


def test_node_processes_receive_the_parsed_scene(monkeypatch: pytest.MonkeyPatch,
                                                 tmp_path: Path) -> None:
    """``run --processes`` hands its children the scene it parsed, as data: no target, no
    --set, no option of the command line to parse again; read back, it is the same scene,
    and reading it parses nothing."""
    import mechsim.scene as scene_module
    from mechsim.ros import processes
    from mechsim.scene import scene_data, scene_from_data, scene_from_target

    path = tmp_path / "two.yaml"
    path.write_text(json.dumps(SCENE))  # (JSON is YAML)
    scene = scene_from_target(str(path), ["a:mass=2"])
    scene.duration, scene.pacing = 1.5, "fast"
    spawned: list[tuple[list[str], Any]] = []

    class Child:
        returncode = 0

        def __init__(self, argv: list[str], **kw: Any) -> None:
            data = json.loads(Path(argv[argv.index("--scene") + 1]).read_text())
            spawned.append((argv, data))

        def poll(self) -> int:
            return 0

        def wait(self, timeout: float | None = None) -> int:
            return 0

    monkeypatch.setattr(processes.subprocess, "Popen", Child)
    run, lines, status = processes.run_processes(scene, bag="out_bag")
    assert status == 0
    kinds = sorted(argv[3] for argv, _ in spawned)
    assert kinds == ["diagnostics", "recorder", "simulator", "simulator"]
    for argv, data in spawned:
        assert argv[:3] == [PY, "-m", "mechsim.cli"]
        assert not any(str(path) in a or "mass" in a or a == "--set" for a in argv), argv
        assert data == {**scene_data(scene), "bag": "out_bag"}

    def refused(*a: Any, **k: Any) -> None:
        raise AssertionError("the scene parsed again")

    monkeypatch.setattr(scene_module, "parse_scene", refused)
    monkeypatch.setattr(scene_module, "parse_instance", refused)
    got = scene_from_data(spawned[0][1])
    assert got == scene.__class__(**{**scene.__dict__, "bag": "out_bag"})
    assert got.systems[0].parameters == {"mass": 2} and got.duration == 1.5


def test_a_node_process_builds_only_its_own_model_once(ros_env: dict[str, str],
                                                       tmp_path: Path) -> None:
    from mechsim.scene import parse_scene, scene_data

    scene = parse_scene({**SCENE, "pacing": "fast", "duration": 0.5})
    (tmp_path / "scene.json").write_text(json.dumps(scene_data(scene)))
    env = dict(ros_env, MECHSIM_GRAPH_WAIT="0")
    report = tmp_path / "report.json"
    _, counts = _counted(["simulator", "--scene", "scene.json", "--instance", "b",
                          "--report", str(report)], env, tmp_path)
    assert counts == {"parse_scene": 0, "parse_instance": 0, "load_yaml": 0, "models": 1}
    assert json.loads(report.read_text())["samples"] == 11


@pytest.mark.parametrize("bad", ["not json", json.dumps({"format": "other"}),
                                 json.dumps({"format": "mechsim-scene/1", "systems": 3})])
def test_a_node_process_refuses_what_is_not_a_scene(bad: str, ros_env: dict[str, str],
                                                    tmp_path: Path) -> None:
    (tmp_path / "scene.json").write_text(bad)
    r = subprocess.run([PY, "-m", "mechsim.cli", "simulator", "--scene", "scene.json",
                        "--instance", "a"], env=ros_env, cwd=tmp_path, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 2 and r.stderr.startswith("mechsim: error: --scene")
    assert len(r.stderr.strip().splitlines()) == 1


#: Runs ``mechsim`` with ``mechsim systems`` raising the exception given as argv[1].
BROKEN = """if True:
    import sys
    import mechsim.cli.systems as verb
    error = eval(sys.argv[1])

    def broken(a):
        raise error

    verb.cmd_systems = broken
    from mechsim.cli import entry
    entry(["systems"])
"""


@pytest.mark.parametrize("error", ['ZeroDivisionError("injected\\nsecond line")',
                                   'RuntimeError("injected")', 'KeyError("injected")'])
def test_an_internal_error_says_so(error: str, ros_env: dict[str, str],
                                   tmp_path: Path) -> None:
    """Not a user's error: exit 1, one line naming it as internal, its type and message and
    the file that holds the traceback (under the user's cache), no traceback on stderr."""
    env = dict(ros_env, XDG_CACHE_HOME=str(tmp_path / "cache"))
    r = subprocess.run([PY, "-c", BROKEN, error], env=env, capture_output=True, text=True,
                       timeout=300)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 1 and len(lines) == 1, r.stderr
    m = re.fullmatch(r"mechsim: internal error: (\w+): (.*) \(traceback in (.+)\)", lines[0])
    assert m is not None, lines[0]
    kind = error.partition("(")[0]
    assert m.group(1) == kind and "injected" in m.group(2)
    file = Path(m.group(3))
    assert file.parent == tmp_path / "cache" / "mechsim" / "errors"
    text = file.read_text()
    assert "Traceback (most recent call last)" in text and f"{kind}: " in text
    assert "in broken" in text and (file.stat().st_mode & 0o077) == 0  # the user's only


def test_an_internal_error_without_a_cache_goes_to_the_temporary_directory(
        ros_env: dict[str, str], tmp_path: Path) -> None:
    blocked = tmp_path / "not_a_directory"
    blocked.write_text("")
    (tmp_path / "tmp").mkdir()
    env = dict(ros_env, XDG_CACHE_HOME=str(blocked), TMPDIR=str(tmp_path / "tmp"))
    r = subprocess.run([PY, "-c", BROKEN, 'OSError("injected")'], env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 1 and "Traceback" not in r.stderr
    written = list((tmp_path / "tmp").iterdir())
    assert len(written) == 1 and str(written[0]) in r.stderr


@pytest.mark.parametrize("error,code", [
    ('__import__("mechsim.errors").errors.ParameterError("field", "a reason")', 2),
    ('__import__("mechsim.environment").environment.RosEnvironmentError("no wheels")', 2),
    ('SystemError("returned a result with an exception set")', 1),
])
def test_each_error_gets_its_exit_status(error: str, code: int, ros_env: dict[str, str],
                                      tmp_path: Path) -> None:
    env = dict(ros_env, XDG_CACHE_HOME=str(tmp_path / "cache"))
    r = subprocess.run([PY, "-c", BROKEN, error], env=env, capture_output=True, text=True,
                       timeout=300)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == code and len(lines) == 1, r.stderr
    assert lines[0].startswith("mechsim: error: " if code == 2 else "mechsim: internal error")
    assert (tmp_path / "cache").exists() == (code == 1)


def test_a_stop_inside_another_exception_is_a_stop(ros_env: dict[str, str]) -> None:
    """Ctrl-C landing in compiled code comes out wrapped: exit 130, quietly."""
    error = ('(lambda: [e for e in [SystemError("wrapped")] '
             'if setattr(e, "__cause__", KeyboardInterrupt()) is None][0])()')
    r = subprocess.run([PY, "-c", BROKEN, error], env=ros_env, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 130 and r.stderr == "", r.stderr


def test_the_node_verbs_validate_before_joining_the_graph(ros_env: dict[str, str],
                                                          tmp_path: Path) -> None:
    """A scene without the instance asked for is refused before ROS starts (no rclpy)."""
    from mechsim.scene import parse_scene, scene_data

    (tmp_path / "scene.json").write_text(json.dumps(scene_data(parse_scene(SCENE))))
    code = """if True:
        import sys
        from mechsim.cli import main
        code = main(["simulator", "--scene", "scene.json", "--instance", "c"])
        assert "rclpy" not in sys.modules
        sys.exit(code)
    """
    r = subprocess.run([PY, "-c", code], env=dict(ros_env, **{"PYTHONPATH": os.environ.get(
        "PYTHONPATH", "")}), cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "instance 'c'" in r.stderr and "instances: a, b" in r.stderr
