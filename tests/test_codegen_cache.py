"""The cache of generated kernel modules: keyed on every input of the derivation (a system
whose parameters are reordered, with the old kernels still cached, computes with the new
order), bounded (least recently used modules go first), and shown and emptied by
``mechsim cache info|clear`` without touching anything else in the directory; ``cache warm``
derives a system's models ahead of its first run."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import pytest

from mechsim import codegen
from mechsim.cli import main
from mechsim.params import number, positive
from mechsim.simulate import simulate
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


class _Spring(LagrangianModel):
    """m ẍ = −k x: x = x₀ cos(√(k/m) t)."""

    id = "cache_test_spring"
    title = "spring"
    source = "tests"
    parameters = (positive("spring_constant", 9.0, "N/m", "k"), positive("mass", 1.0, "kg", "m"),
                  number("initial.x", 1.0, "m", "x₀"))

    def declare(self, b: LagrangianBuilder) -> None:
        x, v = b.coordinate("x", "m")
        k, m = b.param("spring_constant"), b.param("mass")
        b.kinetic = m * v**2 / 2
        b.potential = k * x**2 / 2
        b.observable("force", "N", -k * x)


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("MECHSIM_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(codegen, "_recalled", {})  # as in a new process
    return tmp_path / "cache"


def _end_x(model: LagrangianModel) -> float:
    run = simulate(model, 2.0, 1.0, method="dop853", tolerance=1e-12, outputs=())
    return float(run.q[-1, 0])


def test_reordered_parameters_with_a_warm_cache(cache: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """k = 9, m = 1: x(2) = cos 6. The generated code reads k and m by index; after the two
    parameters swap places in the spec, the cached kernels (k at 0, m at 1) must not serve."""
    first = _Spring()
    assert _end_x(first) == pytest.approx(math.cos(6.0), abs=1e-9)
    assert codegen.cache_info()["modules"] >= 1  # the cache is warm
    spec = _Spring.parameters
    monkeypatch.setattr(_Spring, "parameters", (spec[1], spec[0], spec[2]))
    swapped = _Spring()
    assert list(swapped.parameter_vector()[:2]) == [1.0, 9.0]
    assert _end_x(swapped) == pytest.approx(math.cos(6.0), abs=1e-9)
    assert swapped.kernels is not first.kernels


def test_least_recently_used_modules_are_evicted(cache: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(codegen, "MAX_MODULES", 3)
    monkeypatch.setattr(codegen, "_EVICT_GRACE", -1.0)
    folder = cache / "kernels"
    for i in range(3):
        codegen.load_module(f"evict{i}", f"key{i}", lambda i=i: f"VALUE = {i}\n")
    used = sorted(folder.glob("*.used"))
    for k, marker in enumerate(sorted(used, key=lambda p: p.name)):
        os.utime(marker, (1000.0 + k, 1000.0 + k))  # evict0 … evict2, oldest first
    oldest = min(used, key=lambda p: p.stat().st_mtime).with_suffix(".py")
    codegen.load_module("evict3", "key3", lambda: "VALUE = 3\n")
    names = {p.name for p in folder.glob("*.py")}
    assert len(names) == 3 and oldest.name not in names


def test_cache_info_and_clear(cache: Path, capsys: pytest.CaptureFixture[str]) -> None:
    codegen.load_module("clear_me", "k", lambda: "VALUE = 1\n")
    codegen.remember("a_summary", {"coordinates": []})
    assert codegen.recall("a_summary") == {"coordinates": []}
    cache.mkdir(parents=True, exist_ok=True)
    foreign = cache / "notes.txt"
    foreign.write_text("not ours")
    assert main(["cache", "info", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["path"] == str(cache) and info["modules"] == 1 and info["bytes"] > 0
    assert info["summaries"] == 1
    assert main(["cache", "clear"]) == 0
    assert "removed 1 generated module" in capsys.readouterr().out
    assert not list((cache / "kernels").glob("mechsim_*"))
    assert codegen.recall("a_summary") is None
    assert foreign.read_text() == "not ours"
    assert main(["cache", "info"]) == 0
    assert "modules: 0" in capsys.readouterr().out


def _lock_waiters(lock: Path) -> int:
    """Waiters for the flock on ``lock``: the ``->`` rows of /proc/locks for its inode."""
    inode = str(lock.stat().st_ino)
    rows = Path("/proc/locks").read_text().splitlines()
    return sum(1 for row in rows if "->" in row
               and any(f.count(":") == 2 and f.rsplit(":", 1)[1] == inode for f in row.split()))


def test_a_model_being_derived_elsewhere_is_waited_for(cache: Path) -> None:
    """Two builders of one uncached module (a scene's node processes, test workers): the second
    waits for the first's build lock, then loads the module the first wrote instead of
    deriving it again."""
    import threading

    name, key = "shared", "inputs"
    path = codegen._module_dir() / f"{codegen._PREFIX}{name}_" \
        f"{codegen.fingerprint(key, codegen.RUNTIME)}.py"
    path.parent.mkdir(parents=True)
    derived: list[int] = []
    loaded: dict[str, Any] = {}

    def second() -> None:
        loaded["module"] = codegen.load_module(
            name, key, lambda: derived.append(1) or "VALUE = 2\n")

    with codegen._exclusive(path):  # the first builder, deriving
        waiter = threading.Thread(target=second)
        waiter.start()
        # until the second blocks on the lock (a waiter in /proc/locks) or returns without it
        while waiter.is_alive() and _lock_waiters(path.with_suffix(".lock")) == 0:
            waiter.join(0.01)
        assert waiter.is_alive(), "the second builder did not wait for the lock"
        codegen.write_atomic(path, "VALUE = 1\n")  # the module and its seal
        codegen.write_atomic(path.with_suffix(".sum"), codegen._seal(path.stem, b"VALUE = 1\n"))
    waiter.join(120)
    assert not derived and loaded["module"].VALUE == 1


def test_cache_warm(capsys: pytest.CaptureFixture[str]) -> None:
    """``mechsim cache warm SYSTEM``: every formulation of the system derived, compiled and
    run once, a line each (none with ``--quiet``, before or after the systems); an unknown
    system is a one-line error, a system given to another action a usage error (exit 2)."""
    from mechsim.systems import system_class

    forms = system_class("pendulum").formulations
    assert len(forms) > 1
    assert main(["cache", "warm", "pendulum"]) == 0
    out = capsys.readouterr()
    assert [f"mechsim: cache warm: pendulum ({f})" for f in forms] == out.err.splitlines()
    assert out.out.startswith(f"{len(forms)} models ready in ")
    for argv in (["--quiet", "pendulum"], ["pendulum", "--quiet"]):
        assert main(["cache", "warm", *argv]) == 0
        assert capsys.readouterr().err == ""
    assert main(["cache", "warm", "no_such_system"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("mechsim: error: unknown system")
    with pytest.raises(SystemExit) as stop:  # argparse's usage error, as for every verb
        main(["cache", "info", "pendulum"])
    assert stop.value.code == 2


# --- a cache that verifies before it trusts -----------------------------------------------------
def _module(cache: Path, name: str) -> Path:
    (path,) = (cache / "kernels").glob(f"mechsim_{name}_*.py")
    return path


def test_a_truncated_module_is_derived_again(cache: Path) -> None:
    """A generated module cut in half (a crash, a full disk): its seal does not hold, so it is
    made again, never imported (importing it would fail, or define half the module)."""
    codegen.load_module("cut", "k", lambda: "A = 1\nB = 2\n")
    path = _module(cache, "cut")
    path.write_bytes(path.read_bytes()[:5])  # "A = 1"
    codegen._loaded.clear()
    made: list[int] = []
    module = codegen.load_module("cut", "k", lambda: made.append(1) or "A = 1\nB = 2\n")
    assert made == [1] and (module.A, module.B) == (1, 2)
    assert path.read_text() == "A = 1\nB = 2\n"


def test_a_planted_module_is_never_imported(cache: Path, tmp_path: Path) -> None:
    """Code swapped into a cached module (same name, other content) would run on import and
    could change the physics: the content does not match its seal, so it is removed and
    derived again; the planted code never runs."""
    codegen.load_module("swap", "k", lambda: "G = 9.81\n")
    path = _module(cache, "swap")
    ran = tmp_path / "ran"
    path.write_text(f"open({str(ran)!r}, 'w').close()\nG = 1.0\n")
    codegen._loaded.clear()
    module = codegen.load_module("swap", "k", lambda: "G = 9.81\n")
    assert module.G == 9.81 and not ran.exists()


def test_entries_writable_by_others_are_not_trusted(cache: Path, tmp_path: Path,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """A module (with a valid seal) that others may write is derived again; a cache directory
    writable by others is not used at all: one warning line, and this process builds in a
    private temporary directory (what it derives is right, nothing is read from there)."""
    codegen.load_module("shared", "k", lambda: "V = 1\n")
    path = _module(cache, "shared")
    path.chmod(0o666)
    codegen._loaded.clear()
    made: list[int] = []
    assert codegen.load_module("shared", "k", lambda: made.append(1) or "V = 1\n").V == 1
    assert made == [1] and path.stat().st_mode & 0o022 == 0  # written anew, private
    (cache / "kernels").chmod(0o777)
    codegen._loaded.clear()
    try:
        module = codegen.load_module("shared", "k", lambda: made.append(2) or "V = 1\n")
    finally:
        codegen._private.clear()
    assert module.V == 1 and made == [1, 2]
    assert not Path(module.__file__).is_relative_to(cache)
    err = capsys.readouterr().err.splitlines()
    assert err == [f"mechsim: warning: cache {cache / 'kernels'} is writable by others: not "
                   f"used (this process builds in {Path(module.__file__).parent.parent})"]


def test_a_symlinked_marker_is_not_followed(cache: Path, tmp_path: Path) -> None:
    """The last-use marker planted as a symlink to a file outside the cache: using the
    module neither creates nor touches the target; the link is replaced by a marker."""
    codegen.load_module("marked", "k", lambda: "M = 1\n")
    marker = _module(cache, "marked").with_suffix(".used")
    marker.unlink()
    outside = tmp_path / "outside"
    marker.symlink_to(outside)
    codegen._loaded.clear()
    codegen.load_module("marked", "k", lambda: "M = 1\n")
    assert not outside.exists() and not marker.is_symlink() and marker.is_file()


def test_a_summary_that_does_not_match_its_key_is_not_recalled(cache: Path) -> None:
    codegen.remember("summary_key", {"coordinates": ["x"]})
    path = cache / "summaries" / "summary_key.json"
    record = json.loads(path.read_text())
    record["value"]["coordinates"] = ["y"]  # edited, the check left as it was
    path.write_text(json.dumps(record))
    assert codegen.recall("summary_key") is None
    path.unlink()
    path.symlink_to(cache / "elsewhere.json")
    (cache / "elsewhere.json").write_text(json.dumps(record))
    assert codegen.recall("summary_key") is None  # never read through a link


def test_a_summary_is_read_from_its_file_once_a_process(cache: Path) -> None:
    """What ``recall`` read stands for its key until ``remember`` replaces it or the cache is
    cleared: the file is not read again (here: removed, and still recalled)."""
    codegen.remember("summary_key", {"coordinates": ["x"]})
    path = cache / "summaries" / "summary_key.json"
    assert codegen.recall("summary_key") == {"coordinates": ["x"]}
    path.unlink()
    assert codegen.recall("summary_key") == {"coordinates": ["x"]}
    codegen.remember("summary_key", {"coordinates": ["y"]})
    assert codegen.recall("summary_key") == {"coordinates": ["y"]}
    codegen.cache_clear()
    assert codegen.recall("summary_key") is None


def test_summaries_stay_bounded_when_a_sweep_remembers_many(
        cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(codegen, "MAX_SUMMARIES", 3)
    monkeypatch.setattr(codegen, "_PRUNE_EVERY", 4)
    monkeypatch.setattr(codegen, "_remembered", [0])
    for k in range(20):
        codegen.remember(f"summary_{k}", {"k": k})
        held = len(list((cache / "summaries").glob("*.json")))
        assert held <= 3 + 4, (k, held)
    assert codegen.recall("summary_19") == {"k": 19}
