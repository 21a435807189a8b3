"""Set-up touches nothing outside the checkout: `make run` (tools/bootstrap.py) runs no package
manager of the system and installs no test tool; `make test` installs the test-only tools
(tools/test_tools.py) into the checkout, and asks apt, as a simulation, which of chromium's
dependencies this machine lacks. (A fresh clone's `make run` with apt-get and npm made
unavailable is the end-to-end check; it needs a new venv, so it is not part of the suite.)"""

from __future__ import annotations

import ast
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: Programs that install or fetch outside the project's venv.
SYSTEM_TOOLS = ("apt", "apt-get", "dpkg", "npm", "node", "sudo", "chromium")


def _strings(path: Path) -> list[str]:
    """The string constants of a module that could reach a command line (docstrings are
    prose: they are left out)."""
    tree = ast.parse(path.read_text())
    docs = {id(body[0].value) for n in ast.walk(tree)
            if isinstance(n, ast.Module | ast.FunctionDef | ast.ClassDef)
            and (body := n.body) and isinstance(body[0], ast.Expr)
            and isinstance(body[0].value, ast.Constant)}
    return [n.value for n in ast.walk(tree)
            if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docs]


def test_bootstrap_runs_no_system_tool() -> None:
    words = {w for s in _strings(ROOT / "tools" / "bootstrap.py") for w in s.split()}
    assert not words & set(SYSTEM_TOOLS), words & set(SYSTEM_TOOLS)


@pytest.mark.skipif(shutil.which("make") is None, reason="no make")
def test_make_run_is_the_bootstrap_and_the_run_only() -> None:
    plan = subprocess.run(["make", "-n", "run"], cwd=ROOT, capture_output=True, text=True,
                          check=True).stdout
    assert "tools/bootstrap.py" in plan and "mechsim run" in plan
    assert "test_tools" not in plan and not any(f"{t} " in plan for t in SYSTEM_TOOLS)
    quiet = subprocess.run(["make", "-n", "test", "NO_TEST_TOOLS=1"], cwd=ROOT,
                           capture_output=True, text=True, check=True).stdout
    assert 'if [ -n "1" ]' in quiet  # the tools' step is skipped when asked


def _test_tools() -> object:
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import test_tools
    finally:
        sys.path.pop(0)
    return test_tools


def test_a_status_database_without_some_packages() -> None:
    tools = _test_tools()
    status = ("Package: chromium\nStatus: install ok installed\n\n"
              "Package: chromium-common\nStatus: install ok installed\n\n"
              "Package: libopus0\nStatus: install ok installed\n")
    left = tools.without_packages(status, ("chromium", "chromium-common"))  # type: ignore[attr-defined]
    assert left.split("\n\n")[0] == "Package: libopus0\nStatus: install ok installed"


@pytest.mark.skipif(shutil.which("apt-get") is None or not Path("/var/lib/dpkg/status").is_file(),
                    reason="not a Debian-like system (no apt-get or dpkg database)")
def test_what_chromium_would_need_on_a_machine_without_one_of_its_libraries(
        tmp_path: Path) -> None:
    """With a library only chromium needs left out of the dpkg database, apt's simulation
    names it among the packages to fetch: what a machine without it downloads and unpacks."""
    tools = _test_tools()
    real = Path("/var/lib/dpkg/status").read_text(errors="replace")
    try:
        everything = tools.packages_to_fetch()  # type: ignore[attr-defined]
    except tools.Skipped as e:  # type: ignore[attr-defined]
        pytest.skip(str(e))
    names = [n for n, _ in everything]
    assert "chromium" in names and "chromium-common" in names
    installed = [e.split("\n", 1)[0].removeprefix("Package: ") for e in real.split("\n\n")
                 if "Status: install ok installed" in e]
    # (libraries nothing else depends on: leaving one out keeps the database consistent)
    lib = next((p for p in ("libminizip1", "libopenh264-7", "libdouble-conversion3")
                if p in installed), None)
    if lib is None:
        pytest.skip("none of the example libraries is installed here")
    status = tmp_path / "status"
    status.write_text(tools.without_packages(real, (lib,)))  # type: ignore[attr-defined]
    needed = [n for n, _ in tools.packages_to_fetch(status)]  # type: ignore[attr-defined]
    assert lib in needed and "chromium" in needed
