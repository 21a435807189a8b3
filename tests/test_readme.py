"""The README runs as written: every ```sh block is run literally by bash (``-e``: a failing
line fails the test) in a scratch directory holding the project's scenes, with the venv's
``bin`` on PATH as the README says, the test's ROS domain, and simulated durations capped at
3 s. A block preceded by ``<!-- not run: REASON -->`` is skipped with that reason (the set-up
commands themselves, and recipes for other hosts)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
_FENCE = re.compile(r"^```sh\n(.*?)^```", re.MULTILINE | re.DOTALL)
_SKIP = re.compile(r"<!-- not run: (.*?) -->\s*$")


def _blocks() -> list[tuple[str, str, str | None]]:
    text = (ROOT / "README.md").read_text()
    out = []
    for m in _FENCE.finditer(text):
        line = text.count("\n", 0, m.start()) + 1
        before = text[:m.start()].rstrip("\n").rsplit("\n", 1)[-1]
        skip = _SKIP.search(before)
        out.append((f"README.md:{line}", m.group(1), skip.group(1) if skip else None))
    return out


BLOCKS = _blocks()


def test_the_readme_has_runnable_blocks() -> None:
    assert sum(1 for _, _, skip in BLOCKS if skip is None) >= 4


@pytest.mark.parametrize("where,block,skip", BLOCKS, ids=[b[0] for b in BLOCKS])
def test_block_runs_as_written(where: str, block: str, skip: str | None,
                               ros_env: dict[str, str], tmp_path: Path) -> None:
    if skip is not None:
        pytest.skip(skip)
    shutil.copytree(ROOT / "scenes", tmp_path / "scenes")
    script = re.sub(r"--duration (\d+(?:\.\d+)?)",
                    lambda m: f"--duration {min(float(m.group(1)), 3.0):g}", block)
    env = dict(ros_env, PATH=f"{Path(sys.executable).parent}{os.pathsep}{ros_env['PATH']}")
    done = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", script], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, f"{where}\n{script}\n--- stderr:\n{done.stderr[-3000:]}"
    assert "Traceback" not in done.stderr, done.stderr[-3000:]
