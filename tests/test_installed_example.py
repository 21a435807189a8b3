"""The closed-loop example as a user runs it: mechsim built and installed by pip (a real wheel
build of this repository, without its dependencies, which the environment already has) into a
directory outside the repository, and the example test copied next to it and run by pytest
from there. The plugin's fixtures then come from the installed copy's ``pytest11`` entry point,
not from this repository's ``src`` or ``conftest.py``."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = Path(__file__).with_name("test_swing_up_example.py")


def test_example_passes_with_pip_installed_mechsim() -> None:
    with tempfile.TemporaryDirectory(prefix="mechsim-user-") as tmp:
        work = Path(tmp)
        assert REPO not in work.parents
        # pip builds in the source tree (build/, *.egg-info): build from a copy of what the
        # package is made of, so the repository stays untouched.
        project = work / "project"
        project.mkdir()
        for name in ("pyproject.toml", "setup.cfg", "setup.py", "README.md", "package.xml"):
            shutil.copy(REPO / name, project / name)
        # The code, and the ROS package's data files (setup.cfg's [options.data_files]).
        for tree in ("src", "resource", "launch_scripts", "scenes", "config"):
            shutil.copytree(REPO / tree, project / tree,
                            ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
        site = work / "site"
        build = subprocess.run(
            [sys.executable, "-m", "pip", "install", "--no-deps", "--no-build-isolation",
             "--no-index", "--quiet", "--target", str(site), str(project)],
            capture_output=True, text=True, timeout=600)
        assert build.returncode == 0, build.stdout[-2000:] + build.stderr[-2000:]
        assert (site / "mechsim" / "testing.py").is_file()
        shutil.copy(EXAMPLE, work / EXAMPLE.name)
        # Where mechsim is imported from in the user's run (a plugin module loaded by -p).
        (work / "where.py").write_text(
            "import mechsim, pathlib\n"
            "pathlib.Path('mechsim_location.txt').write_text(mechsim.__file__)\n")
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
        env["PYTHONPATH"] = f"{site}{os.pathsep}{work}"
        run = subprocess.run(
            [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
             "-p", "where", EXAMPLE.name],
            cwd=work, env=env,
            capture_output=True, text=True, timeout=900)
        assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
        assert "1 passed" in run.stdout
        used = Path((work / "mechsim_location.txt").read_text()).resolve()
        assert site.resolve() in used.parents, used
