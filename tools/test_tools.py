#!/usr/bin/env python3
"""Install what only the tests need, into the checkout (stdlib only; `make test` runs it).

Nothing here is needed to run mechsim, and nothing is written outside the checkout:

1. foxglove  Foxglove's ROS 2 decoders (``npm ci`` in tests/foxglove, into its node_modules),
             which tests/test_plottable.py reads bags with. Needs node and npm.
2. chromium  Debian's ``chromium`` and the libraries of its dependencies this machine lacks,
             fetched with ``apt-get download`` (as any user: no root, nothing installed on
             the system) and unpacked with ``dpkg -x`` under .cache/test-tools/chromium;
             tests/test_live_viewer.py opens the live Rerun view in it, headless, with
             LD_LIBRARY_PATH pointing there. Needs apt-get and dpkg (a Debian-like system)
             with package lists; about 100 MB to download, 340 MB unpacked.
3. ros2      the real ``ros2`` command, ``launch`` and ``launch_ros`` (not on PyPI), built by
             ../shared/ros2cli/setup.sh into .ros2tools where that folder exists, unless a
             ``ros2`` command is on PATH already (a ROS install); tests/test_ros2_cli.py,
             tests/test_launch_files.py and others use it as a ROS user would.
4. colcon    colcon-core and colcon-ros from PyPI (tools/colcon-requirements.txt) in a venv of
             their own, .cache/colcon (never the project's: colcon brings pytest plugins and
             its own setuptools pin); tests/test_colcon.py builds the repository with it.

What cannot be installed is said in one line and skipped; the tests that need it then skip,
with the reason. Each step is redone only when its inputs changed (the package lock; the
package versions apt offers). Usage: python3 tools/test_tools.py [--force]. Logs go to
.cache/test-tools/<step>.log.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CACHE = ROOT / ".cache" / "test-tools"
FOXGLOVE = ROOT / "tests" / "foxglove"
FOXGLOVE_STAMP = FOXGLOVE / "node_modules" / ".mechsim-installed"
CHROMIUM = CACHE / "chromium"
#: What tests/test_live_viewer.py reads: the browser's executable and its library path.
CHROMIUM_INFO = CACHE / "chromium.json"
#: The packages whose files are unpacked; their dependencies are added where missing.
CHROMIUM_PACKAGES = ("chromium", "chromium-common")
DPKG_STATUS = Path("/var/lib/dpkg/status")


class Skipped(Exception):
    """A step that cannot run here: its one-line reason."""


def say(msg: str) -> None:
    print(f"test tools: {msg}", flush=True)


def run(step: str, cmd: list[str], cwd: Path | None = None, append: bool = False) -> str:
    """Run ``cmd`` with its output logged; its standard output. Skipped on failure, naming
    the command and its last line of output."""
    CACHE.mkdir(parents=True, exist_ok=True)
    log = CACHE / f"{step}.log"
    env = dict(os.environ, LC_ALL="C", DEBIAN_FRONTEND="noninteractive")
    try:
        done = subprocess.run(cmd, cwd=cwd or ROOT, env=env, capture_output=True, text=True,
                              check=False, timeout=1800)
    except (OSError, subprocess.TimeoutExpired) as e:
        raise Skipped(f"`{Path(cmd[0]).name}` could not run ({e})") from None
    with log.open("a" if append else "w") as f:
        f.write(f"$ {' '.join(cmd)}\n{done.stdout}{done.stderr}")
    if done.returncode != 0:
        lines = [ln for ln in (done.stderr + done.stdout).splitlines() if ln.strip()]
        last = lines[-1].strip()[:160] if lines else "no output"
        raise Skipped(f"`{' '.join([Path(cmd[0]).name, *cmd[1:3]])}` exited "
                      f"{done.returncode}: {last} (log: {log.relative_to(ROOT)})")
    return done.stdout


# --------------------------------------------------------------------------------- foxglove


def foxglove(force: bool) -> None:
    npm, node = shutil.which("npm"), shutil.which("node")
    if npm is None or node is None:
        raise Skipped("node/npm not found; tests/test_plottable.py's Foxglove test will skip "
                      "(install Node.js to run it)")
    key = hashlib.sha256((FOXGLOVE / "package-lock.json").read_bytes()).hexdigest()
    if not force and FOXGLOVE_STAMP.is_file() and FOXGLOVE_STAMP.read_text() == key:
        say("Foxglove's decoders: up to date (tests/foxglove/node_modules)")
        return
    say("Foxglove's decoders: npm ci in tests/foxglove")
    run("foxglove", [npm, "ci", "--no-audit", "--no-fund", "--prefix", str(FOXGLOVE)])
    FOXGLOVE_STAMP.write_text(key)


# --------------------------------------------------------------------------------- chromium


def without_packages(status: str, names: tuple[str, ...]) -> str:
    """A dpkg status database (its text) with the entries of ``names`` left out."""
    entries = [e for e in status.split("\n\n") if e.strip()]
    kept = [e for e in entries
            if not any(e.startswith(f"Package: {n}\n") for n in names)]
    return "\n\n".join(kept) + "\n"


def packages_to_fetch(status: Path | None = None) -> list[tuple[str, str]]:
    """(package, version) of chromium, chromium-common and every dependency the dpkg status
    database ``status`` does not list as installed: what ``apt-get install`` would install
    on a machine without chromium, asked of apt as a simulation (no root needed)."""
    if shutil.which("apt-get") is None or shutil.which("dpkg") is None:
        raise Skipped("apt-get/dpkg not found (not a Debian-like system)")
    status = status or DPKG_STATUS
    try:
        text = status.read_text(errors="replace")
    except OSError as e:
        raise Skipped(f"cannot read {status} ({e.strerror})") from None
    CACHE.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", dir=CACHE, prefix=".status.", delete=False) as f:
        f.write(without_packages(text, CHROMIUM_PACKAGES))
    try:
        out = run("chromium", ["apt-get", "-s", "-o", f"Dir::State::status={f.name}",
                               "-o", "Debug::NoLocking=1", "install",
                               "--no-install-recommends", *CHROMIUM_PACKAGES[:1]])
    finally:
        os.unlink(f.name)
    found = []
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 3 and parts[0] == "Inst":  # Inst NAME [OLD] (VERSION ...)
            version = line.split("(", 1)[1].split()[0] if "(" in line else ""
            found.append((parts[1], version))
    if not any(name == "chromium" for name, _ in found):
        raise Skipped("apt offers no `chromium` package (package lists empty or another "
                      "distribution)")
    return found


#: How the unpacked tree is described (bumped when ``chromium.json`` gains a field or a
#: folder): part of the key, so a copy described the old way is unpacked again.
CHROMIUM_LAYOUT = 2


def chromium(force: bool) -> None:
    try:
        wanted = packages_to_fetch()
    except Skipped:
        if not force and CHROMIUM_INFO.is_file():  # e.g. offline now: keep what is there
            say("chromium: apt cannot be asked now; keeping the copy in .cache/test-tools")
            return
        raise
    key = hashlib.sha256(json.dumps([CHROMIUM_LAYOUT, wanted]).encode()).hexdigest()
    if not force and CHROMIUM_INFO.is_file():
        try:
            if json.loads(CHROMIUM_INFO.read_text()).get("key") == key:
                say("chromium: up to date (.cache/test-tools/chromium)")
                return
        except ValueError:
            pass
    say(f"chromium: apt-get download of {len(wanted)} package(s) (chromium and the "
        "libraries this machine lacks), unpacked with dpkg -x into .cache/test-tools/chromium")
    CHROMIUM_INFO.unlink(missing_ok=True)
    debs = CACHE / "debs"
    shutil.rmtree(debs, ignore_errors=True)
    debs.mkdir(parents=True)
    run("chromium", ["apt-get", "download", *(f"{n}={v}" if v else n for n, v in wanted)],
        cwd=debs, append=True)
    staging = Path(tempfile.mkdtemp(prefix=".chromium.", dir=CACHE))
    try:
        for deb in sorted(debs.glob("*.deb")):
            run("chromium", ["dpkg", "-x", str(deb), str(staging)], append=True)
        binary = staging / "usr" / "lib" / "chromium" / "chromium"
        if not os.access(binary, os.X_OK):
            raise Skipped("the chromium package holds no usr/lib/chromium/chromium")
        shutil.rmtree(CHROMIUM, ignore_errors=True)
        staging.rename(CHROMIUM)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
        shutil.rmtree(debs, ignore_errors=True)
    # Paths relative to the checkout's root (it may move): the usual library folders first,
    # then every other folder holding a shared object (libpulse0's libpulsecommon lives in
    # usr/lib/x86_64-linux-gnu/pulseaudio, found through a RUNPATH the unpacked tree lacks).
    usual = [CHROMIUM / d for d in ("usr/lib/x86_64-linux-gnu", "lib/x86_64-linux-gnu",
                                    "usr/lib/chromium")]
    others = sorted({f.parent for f in CHROMIUM.rglob("*.so*") if f.is_file()} - set(usual))
    libs = [*usual, *others]
    info = {"key": key, "packages": [f"{n} {v}" for n, v in wanted],
            "executable": str((CHROMIUM / "usr/lib/chromium/chromium").relative_to(ROOT)),
            "library_path": [str(d.relative_to(ROOT)) for d in libs if d.is_dir()]}
    CHROMIUM_INFO.write_text(json.dumps(info, indent=1) + "\n")



# ----------------------------------------------------------------------------- ros2, colcon

ROS2TOOLS = ROOT / ".ros2tools"
SHARED_ROS2CLI = ROOT.parent / "shared" / "ros2cli"
COLCON = ROOT / ".cache" / "colcon"
COLCON_PINS = ROOT / "tools" / "colcon-requirements.txt"


def ros2(force: bool) -> None:
    if shutil.which("ros2"):
        say(f"ros2: on PATH ({shutil.which('ros2')})")
        return
    if (ROS2TOOLS / "venv" / "bin" / "ros2").exists() and not force:
        return
    setup = SHARED_ROS2CLI / "setup.sh"
    if not setup.exists():
        raise Skipped(f"no ros2 command on PATH and no {setup}")
    say(f"ros2: building the ros2 command from {SHARED_ROS2CLI} (1-2 min, once)")
    run("ros2", [str(setup), str(ROOT)])


def colcon(force: bool) -> None:
    stamp = COLCON / ".pins"
    pins = COLCON_PINS.read_bytes()
    if (COLCON / "bin" / "colcon").exists() and stamp.exists() and stamp.read_bytes() == pins \
            and not force:
        return
    say("colcon: installing into .cache/colcon (PyPI)")
    shutil.rmtree(COLCON, ignore_errors=True)
    python = sys._base_executable  # the interpreter the project's venv was made from
    uv = Path(sys.prefix) / "bin" / "uv"
    try:
        if uv.exists():
            run("colcon", [python, "-m", "venv", "--without-pip", str(COLCON)])
            run("colcon", [str(uv), "pip", "install", "-q", "--python",
                           str(COLCON / "bin" / "python"), "-r", str(COLCON_PINS)], append=True)
        else:
            run("colcon", [python, "-m", "venv", str(COLCON)])
            run("colcon", [str(COLCON / "bin" / "python"), "-m", "pip", "install", "-q",
                           "--disable-pip-version-check", "-r", str(COLCON_PINS)], append=True)
    except Skipped:
        shutil.rmtree(COLCON, ignore_errors=True)
        raise
    stamp.write_bytes(pins)


STEPS = (("foxglove", foxglove, "tests/test_plottable.py's Foxglove test"),
         ("chromium", chromium, "tests/test_live_viewer.py's browser tests"),
         ("ros2", ros2, "the tests that use the ros2 command"),
         ("colcon", colcon, "tests/test_colcon.py"))


def main(argv: list[str]) -> int:
    if any(a in ("-h", "--help") for a in argv):
        print(__doc__)
        return 0
    unknown = [a for a in argv if a != "--force"]
    if unknown:
        print(f"test tools: unknown argument(s): {' '.join(unknown)}", file=sys.stderr)
        return 2
    for name, step, users in STEPS:
        try:
            step("--force" in argv)
        except Skipped as e:
            say(f"{name}: not installed: {e}; {users} will skip")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
