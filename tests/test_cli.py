"""The mechsim command as a user runs it: one-line errors and exit status 2 on bad input,
never a traceback; `systems --json`; a short run prints the conservation table."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

MECHSIM = [sys.executable, "-m", "mechsim.cli"]


def run(args: list[str], env: dict[str, str], timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([*MECHSIM, *args], env=env, capture_output=True, text=True,
                          timeout=timeout)


@pytest.mark.parametrize("args, expected", [
    (["run", "nosuch"], "unknown system 'nosuch'"),
    (["run", "pendulum", "--set", "mass=-1"], "mass: must be > 0"),
    (["run", "pendulum", "--set", "mass=nan"], "mass: must be finite"),
    (["run", "pendulum", "--set", "lenght=2"], "not a parameter"),
    (["run", "pendulum", "--set", "formulation=x"], "formulation: must be one of"),
    (["run", "kepler", "--set", "eccentricity=1.5"], "eccentricity: must be < 1"),
    (["run", "missing_scene.yaml"], "cannot read"),
])
def test_bad_input_is_one_line(args: list[str], expected: str, ros_env: dict[str, str]) -> None:
    r = run(args, ros_env)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("mechsim: error:") and expected in lines[0]


@pytest.mark.parametrize("text, expected", [
    ("systems: [\n  - system: pendulum\n  bad", "not valid YAML"),
    ("systems:\n  - system: pendulum\n    colour: red\n", "systems[0].colour: unknown key"),
    ("systems: []\n", "systems: must be a non-empty list"),
    ("pacing: warp\nsystems:\n  - system: pendulum\n", "pacing: must be realtime or fast"),
    ("systems:\n  - {system: pendulum}\n  - {system: pendulum}\n", "used twice"),
    ("systems:\n  - {system: pendulum, parameters: {length: -2}}\n",
     "systems[0].parameters.length: must be > 0"),
])
def test_bad_scene_is_one_line(text: str, expected: str, tmp_path: Path,
                               ros_env: dict[str, str]) -> None:
    scene = tmp_path / "bad.yaml"
    scene.write_text(text)
    r = run(["run", str(scene)], ros_env)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert expected in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_systems_json(ros_env: dict[str, str]) -> None:
    r = run(["systems", "--json"], ros_env, timeout=300)
    assert r.returncode == 0, r.stderr
    data = {d["id"]: d for d in json.loads(r.stdout)}
    assert {"pendulum", "driven_oscillator", "kepler"} <= set(data)
    pend = data["pendulum"]
    assert pend["source"].startswith("seed 000 S1")
    names = {p["name"]: p for p in pend["parameters"]}
    assert names["mass"]["unit"] == "kg" and names["initial.angle"]["unit"] == "rad"
    assert data["kepler"]["laws"][:1] == ["energy"]


def test_short_run_prints_conservation_table(ros_env: dict[str, str]) -> None:
    r = run(["run", "pendulum", "--fast", "--duration", "2"], ros_env)
    assert r.returncode == 0, r.stderr
    assert "Conservation results" in r.stdout
    assert "pendulum" in r.stdout and "energy" in r.stdout and "OK" in r.stdout


def test_output_into_a_closed_pipe_is_quiet(ros_env: dict[str, str]) -> None:
    proc = subprocess.Popen([*MECHSIM, "systems"], env=ros_env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    proc.stdout.readline()
    proc.stdout.close()  # like `mechsim systems | head -1`
    _, err = proc.communicate(timeout=120)
    assert "Traceback" not in err and proc.returncode == 0
