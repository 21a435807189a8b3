"""Every scene file is valid; a system runs from its id alone, with the default scene."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from mechsim.scene import load_scene

ROOT = Path(__file__).resolve().parent.parent
SCENES = sorted((ROOT / "scenes").glob("*.yaml"))


@pytest.mark.parametrize("path", SCENES, ids=[p.stem for p in SCENES])
def test_scene_is_valid(path: Path) -> None:
    scene = load_scene(path)
    assert scene.systems


def test_a_system_runs_without_a_scene_file(ros_env: dict[str, str], tmp_path: Path) -> None:
    r = subprocess.run([sys.executable, "-m", "mechsim.cli", "run", "kepler", "--fast",
                        "--duration", "0.5"], env=ros_env, capture_output=True, text=True,
                       timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "Conservation results" in r.stdout and "kepler" in r.stdout
