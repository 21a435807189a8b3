#!/usr/bin/env python3
"""Create or update the project's virtual environment (stdlib only; run with the system python3).

Everything it writes is inside the checkout (.venv, .cache): no system package, no npm, no
browser. What only the tests need is installed by tools/test_tools.py (`make test`).

Steps, each redone only when its inputs changed (hashes kept in .venv/.mechsim-bootstrap.json):

1. venv      create ./.venv with a Python 3.11 interpreter;
2. installer pip install the pinned uv (requirements.txt), which installs the rest: it
             downloads in parallel and unpacks in native code, in a third of pip's time
             (pip does, where uv cannot be installed or fails);
   numerics  install the pins of numpy, scipy, sympy, numba and pyyaml from
             requirements.txt: what the next step imports;
3. loops     compile mechsim's shared integrator loops (numba, once per machine, ~40 s of
             CPU, from the source tree) so that the first run of a system only compiles that
             system's kernels; in the background from here on, in two processes, beside pip
             and the interface builds;
4. pip       install -r requirements.txt (steps 2 and 4 without byte-compiling: see 5);
5. bytecode  byte-compile the venv's packages (not their own test suites) on every core, in
             the background from here on;
6. cmake     rewrite the wheels' hard-coded /opt/python/cp311-cp311/... include directories in
             .venv/share/*/cmake/*.cmake (files of the venv only) to this venv's real paths
             (CMake rejects missing paths);
7. project   install -e . --no-deps --no-build-isolation;
8. <pkg>     build and install the ament_cmake interface packages src/tf2_msgs and
             src/mechsim_msgs into the venv (build trees under .cache/build/).
9. ros-package  make the venv a ROS prefix of the mechsim package, as `colcon build
             --symlink-install` would: setup.cfg's data files (the ament index marker,
             share/mechsim/{package.xml,launch,scenes,config}) linked file by file to the
             checkout (redone when one is added or removed), and the node executables (entry
             point group mechsim.executables) under lib/mechsim, where `ros2 run` looks.

Usage: python3 tools/bootstrap.py [--force]. Logs go to .cache/bootstrap/<step>.log.
"""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import ros_prefix  # tools/ros_prefix.py: the venv as a ROS prefix of the package

ROOT = Path(__file__).resolve().parent.parent
VENV = ROOT / ".venv"
VENV_PY = VENV / "bin" / "python"
STAMP = VENV / ".mechsim-bootstrap.json"
CACHE = ROOT / ".cache"
LOG_DIR = CACHE / "bootstrap"
BUILD_DIR = CACHE / "build"
REQUIREMENTS = ROOT / "requirements.txt"
PY_VERSION = (3, 11)
# Order matters: mechsim_msgs may one day use tf2_msgs; tf2_msgs needs only the wheels.
INTERFACE_PACKAGES = ("tf2_msgs", "mechsim_msgs")
# Where the ROS wheels were built (manylinux image); see ROS_NOTES "pitfall 1".
WHEEL_BUILD_PYTHON = "/opt/python/cp311-cp311"

# Variables from a sourced ROS install or an outer venv that must not leak into the build.
_SCRUB_ENV = (
    "AMENT_PREFIX_PATH",
    "CMAKE_PREFIX_PATH",
    "COLCON_PREFIX_PATH",
    "PYTHONPATH",
    "PYTHONHOME",
    "VIRTUAL_ENV",
    "_ROS_WHEELS_BOOTSTRAP_COMPLETE",
    # The set-up's own processes (the loops' imports) write the .pyc files they compile.
    "PYTHONDONTWRITEBYTECODE",
)


class StepFailed(Exception):
    def __init__(self, reason: str, log: Path | None = None) -> None:
        super().__init__(reason)
        self.reason = reason
        self.log = log


def say(msg: str) -> None:
    print(f"bootstrap: {msg}", flush=True)


def sha256_files(paths: list[Path], extra: str = "") -> str:
    h = hashlib.sha256(extra.encode())
    for p in sorted(paths):
        h.update(str(p.relative_to(ROOT)).encode() + b"\0")
        h.update(p.read_bytes() + b"\0")
    return h.hexdigest()[:16]


def package_files(pkg: str) -> list[Path]:
    base = ROOT / "src" / pkg
    return [p for p in base.rglob("*") if p.is_file() and "__pycache__" not in p.parts]


def clean_env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in _SCRUB_ENV}
    env["PATH"] = f"{VENV / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    return env


def run_logged(step: str, cmd: list[str], *, append: bool = False) -> None:
    """Run cmd with output to the step's log; raise StepFailed with a one-line reason."""
    LOG_DIR.mkdir(parents=True, exist_ok=True)
    log = LOG_DIR / f"{step}.log"
    with log.open("a" if append else "w") as f:
        f.write(f"$ {' '.join(cmd)}\n")
        f.flush()
        rc = subprocess.call(cmd, stdout=f, stderr=subprocess.STDOUT, cwd=ROOT, env=clean_env())
    if rc != 0:
        what = " ".join([Path(cmd[0]).name, *cmd[1:4]])
        raise StepFailed(f"`{what}` exited {rc}: {last_error_line(log)}", log)


class Pending:
    """A step's commands running in the background, each with its own log: :meth:`wait`
    raises StepFailed as ``run_logged`` would."""

    def __init__(self, cmds: list[tuple[list[str], Path]],
                 env: dict[str, str] | None = None) -> None:
        self.runs = []
        for cmd, log in cmds:
            out = log.open("w")
            out.write(f"$ {' '.join(cmd)}\n")
            out.flush()
            proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, cwd=ROOT,
                                    env=env or clean_env())
            self.runs.append((cmd, log, out, proc))

    def wait(self) -> None:
        for cmd, log, out, proc in self.runs:
            rc = proc.wait()
            out.close()
            if rc != 0:
                what = " ".join([Path(cmd[0]).name, *cmd[1:4]])
                raise StepFailed(f"`{what}` exited {rc}: {last_error_line(log)}", log)

    def stop(self) -> None:
        for _, _, out, proc in self.runs:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
            out.close()


def start_logged(step: str, *cmds: list[str], env: dict[str, str] | None = None) -> Pending:
    """Start the commands in the background, with output to the step's logs."""
    LOG_DIR.mkdir(parents=True, exist_ok=True)
    return Pending([(cmd, LOG_DIR / f"{step}-{i}.log") for i, cmd in enumerate(cmds, 1)], env)


def last_error_line(log: Path) -> str:
    """The most telling line of a failed command's log (Python exception, compiler/pip error)."""
    lines = [ln.strip() for ln in log.read_text(errors="replace").splitlines() if ln.strip()]
    patterns = (
        (r"^\w*(Error|Exception): ", True),  # Python traceback: its last line
        (r"\berror\b:|^ERROR:", False),  # gcc / pip: the first one
        (r"CMake Error|error|not found|failed", False),
    )
    for pattern, last in patterns:
        hits = [ln for ln in lines if re.search(pattern, ln, re.IGNORECASE if not last else 0)]
        if hits:
            return (hits[-1] if last else hits[0])[:200]
    return lines[-1][:200] if lines else "(empty log)"


def find_python() -> str:
    if sys.version_info[:2] == PY_VERSION:
        return sys.executable
    name = f"python{PY_VERSION[0]}.{PY_VERSION[1]}"
    found = shutil.which(name)
    if found is None:
        raise StepFailed(f"need Python {name} (the ROS wheels are cp311); not on PATH")
    return found


# --------------------------------------------------------------------------------------- steps


def venv_python_ok() -> bool:
    if not VENV_PY.exists():
        return False
    want = f"{PY_VERSION[0]}.{PY_VERSION[1]}"
    code = "import sys; print('%d.%d' % sys.version_info[:2])"
    out = subprocess.run([str(VENV_PY), "-c", code], capture_output=True, text=True,
                         env=clean_env(), check=False)
    return out.returncode == 0 and out.stdout.strip().endswith(want)


def step_venv() -> None:
    if venv_python_ok():
        say("reusing existing .venv")
        return
    if VENV.exists():
        shutil.rmtree(VENV)
    python = find_python()
    say(f"creating .venv with {python}")
    run_logged("venv", [python, "-m", "venv", str(VENV)])


#: What compiling the shared loops imports (mechsim's numerical core), installed first so that
#: the loops compile while pip installs the rest.
NUMERICS = ("numpy", "scipy", "sympy", "numba", "pyyaml")


def pins() -> dict[str, str]:
    """requirements.txt's lines by (lower-case) package name."""
    found = {}
    for line in REQUIREMENTS.read_text().splitlines():
        name = re.split(r"[=<>!~\[; ]", line.strip(), maxsplit=1)[0].lower()
        if name and not name.startswith("#"):
            found[name] = line.strip()
    return found


def numeric_pins() -> list[str]:
    """The requirements.txt lines that pin ``NUMERICS``."""
    return [line for name, line in pins().items() if name in NUMERICS]


def requirement_pin(name: str) -> str:
    """The requirements.txt line that pins ``name``."""
    line = pins().get(name)
    if line is None:
        raise StepFailed(f"requirements.txt pins no {name}")
    return line


UV = VENV / "bin" / "uv"


def install(step: str, args: list[str]) -> None:
    """Install ``args`` (pip's arguments after ``install``) into the venv with uv's pip
    interface, or with pip where uv is missing or fails (uv reads none of pip's settings: an
    index or certificate configured for pip alone), saying so.

    Neither byte-compiles here: compiling is half of pip's CPU and runs on one core; step
    ``bytecode`` compiles the venv afterwards on every core, beside the interface builds. It
    must not be left out: with PYTHONDONTWRITEBYTECODE set, as on some machines, nothing else
    would write the .pyc files and every process would compile sympy, scipy and numba from
    source (a cold test run took twice the CPU). uv copies files out of its cache rather than
    hard-linking them: step ``cmake-paths`` edits installed files, which must not change the
    cache's copies."""
    if UV.exists():
        try:
            run_logged(step, [str(UV), "pip", "install", "--python", str(VENV_PY),
                              "--link-mode", "copy", *args])
            return
        except StepFailed as e:
            say(f"uv failed ({e.reason}); installing with pip instead")
    else:
        say("no uv in the venv: installing with pip")
    # A log of its own: a failure names pip's error, not uv's.
    run_logged(f"{step}-pip", [str(VENV_PY), "-m", "pip", "install", "--no-compile", *args])


class NotDone(Exception):
    """A step that failed without stopping the set-up: not recorded as done, so the next
    run tries it again."""


def step_installer() -> None:
    say("pip install uv (the installer of the next steps)")
    try:
        run_logged("installer", [str(VENV_PY), "-m", "pip", "install", "--no-compile",
                                 requirement_pin("uv")])
    except StepFailed as e:
        say(f"no uv ({e.reason}): pip installs the rest")
        raise NotDone from e


def step_numerics() -> None:
    say("install numpy, scipy, sympy, numba, pyyaml (for the loops, first)")
    install("numerics", numeric_pins())


def step_pip() -> None:
    say("install -r requirements.txt (about 10 s with uv in a new venv, 30 s with pip)")
    install("pip", ["-r", str(REQUIREMENTS)])


def step_bytecode() -> Pending:
    say("byte-compiling the venv's packages (on every core, alongside the next steps)")
    # compile_dir's result is ignored, as pip ignores its own: a package may ship a file that
    # is not Python 3 (templates, examples), which nothing imports. The packages' own test
    # suites (a third of the files: sympy's, scipy's, numpy's...) are left out: nothing
    # imports them, and they were half of this step's CPU.
    # The pattern is matched against whole paths: anchored at site-packages, so that a
    # checkout under a directory named tests is still compiled.
    code = ("import compileall, re, sysconfig; p = sysconfig.get_paths()['purelib']; "
            "compileall.compile_dir(p, quiet=2, workers=0, "
            r"rx=re.compile(re.escape(p) + r'[/\\](.*[/\\])?tests?[/\\]'))")
    return start_logged("bytecode", [str(VENV_PY), "-c", code])


def venv_paths() -> dict[str, str]:
    code = (
        "import json, sysconfig, numpy; "
        "print(json.dumps({'include': sysconfig.get_paths()['include'], "
        "'purelib': sysconfig.get_paths()['purelib'], 'numpy': numpy.get_include()}))"
    )
    out = subprocess.run([str(VENV_PY), "-c", code], capture_output=True, text=True,
                         env=clean_env(), check=False)
    if out.returncode != 0:
        raise StepFailed(f"venv python cannot report its paths: {out.stderr.strip()[-200:]}")
    paths: dict[str, str] = json.loads(out.stdout.strip().splitlines()[-1])
    return paths


def step_cmake_paths() -> None:
    paths = venv_paths()
    old_sp = f"{WHEEL_BUILD_PYTHON}/lib/python3.11/site-packages"
    old_inc = f"{WHEEL_BUILD_PYTHON}/include/python3.11"
    repl = [(f"{old_sp}/numpy/_core/include", paths["numpy"]), (old_sp, paths["purelib"]),
            (old_inc, paths["include"])]
    for _, new in repl:
        if not Path(new).is_dir():
            raise StepFailed(f"expected directory missing: {new}")
    changed = 0
    for f in sorted((VENV / "share").glob("*/cmake/*.cmake")):
        text = f.read_text()
        if WHEEL_BUILD_PYTHON not in text:
            continue
        for old, new in repl:
            text = text.replace(old, new)
        tmp = f.with_name(f".{f.name}.tmp")  # a new file: never write through a shared inode
        tmp.unlink(missing_ok=True)
        tmp.write_text(text)
        tmp.replace(f)
        changed += 1
    say(f"rewrote {WHEEL_BUILD_PYTHON} include paths in {changed} cmake files")


def step_project() -> None:
    say("install -e . (mechsim, no deps)")
    install("project", ["--no-deps", "--no-build-isolation", "-e", str(ROOT)])


def step_loops() -> Pending:
    say("compiling the shared integrator loops (numba, ~40 s of CPU in two processes, "
        "alongside the next steps)")
    # From the source tree: the project is installed into the venv only later.
    env = dict(clean_env(), PYTHONPATH=str(ROOT / "src"))
    return start_logged("loops", *([str(VENV_PY), "-c", "import mechsim.integrators as i; "
                                    f"i.precompile({part})"] for part in (0, 1)), env=env)


#: What the compiled loops are made from (their cache key inside mechsim covers the same): the
#: integrators package (the loops' fragments, the tableaus, the state records, the steppers)
#: and the code generator, every module of both.
LOOP_SOURCES = tuple(sorted(str(p.relative_to(ROOT)) for d in ("integrators", "codegen")
                            for p in (ROOT / "src" / "mechsim" / d).rglob("*.py")))



def step_interface(pkg: str) -> None:
    say(f"building {pkg} (cmake, ~10 s)")
    src = ROOT / "src" / pkg
    build = BUILD_DIR / pkg
    if build.exists():  # from scratch: the message set may have changed
        shutil.rmtree(build)
    build.mkdir(parents=True)
    jobs = str(os.cpu_count() or 2)
    step = f"build-{pkg}"
    run_logged(step, [
        "cmake", "-S", str(src), "-B", str(build),
        f"-DCMAKE_PREFIX_PATH={VENV}",
        f"-DCMAKE_INSTALL_PREFIX={VENV}",
        f"-DPython3_EXECUTABLE={VENV_PY}",
        "-DBUILD_TESTING=OFF",
        "-DCMAKE_BUILD_TYPE=Release",
    ])
    run_logged(step, ["cmake", "--build", str(build), "-j", jobs], append=True)
    run_logged(step, ["cmake", "--install", str(build)], append=True)


def step_ros_package() -> None:
    say("the venv as a ROS prefix of package mechsim (ament index, share/mechsim, lib/mechsim)")
    ros_prefix.install(ROOT, VENV, VENV_PY)


# ----------------------------------------------------------------------------------- driver


@contextlib.contextmanager
def locked() -> Iterator[None]:
    CACHE.mkdir(parents=True, exist_ok=True)
    with (CACHE / "bootstrap.lock").open("w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def load_stamp() -> dict[str, str]:
    try:
        data = json.loads(STAMP.read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def save_stamp(stamp: dict[str, str]) -> None:
    tmp = STAMP.with_suffix(".tmp")
    tmp.write_text(json.dumps(stamp, indent=1, sort_keys=True) + "\n")
    tmp.replace(STAMP)


def plan() -> list[tuple[str, str, Callable[[], Pending | None]]]:
    """(step name, input hash, action), in order. A step's hash includes what it builds on."""
    venv_key = hashlib.sha256(f"{VENV}|{PY_VERSION}".encode()).hexdigest()[:16]
    pip_key = sha256_files([REQUIREMENTS], venv_key)
    # The interface builds depend on the ROS/catkin/setuptools pins, not on e.g. pytest's.
    build_reqs = "\n".join(
        ln for ln in REQUIREMENTS.read_text().splitlines()
        if re.match(r"\s*(ros-|catkin|setuptools)", ln, re.IGNORECASE)
    )
    build_key = hashlib.sha256(f"{venv_key}|{build_reqs}".encode()).hexdigest()[:16]
    numerics_key = hashlib.sha256("|".join([venv_key, requirement_pin("uv"), *numeric_pins()])
                                  .encode()).hexdigest()
    # The loops compile in the background, beside the steps after them: once the numerical
    # packages are in, while pip installs the rest.
    steps: list[tuple[str, str, Callable[[], Pending | None]]] = [
        ("venv", venv_key, step_venv),
        ("installer", hashlib.sha256(f"{venv_key}|{requirement_pin('uv')}".encode())
         .hexdigest()[:16], step_installer),
        ("numerics", numerics_key[:16], step_numerics),
        ("loops", sha256_files([ROOT / f for f in LOOP_SOURCES], pip_key), step_loops),
        ("pip", pip_key, step_pip),
        ("bytecode", pip_key, step_bytecode),
        ("cmake-paths", pip_key, step_cmake_paths),
        ("project", sha256_files([ROOT / "pyproject.toml", ROOT / "setup.cfg"], venv_key),
         step_project),
    ]
    for pkg in INTERFACE_PACKAGES:
        steps.append((pkg, sha256_files(package_files(pkg), build_key),
                      lambda pkg=pkg: step_interface(pkg)))
    steps.append(("ros-package", ros_prefix.key(ROOT, venv_key), step_ros_package))
    return steps


def bootstrap(force: bool = False) -> int:
    t0 = time.monotonic()
    stamp = {} if force or not VENV_PY.exists() else load_stamp()
    try:
        steps = plan()
    except (OSError, StepFailed) as e:
        print(f"bootstrap: FAILED: cannot read inputs: {e}", file=sys.stderr, flush=True)
        return 1
    if all(stamp.get(name) == key for name, key, _ in steps):
        say(f"up to date ({time.monotonic() - t0:.2f} s)")
        return 0
    with locked():
        stamp = {} if force or not VENV_PY.exists() else load_stamp()
        pending: list[tuple[str, str, Pending]] = []
        try:
            for name, key, action in steps:
                if stamp.get(name) == key:
                    continue
                # Not current until the step succeeds again; a pip run installs files not
                # yet byte-compiled and may restore the wheels' original cmake files, so it
                # also invalidates those two steps.
                for stale in (name, "bytecode", "cmake-paths") if name == "pip" else (name,):
                    stamp.pop(stale, None)
                if VENV.is_dir():
                    save_stamp(stamp)
                try:
                    running = action()
                except NotDone:
                    continue
                if running is not None:  # stamped once it has finished
                    pending.append((name, key, running))
                    continue
                if name == "venv":
                    stamp = {}
                stamp[name] = key
                save_stamp(stamp)
            while pending:
                name, key, running = pending[0]
                running.wait()
                pending.pop(0)
                stamp[name] = key
                save_stamp(stamp)
        except StepFailed as e:
            where = f" (log: {e.log})" if e.log else ""
            print(f"bootstrap: FAILED at step '{name}': {e.reason}{where}",
                  file=sys.stderr, flush=True)
            return 1
        finally:
            for _, _, running in pending:
                running.stop()
    say(f"done ({time.monotonic() - t0:.1f} s)")
    return 0



def main(argv: list[str]) -> int:
    if any(a in ("-h", "--help") for a in argv):
        print(__doc__)
        return 0
    unknown = [a for a in argv if a != "--force"]
    if unknown:
        print(f"bootstrap: unknown argument(s): {' '.join(unknown)}", file=sys.stderr)
        return 2
    return bootstrap(force="--force" in argv)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
