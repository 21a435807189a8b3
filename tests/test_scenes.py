"""Every system has a scene and a launch script; every scene is valid; a launch script runs."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

import mechsim
from mechsim.scene import load_scene

ROOT = Path(__file__).resolve().parent.parent
SCENES = sorted((ROOT / "scenes").glob("*.yaml"))
SCRIPTS = sorted((ROOT / "launch_scripts").glob("*.py"))


def test_every_system_has_a_scene_and_a_launch_script() -> None:
    for sid in mechsim.system_ids():
        assert (ROOT / "scenes" / f"{sid}.yaml").is_file(), sid
        assert (ROOT / "launch_scripts" / f"{sid}.py").is_file(), sid


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_scene_is_valid(path: Path) -> None:
    scene = load_scene(path)
    assert scene.systems


@pytest.mark.parametrize("path", SCRIPTS, ids=[p.stem for p in SCRIPTS])
def test_launch_script_names_an_existing_scene(path: Path) -> None:
    text = path.read_text()
    match = re.search(r'"scenes" / "([^"]+)"', text)
    assert match and (ROOT / "scenes" / match.group(1)).is_file()
    assert path.stat().st_mode & 0o111, "launch scripts are executable"


def test_a_launch_script_runs(ros_env: dict[str, str]) -> None:
    r = subprocess.run([sys.executable, str(ROOT / "launch_scripts" / "kepler.py"), "--fast",
                        "--duration", "0.5"], env=ros_env, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert "Conservation results" in r.stdout and "very_eccentric" in r.stdout
