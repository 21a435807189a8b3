"""A multi-process run whose simulator process hangs in its start-up (as a process stuck in
the DDS library while it makes its node) is stopped with a one-line reason, not waited for
forever."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

from mechsim.ros import processes
from mechsim.scene import parse_scene


def _blocked() -> subprocess.Popen[bytes]:
    """A child that never gets further: it reads its standard input, which stays open."""
    return subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"],
                            stdin=subprocess.PIPE)


def test_a_simulator_that_never_starts_stops_the_run(monkeypatch: Any, tmp_path: Any,
                                                     capsys: Any) -> None:
    scene = parse_scene({"name": "two", "systems": [{"system": "pendulum", "name": "a"},
                                                    {"system": "pendulum", "name": "b"}]})
    children = processes._Children(str(tmp_path), scene)
    children.sims = [_blocked(), _blocked()]
    # "a" started (its process made the file beside its report), "b" did not
    open(processes.started_file(os.path.join(str(tmp_path), "system0.json")), "x").close()
    monkeypatch.setattr(processes, "START_DEADLINE", 0.5)
    try:
        watching = threading.Thread(target=children.watch, daemon=True)
        watching.start()
        watching.join(120.0)  # (a watch that waits for ever fails here)
        assert not watching.is_alive()
        assert children.status == 1
        assert [p.poll() for p in children.sims] == [None, None]  # watch only decides
        err = capsys.readouterr().err.strip()
        assert err == ("mechsim: b: the simulator process did not start within 0.5 s (hung "
                       "in its start-up); stopping the run")
    finally:
        for p in children.sims:
            p.kill()
            p.wait()


def test_started_simulators_are_waited_for(monkeypatch: Any, tmp_path: Any) -> None:
    """Past the deadline, simulators that started are still waited for until they end."""
    scene = parse_scene({"name": "one", "systems": [{"system": "pendulum", "name": "a"}]})
    children = processes._Children(str(tmp_path), scene)
    p = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.read()"],
                         stdin=subprocess.PIPE)
    children.sims = [p]
    open(processes.started_file(os.path.join(str(tmp_path), "system0.json")), "x").close()
    monkeypatch.setattr(processes, "START_DEADLINE", 0.0)
    assert p.stdin is not None
    p.stdin.close()  # the child ends (as a run that reached its duration)
    children.watch()
    assert children.status == 0 and p.wait() == 0


def test_a_simulator_process_says_it_started(ros_env: dict[str, str], tmp_path: Any) -> None:
    """A simulator process of a scene makes the file beside its report (``started_file``) once
    it steps, which is what the parent's start deadline looks for."""
    import json

    from mechsim.scene import scene_data

    scene = parse_scene({"name": "one", "pacing": "fast", "duration": 0.1,
                         "systems": [{"system": "pendulum", "name": "a"}]})
    scene_file = tmp_path / "scene.json"
    scene_file.write_text(json.dumps(scene_data(scene)))
    report = str(tmp_path / "system0.json")
    r = subprocess.run([sys.executable, "-m", "mechsim.cli", "simulator", "--scene",
                        str(scene_file), "--instance", "a", "--report", report],
                       env=ros_env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert os.path.exists(processes.started_file(report))
    assert json.loads(Path(report).read_text())["samples"] == 11
