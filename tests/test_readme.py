"""The README and the pages of docs/ run as written: every ```sh block is run literally by bash
(``-e``: a failing line fails the test) in a scratch directory holding the project's scenes and
the files the page writes out (a block preceded by ``<!-- file: NAME -->``), with the venv's
``bin`` on PATH as the README says, the test's ROS domain, and simulated durations capped at
3 s. A block preceded by ``<!-- not run: REASON -->`` (or ``<!-- not run here: REASON -->``,
run by another test) is skipped with that reason: the set-up commands themselves, recipes
for other hosts.

The README is user documentation: at most ``MAX_README_LINES`` lines, its systems list the
one the systems generate, and no text of the project speaks of its own development history
(numbered or "current" work sessions): a CHANGELOG says what changed."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MAX_README_LINES = 300
_FENCE = re.compile(r"^```(\w+)\n(.*?)^```", re.MULTILINE | re.DOTALL)
_SKIP = re.compile(r"<!-- not run(?: here)?: (.*?) -->\s*$")
_FILE = re.compile(r"<!-- file: (\S+) -->\s*$")
#: Development history in the project's text (written so that this file does not match it).
_HISTORY = re.compile(r"session [0-9]+|(this|last|previous)\s+session", re.IGNORECASE)


def pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def _blocks() -> list[tuple[str, str, str | None, dict[str, str]]]:
    """(where, script, reason to skip, files the page writes out) of every sh block."""
    out = []
    for page in pages():
        text = page.read_text()
        files: dict[str, str] = {}
        found = []
        for m in _FENCE.finditer(text):
            before = text[:m.start()].rstrip("\n").rsplit("\n", 1)[-1]
            named = _FILE.search(before)
            if named:
                files[named.group(1)] = m.group(2)
            if m.group(1) != "sh":
                continue
            line = text.count("\n", 0, m.start()) + 1
            skip = _SKIP.search(before)
            found.append((f"{page.relative_to(ROOT)}:{line}", m.group(2),
                          skip.group(1) if skip else None))
        out += [(where, script, skip, files) for where, script, skip in found]
    return out


BLOCKS = _blocks()


def test_the_readme_has_runnable_blocks() -> None:
    assert sum(1 for where, _, skip, _ in BLOCKS
               if skip is None and where.startswith("README")) >= 4


@pytest.mark.parametrize("where,block,skip,files", BLOCKS, ids=[b[0] for b in BLOCKS])
def test_block_runs_as_written(where: str, block: str, skip: str | None,
                               files: dict[str, str], ros_env: dict[str, str],
                               tmp_path: Path) -> None:
    if skip is not None:
        pytest.skip(skip)
    shutil.copytree(ROOT / "scenes", tmp_path / "scenes")
    for name, body in files.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(body)
    script = re.sub(r"--duration (\d+(?:\.\d+)?)",
                    lambda m: f"--duration {min(float(m.group(1)), 3.0):g}", block)
    env = dict(ros_env, PATH=f"{Path(sys.executable).parent}{os.pathsep}{ros_env['PATH']}")
    done = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", script], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, f"{where}\n{script}\n--- stderr:\n{done.stderr[-3000:]}"
    assert "Traceback" not in done.stderr, done.stderr[-3000:]


def test_the_readme_is_short() -> None:
    lines = (ROOT / "README.md").read_text().count("\n")
    assert lines <= MAX_README_LINES, f"README.md: {lines} lines (at most {MAX_README_LINES})"


def test_the_readme_lists_every_system() -> None:
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        from readme_systems import BEGIN, END, table
    finally:
        sys.path.pop(0)
    text = (ROOT / "README.md").read_text()
    assert f"{BEGIN}\n{table()}\n{END}" in text, "run tools/readme_systems.py"


def test_the_readme_performance_is_the_benchmark_outputs() -> None:
    """The performance table is what docs/bench/'s JSON and pages say (no figure typed in)."""
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        from readme_performance import BEGIN, END, block
    finally:
        sys.path.pop(0)
    text = (ROOT / "README.md").read_text()
    assert f"{BEGIN}\n{block()}\n{END}" in text, "run tools/readme_performance.py"
    assert "| met |" in text and "recording" in block()  # the pages were found and read


def _project_text() -> list[Path]:
    """The project's own text: README, changelog, docs, sources, tests, tools."""
    found = [ROOT / "README.md"]
    for top in ("docs", "src", "tests", "tools"):
        for path in (ROOT / top).rglob("*"):
            parts = set(path.relative_to(ROOT).parts)
            if path.is_file() and not parts & {"node_modules", "__pycache__", ".cache"} \
                    and path.suffix in (".md", ".py", ".txt", ".yaml", ".msg", ".cfg", ".cjs",
                                        ".json", ".xml", ".toml", ".sh", ""):
                found.append(path)
    return found


def test_no_text_speaks_of_the_projects_history() -> None:
    hits = []
    for path in _project_text():
        try:
            text = path.read_text()
        except (UnicodeDecodeError, OSError):
            continue
        for n, line in enumerate(text.splitlines(), 1):
            if _HISTORY.search(line):
                hits.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()[:100]}")
    assert not hits, "\n".join(hits)


def test_every_docs_link_resolves_or_is_a_page_to_come() -> None:
    """Relative links between the pages point at files that exist, or at the pages other
    parts of the documentation provide (named in docs/index.md)."""
    index = (ROOT / "docs" / "index.md").read_text()
    missing = []
    for page in pages():
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
            if "://" in target:
                continue
            path = (page.parent / target).resolve()
            if not path.exists() and Path(target).name not in index:
                missing.append(f"{page.relative_to(ROOT)} -> {target}")
    assert not missing, missing
