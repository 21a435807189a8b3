"""``colcon build`` of the repository in a scratch ROS workspace, over the project's venv as
the ROS install (``AMENT_PREFIX_PATH``/``CMAKE_PREFIX_PATH``, as a sourced install sets them),
with the command docs/ros2.md gives: the package is installed (marker, package.xml, launch
files, scenes, executables), with its message package, and never a copy of the install's own
``tf2_msgs``. colcon-core and colcon-ros come from PyPI into ``.cache/colcon`` (the test
command's tools/test_tools.sh); skipped, saying why, where colcon or cmake is missing."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from rosuser import DEADLINE, ROOT

COLCON = ROOT / ".cache" / "colcon" / "bin" / "colcon"


def _colcon() -> str:
    found = shutil.which("colcon") or (str(COLCON) if COLCON.exists() else None)
    if found is None:
        pytest.skip("no colcon: none on PATH and none in .cache/colcon (tools/test_tools.sh "
                    "installs it from PyPI)")
    if shutil.which("cmake") is None:
        pytest.skip("no cmake: the message package cannot be built")
    return found


def _workspace(tmp: Path) -> Path:
    """A workspace holding the repository as a user's clone would: its tracked and new
    files (not what is ignored: no venv, no caches)."""
    ws = tmp / "ws"
    files = subprocess.run(["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=ROOT,
                           capture_output=True, check=True).stdout.decode().split("\0")
    for name in filter(None, files):
        src, dst = ROOT / name, ws / "src" / "mechsim" / name
        if src.is_file() or src.is_symlink():
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst, follow_symlinks=False)
    return ws


def test_colcon_build_installs_the_package(tmp_path: Path) -> None:
    colcon = _colcon()
    ws = _workspace(tmp_path)
    env = {**os.environ, "AMENT_PREFIX_PATH": sys.prefix, "CMAKE_PREFIX_PATH": sys.prefix,
           "PATH": f"{Path(sys.prefix) / 'bin'}{os.pathsep}{os.environ['PATH']}"}
    out = subprocess.run([colcon, "build", "--base-paths", "src", "src/mechsim/src/mechsim_msgs",
                          "--cmake-args", f"-DPython3_EXECUTABLE={sys.executable}",
                          "-DBUILD_TESTING=OFF"], cwd=ws, env=env, capture_output=True,
                         text=True, timeout=DEADLINE * 5)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    install = ws / "install"
    assert sorted(p.name for p in install.iterdir() if p.is_dir()) == ["mechsim",
                                                                       "mechsim_msgs"]
    prefix = install / "mechsim"
    assert (prefix / "share/ament_index/resource_index/packages/mechsim").is_file()
    share = prefix / "share" / "mechsim"
    assert (share / "package.xml").read_text() == (ROOT / "package.xml").read_text()
    assert sorted(p.name for p in (share / "launch").iterdir()) == sorted(
        p.name for p in (ROOT / "launch_scripts").glob("*.launch.py"))
    assert (share / "scenes" / "default.yaml").is_file()
    assert (share / "config" / "fastdds_loopback.xml").is_file()
    for exe in ("simulator", "diagnostics", "recorder", "swing_up_controller"):
        assert os.access(prefix / "lib" / "mechsim" / exe, os.X_OK), exe
    assert (install / "mechsim_msgs" / "share" / "mechsim_msgs" / "srv" / "Step.srv").is_file()
    # The installed copy is what runs (not the checkout's): its executable, with the
    # workspace's Python path first, as install/setup.bash sets it.
    site = next((prefix / "lib").glob("python3*/site-packages"))
    msgs = next((install / "mechsim_msgs" / "lib").glob("python3*/site-packages"))
    run = subprocess.run([sys.executable, str(prefix / "lib" / "mechsim" / "simulator"),
                          "--help"], env={**os.environ, "PYTHONPATH": f"{site}:{msgs}"},
                         capture_output=True, text=True, timeout=DEADLINE)
    assert run.returncode == 0 and "--ros-args" in run.stdout, run.stderr
    where = subprocess.run([sys.executable, "-c", "import mechsim, mechsim_msgs; "
                            "print(mechsim.__file__, mechsim_msgs.__file__)"],
                           env={**os.environ, "PYTHONPATH": f"{site}:{msgs}"},
                           capture_output=True, text=True, timeout=DEADLINE)
    assert where.stdout.split() == [str(site / "mechsim" / "__init__.py"),
                                    str(msgs / "mechsim_msgs" / "__init__.py")], where
    # Nothing written into the sources.
    assert not list((ws / "src").rglob("*.egg-info"))
