"""docs/adding_a_system.md followed as written, in a scratch copy of the project: its module,
registry line and test file added where the page says, the linter and every test that covers
all systems (filtered to the new one where they are per system) pass there, and the page's
Python and shell examples run. The page marks its pieces with HTML comments:
``<!-- file: PATH -->`` (the block is that file), ``<!-- line in: PATH, after: TEXT -->`` (the
block goes in after the line TEXT), ``<!-- run: python -->`` and, before the shell block,
``<!-- not run here: ... -->`` (the README test skips it; this test runs it)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "adding_a_system.md"
_BLOCK = re.compile(r"<!-- (file|line in|run|not run here): ?(.*?) -->\n```(\w+)\n(.*?)^```",
                    re.MULTILINE | re.DOTALL)
#: The tests that cover every system (run for the new one), and the registry's own.
SUITE = ["tests/test_spring_particle.py", "tests/test_registry.py", "tests/test_cdr.py",
         "tests/test_every_system_diagnostics.py", "tests/test_tolerance.py",
         "tests/test_recall.py", "tests/test_fuzz.py", "tests/test_architecture.py"]


def _pieces() -> list[tuple[str, str, str, str]]:
    return [m.groups() for m in _BLOCK.finditer(PAGE.read_text())]  # type: ignore[misc]


def _scratch_copy(dest: Path) -> None:
    """The project's source, tests and configuration (not its venv, caches or outputs)."""
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "node_modules", "*.egg-info")
    for name in ("src", "tests", "scenes"):
        shutil.copytree(ROOT / name, dest / name, ignore=ignore)
    for name in ("pyproject.toml", "setup.cfg"):
        shutil.copy2(ROOT / name, dest / name)


def _apply(dest: Path, pieces: list[tuple[str, str, str, str]]) -> tuple[list[str], list[str]]:
    """Write the page's files and lines into ``dest``; its (python, shell) examples."""
    python, shell = [], []
    for kind, arg, lang, body in pieces:
        if kind == "file":
            path = dest / arg.strip()
            assert not path.exists(), f"{arg}: the page would overwrite a file"
            path.write_text(body)
        elif kind == "line in":
            where, after = (s.strip() for s in arg.split(", after:", 1))
            path = dest / where
            lines = path.read_text().splitlines(keepends=True)
            at = [i for i, ln in enumerate(lines) if ln.rstrip("\n") == after]
            assert len(at) == 1, f"{where}: no single line {after!r}"
            lines.insert(at[0] + 1, body)
            path.write_text("".join(lines))
        elif kind == "run" and lang == "python":
            python.append(body)
        elif lang == "sh":
            shell.append(body)
    return python, shell


def test_the_page_has_every_piece() -> None:
    kinds = [(kind, arg.strip()) for kind, arg, _, _ in _pieces()]
    assert ("file", "src/mechsim/systems/spring_particle.py") in kinds
    assert ("file", "tests/test_spring_particle.py") in kinds
    assert any(kind == "line in" for kind, _ in kinds)
    assert any(kind == "not run here" for kind, _ in kinds)


def test_the_worked_example_leaves_the_suite_green(tmp_path: Path,
                                                   ros_env: dict[str, str]) -> None:
    dest = tmp_path / "project"
    _scratch_copy(dest)
    python, shell = _apply(dest, _pieces())
    # The scratch copy's mechsim first on the path (before the checkout's editable install).
    env = {k: v for k, v in ros_env.items()
           if k not in ("PYTEST_ADDOPTS", "PYTEST_XDIST_WORKER_COUNT")}
    env["PYTHONPATH"] = os.pathsep.join([str(dest / "src"), env.get("PYTHONPATH", "")])
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env['PATH']}"

    def run(cmd: list[str], what: str) -> subprocess.CompletedProcess[str]:
        done = subprocess.run(cmd, cwd=dest, env=env, capture_output=True, text=True,
                              timeout=1800)
        assert done.returncode == 0, f"{what}:\n{done.stdout[-4000:]}\n{done.stderr[-3000:]}"
        return done

    where = run([sys.executable, "-c", "import mechsim, sys; print(mechsim.__file__)"], "path")
    assert where.stdout.strip().startswith(str(dest)), where.stdout
    run([str(Path(sys.executable).parent / "ruff"), "check", "src", "tests"], "ruff")
    done = run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *SUITE,
                "-k", "spring_particle or registry or architecture or test_closed_form"],
               "the tests of every system, for the new one")
    assert re.search(r"\b(\d+) passed", done.stdout), done.stdout[-2000:]
    assert int(re.search(r"\b(\d+) passed", done.stdout).group(1)) >= 10  # type: ignore[union-attr]
    for code in python:
        run([sys.executable, "-c", code], "the page's Python example")
    if shutil.which("bash") is None:
        pytest.skip("no bash for the page's shell example")
    for script in shell:
        run(["bash", "-e", "-o", "pipefail", "-c", script], "the page's shell example")
    assert (dest / "runs" / "spring.rrd").is_file()
