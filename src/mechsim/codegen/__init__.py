"""Generated, compiled modules: each model's kernel functions and the shared integrator loops.

Numba caches a compiled function on disk next to its source file, keyed on that file's time
stamp only: a change in anything else the compiled code depends on (a helper in another
module, the code generator, numba itself) would not be noticed. So every compiled module
is written here as a file whose name is a hash of *all* its inputs — for a model, what its
kernel source is made from (the declaration, the parameter index map, the generator and its
version; see ``build``), for the loops their source and every module they read — plus what
writes them and what they run against (this package's sources, the numba and Python
versions: ``RUNTIME``). A new input
gives a new file and a fresh compilation; an unchanged one is imported and loaded from
numba's cache without deriving or compiling anything.

``build`` makes a model's kernel module (derived only when missing) and returns its
``Kernels``: the functions of the kernel contract (``contract.py``), each compiled when first
needed, and the ``KernelSet`` the shared loops call them through. The shared loops are one
module for every model (``load_module``), so the per-model cost is the derivation and the
compilation of the small kernels a run needs (a run with ``yoshida8`` never compiles ``rhs``).

Beside the modules, ``remember``/``recall`` keep small JSON records keyed on every input of
what they hold: a Lagrangian model's summary and derivation key, so that a model derived before
is set up without importing sympy (``mechsim.systems.lagrangian``).

Nothing in the cache is trusted as found. The cache directory must be the user's own and
writable by no one else; otherwise it is not used (one warning line) and this process builds
in a private temporary directory. Each module has a seal beside it (``<module>.sum``: the
SHA-256 of its name and text, ``_seal``), and its bytes are read once, checked against the
seal and against the same ownership rule (a regular file of the user's, writable by no one
else), then compiled from those very bytes (no bytecode cache is read): a truncated,
swapped or planted module is removed and derived again, never imported. Numba's compiled
caches of a module whose seal does not hold are removed with it. Markers and every write go
through the non-following, atomic writers of ``mechsim.files`` (a planted symlink is
replaced, never followed); summaries (``recall``) carry a hash of their key and value.

The cache is bounded (``MAX_MODULES`` modules, ``MAX_SUMMARIES`` records; the least recently
used are removed first) and ``cache_info``/``cache_clear`` report and empty it (``mechsim cache
info|clear``; ``mechsim cache warm`` fills it).
"""

from __future__ import annotations

import atexit
import contextlib
import functools
import hashlib
import importlib.metadata
import importlib.util
import json
import os
import shutil
import stat
import sys
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, Any

from mechsim import files
from mechsim.codegen.names import ARGUMENTS, CONTRACT, FUNCTIONS, HOT, SIZES, KernelContract

if TYPE_CHECKING:
    from mechsim.codegen.contract import KernelSet

__all__ = ["ARGUMENTS", "FUNCTIONS", "HOT", "SIZES", "Kernels", "KernelSource", "build",
           "cache_clear", "cache_dir", "cache_info", "decorator", "distribution_version",
           "fingerprint", "load_module", "package_fingerprint", "recall", "remember",
           "source_fingerprint", "write_atomic"]


#: At most this many generated modules are kept; the least recently used go first.
MAX_MODULES = 400
#: At most this many recalled model summaries (``recall``, a few hundred bytes each) are kept.
MAX_SUMMARIES = 2000
#: A recalled summary larger than this is not read (the largest model's is a few kB).
_SUMMARY_BYTES = 1_000_000
#: A module used within this many seconds is never evicted (another process may load it).
_EVICT_GRACE = 600.0
_PREFIX = "mechsim_"
_loaded: dict[str, ModuleType] = {}
_kernels: dict[str, Kernels] = {}


def configured_cache_dir() -> Path:
    """The cache directory asked for: $MECHSIM_CACHE_DIR, else $XDG_CACHE_HOME/mechsim."""
    env = os.environ.get("MECHSIM_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache")
    return Path(base) / "mechsim"


def distrust(st: os.stat_result, *, directory: bool) -> str | None:
    """Why an entry (``os.lstat``) of the cache is not to be trusted, or None: it must be a
    directory or regular file (no symlink) of this user's, writable by no one else."""
    kind = stat.S_ISDIR if directory else stat.S_ISREG
    if not kind(st.st_mode):
        return "is a symbolic link" if stat.S_ISLNK(st.st_mode) else \
            f"is not a {'directory' if directory else 'regular file'}"
    if st.st_uid != os.getuid():
        return f"belongs to another user (uid {st.st_uid})"
    if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return "is writable by others"
    return None


_private: list[Path] = []  # this process's own cache, when the configured one is refused


def cache_dir() -> Path:
    """Where generated modules live: the configured directory (``configured_cache_dir``) if
    it is trusted (``distrust``: it and its ``kernels`` and ``summaries`` folders the user's,
    writable by no one else) or does not exist yet; else, with one warning line, a private
    temporary directory of this process."""
    if _private:
        return _private[0]
    folder = configured_cache_dir()
    for d in (folder, folder / "kernels", folder / "kernels" / "__pycache__",
              folder / "summaries"):
        try:
            why = distrust(os.lstat(d), directory=True)
        except OSError:
            continue  # not there: made by this user when needed
        if why is not None:
            _private.append(Path(tempfile.mkdtemp(prefix="mechsim-cache-")))
            atexit.register(shutil.rmtree, _private[0], ignore_errors=True)
            print(f"mechsim: warning: cache {d} {why}: not used (this process builds in "
                  f"{_private[0]})", file=sys.stderr)
            return _private[0]
    return folder


def _module_dir() -> Path:
    return cache_dir() / "kernels"


def _make_private(folder: Path) -> None:
    """Create ``folder`` (in the cache) and the cache directory above it as this user's,
    writable by no one else whatever the umask (``distrust`` would refuse them otherwise)."""
    root = cache_dir()
    root.parent.mkdir(parents=True, exist_ok=True)
    for d in (root, folder):
        d.mkdir(mode=0o700, exist_ok=True)


def write_atomic(path: Path, text: str | bytes) -> None:
    """Write ``text`` to ``path`` through the project's one atomic writer (concurrent
    processes, parallel test workers or several nodes, never see a partial file)."""
    if path.parent.parent == cache_dir():
        _make_private(path.parent)
    else:
        path.parent.mkdir(parents=True, exist_ok=True)
    files.write_atomic(path, text)


def fingerprint(*parts: object) -> str:
    """A short stable hash of ``parts`` (their reprs)."""
    return hashlib.sha256(repr(parts).encode()).hexdigest()[:16]


def source_fingerprint(modules: Iterable[ModuleType | Path]) -> str:
    """Hash of the source text of ``modules`` (module objects or source paths)."""
    texts = []
    for m in modules:
        path = m if isinstance(m, Path) else getattr(m, "__file__", None)
        texts.append(Path(path).read_text() if path else getattr(m, "__name__", str(m)))
    return fingerprint(*texts)


#: What every generated module is written by and runs against (this package's sources, read
#: from the files so that importing it does not import numba, and the numba and Python
#: versions): a change here invalidates all of them.
RUNTIME = fingerprint(source_fingerprint(sorted(Path(__file__).parent.glob("*.py"))),
                      importlib.metadata.version("numba"), sys.version_info[:2])


@functools.cache
def package_fingerprint() -> str:
    """Hash of the source text of every module of the ``mechsim`` package (read once per
    process): what a recalled summary (``recall``) must have been made by."""
    root = Path(__file__).resolve().parent.parent
    return source_fingerprint(sorted(root.rglob("*.py")))


@functools.cache
def distribution_version(name: str) -> str:
    """The installed version of distribution ``name`` ("" if it is not installed)."""
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        return ""


def decorator(name: str) -> str:
    """The decorator line of a generated function (contract function or helper): compiled
    lazily, for what its callers pass, with IEEE arithmetic (a division by zero gives inf or
    nan, which the loops report as a non-finite state, instead of raising inside a loop).

    Numba gives every compiled function two entry points besides its own: one for calls from
    Python and one for calls through a function value; building them is much of the work of
    compiling a small kernel. A helper (any name outside the contract) is only called from
    the module's compiled code, so it gets neither; a ``HOT`` function is called from Python
    and through its pointer wrapper (``KernelSource.text``), so it gets no function-value
    entry. The same code runs either way."""
    if name not in FUNCTIONS:
        return ('@njit(cache=True, error_model="numpy", no_cpython_wrapper=True, '
                'no_cfunc_wrapper=True)')
    if name in HOT:
        return '@njit(cache=True, error_model="numpy", no_cfunc_wrapper=True)'
    return '@njit(cache=True, error_model="numpy")'


_HEADER = '''"""Generated by mechsim for {name}; do not edit."""
# inputs: {key}
import math

import numpy as np
from numba import carray, njit

from mechsim.codegen.support import all_below as _all_below
from mechsim.codegen.support import matrix as _matrix
from mechsim.codegen.support import project_onto as _project_onto
from mechsim.codegen.support import solve as _solve
from mechsim.codegen.support import tensor as _tensor
from mechsim.codegen.support import vector as _vector
from mechsim.codegen.support import zero_matrix as _zero_matrix
from mechsim.codegen.support import zero_vector as _zero_vector

'''


@dataclass
class KernelSource:
    """A model's kernel module before it is written: its ``body`` defines (with ``decorator``
    lines) the contract functions listed in ``functions`` and any helpers they call; the
    ``constants`` (the sizes ``contract.SIZES`` and any index constants) come first."""

    name: str
    constants: dict[str, int | float] = field(default_factory=dict)
    body: str = ""
    functions: tuple[str, ...] = ()

    def text(self, key: str) -> str:
        consts = "\n".join(f"{k} = {v!r}" for k, v in sorted(self.constants.items()))
        listed = ", ".join(f'"{n}": {n}' for n in self.functions)
        wrappers = []
        for n in self.functions:
            if n in HOT:  # compiled as a C callback by Kernels when a loop needs it
                a, b, c = (f"carray({x}, ({size},))" for x, size in zip(
                    ("y", "p", "out"), CONTRACT[n].pointer_sizes, strict=True))
                wrappers.append(f"def _pointer_{n}(t, y, p, out):\n    {n}(t, {a}, {b}, {c})\n")
        pointers = ", ".join(f'"{n}": _pointer_{n}' for n in self.functions if n in HOT)
        return (_HEADER.format(name=self.name, key=key) + f"{consts}\n\n{self.body}\n\n"
                + "\n\n".join(wrappers) + f"\n\nKERNELS = {{{listed}}}\n"
                f"POINTER_KERNELS = {{{pointers}}}\n")


class Kernels(KernelContract):
    """A model's kernel functions (numba functions, callable from Python and compiled code,
    see ``contract.py``), its sizes (``n_q``, ``n_y``, …; the attributes of ``KernelContract``)
    and, from ``kernel_set``, the compiled record of both that the shared integrator loops
    take."""

    def __init__(self, name: str, module: ModuleType) -> None:
        from mechsim.codegen import contract

        self.name = name
        self.module = module
        self._functions: dict[str, Any] = dict(module.KERNELS)
        for n in FUNCTIONS:
            setattr(self, n, self._functions.get(n, contract.NOTHING[n]))
        self.sizes = {s: int(getattr(module, s)) for s in SIZES}
        for s, value in self.sizes.items():
            setattr(self, s.lower(), value)
        self._compiled: dict[str, Any] = {}
        self._sets: dict[frozenset[str], KernelSet] = {}
        self._by_request: dict[tuple[str, ...], KernelSet] = {}

    def _compile(self, name: str) -> Any:
        """The loop-callable form of kernel function ``name`` (compiled now if need be)."""
        from numba import cfunc

        from mechsim.codegen.contract import POINTER_SIGNATURE, SIGNATURES

        if name not in self._compiled:
            # numba reads its disk cache when it compiles: a process that waited for the
            # lock loads what the one before it compiled
            source = self.module.__file__
            with _exclusive(Path(source) if source else None):
                if name in HOT:
                    wrapper = self.module.POINTER_KERNELS[name]
                    self._compiled[name] = cfunc(POINTER_SIGNATURE, cache=True)(wrapper)
                else:
                    f = self._functions[name]
                    f.compile(SIGNATURES[name].args)
                    self._compiled[name] = f
        return self._compiled[name]

    def kernel_set(self, *needed: str) -> KernelSet:
        """A kernel set in which at least the functions ``needed`` are the model's own
        (compiled on first need; the others may be no-ops): what a loop gets."""
        known = self._by_request.get(needed)
        if known is not None:
            return known
        self._by_request[needed] = ks = self._kernel_set(needed)
        return ks

    def _kernel_set(self, needed: tuple[str, ...]) -> KernelSet:
        from mechsim.codegen.contract import make_kernel_set

        wanted = frozenset(n for n in needed if n in self._functions)
        for have, ks in self._sets.items():
            if wanted <= have:
                return ks
        have = wanted | frozenset(self._compiled)
        ks = make_kernel_set({n: self._compile(n) for n in have}, self.sizes)
        self._sets[have] = ks
        return ks


def _seal(modname: str, text: bytes) -> str:
    """What a module's ``.sum`` holds: the SHA-256 of its name (its key) and its text."""
    return hashlib.sha256(modname.encode() + b"\0" + text).hexdigest()


def _verified(modname: str, path: Path) -> bytes | None:
    """The text of cached module ``path`` if it is trusted (``distrust``) and matches its
    seal; else None (nothing there, or something that must not be imported)."""
    try:
        with files.open_regular(path, follow=False) as f:
            if distrust(os.fstat(f.fileno()), directory=False) is not None:
                return None
            text = f.read()
        with files.open_regular(path.with_suffix(".sum"), follow=False) as f:
            if distrust(os.fstat(f.fileno()), directory=False) is not None:
                return None
            seal = f.read(100).decode("ascii", "replace").strip()
    except OSError:
        return None
    return text if seal == _seal(modname, text) else None


def _import(modname: str, path: Path, text: bytes) -> ModuleType:
    """The module compiled from ``text`` (the verified bytes of ``path``, which numba's
    cache locates by): no bytecode cache is read or written."""
    spec = importlib.util.spec_from_loader(modname, loader=None, origin=str(path))
    assert spec is not None
    module = importlib.util.module_from_spec(spec)
    module.__file__ = str(path)
    sys.modules[modname] = module
    try:
        exec(compile(text, str(path), "exec"), module.__dict__)  # noqa: S102 - verified above
    except BaseException:
        sys.modules.pop(modname, None)
        raise
    return module


@contextlib.contextmanager
def _exclusive(path: Path | None) -> Iterator[None]:
    """Hold the build lock of generated module ``path`` (``<module>.lock`` beside it), so
    that processes needing the same model at once (the nodes of a scene, test workers) derive
    and compile it once: the others wait, then find it in the cache. Without a lock (a cache
    that cannot take one), build anyway."""
    import fcntl

    if path is None:
        yield
        return
    try:
        fd = os.open(path.with_suffix(".lock"),
                     os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    except OSError:
        yield
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)  # and with it the lock


def _touch(path: Path) -> None:
    """Record a use of a generated module (its .used marker; the module file itself keeps its
    time stamp, which numba's cache index is keyed on)."""
    with contextlib.suppress(OSError):
        files.write_atomic(path.with_suffix(".used"), b"")  # a planted link is replaced


def load_module(name: str, key: str, make_text: Callable[[], str]) -> ModuleType:
    """Import the generated module ``name`` for the inputs ``key`` (any string that changes
    whenever the module's text would), writing it with ``make_text()`` first if it is not in
    the cache. Imported once per process."""
    modname = f"{_PREFIX}{name}_{fingerprint(key, RUNTIME)}"
    if modname in _loaded:
        return _loaded[modname]
    folder = _module_dir()
    path = folder / f"{modname}.py"
    text = _verified(modname, path)
    if text is None:
        _make_private(folder)
        _make_private(folder / "__pycache__")  # numba's caches: made here, not by umask
        with _exclusive(path):
            text = _verified(modname, path)  # another process may have derived it meanwhile
            if text is None:
                _remove_module(path, keep_lock=True)  # and numba's caches of what was there
                text = make_text().encode()
                write_atomic(path, text)
                write_atomic(path.with_suffix(".sum"), _seal(modname, text) + "\n")
                _evict(folder)
    _touch(path)
    module = _import(modname, path, text)
    _loaded[modname] = module
    return module


def _summary_dir() -> Path:
    return cache_dir() / "summaries"


#: What ``recall`` read in this process, by key: a key stands for every input of what it
#: holds, so it is read from disk once a process (a sweep of a value the declaration does not
#: read sets up each model from one summary); ``remember`` and ``cache_clear`` drop what they
#: replace or remove. Emptied when full.
_recalled: dict[str, dict[str, Any]] = {}
_MAX_RECALLED = 4096


def _keep(key: str, value: dict[str, Any]) -> None:
    if len(_recalled) >= _MAX_RECALLED:
        _recalled.clear()
    _recalled[key] = value


def recall(key: str) -> dict[str, Any] | None:
    """What ``remember`` stored under ``key`` (a hash of every input of what it holds), or
    None when there is nothing, or nothing readable (then the caller makes it again). The
    value is the caller's to read, not to change."""
    kept = _recalled.get(key)
    if kept is not None:
        return kept
    path = _summary_dir() / f"{key}.json"
    try:
        with files.open_regular(path, follow=False) as f:
            if distrust(os.fstat(f.fileno()), directory=False) is not None:
                return None
            data = f.read(_SUMMARY_BYTES + 1)  # not one of ours if larger: never read whole
        record = json.loads(data) if len(data) <= _SUMMARY_BYTES else None
    except (OSError, ValueError):
        return None
    if not (isinstance(record, dict) and isinstance(record.get("value"), dict)
            and record.get("check") == _summary_check(key, record["value"])):
        return None
    _touch_file(path)
    _keep(key, record["value"])
    return record["value"]


def _summary_check(key: str, value: dict[str, Any]) -> str:
    """The hash a stored summary carries: its key and its value."""
    return hashlib.sha256(key.encode() + b"\0" + json.dumps(value, sort_keys=True).encode()
                          ).hexdigest()


#: ``remember`` looks at the size of the summaries' folder on its first call in a process and
#: then on every ``_PRUNE_EVERY``-th (a sweep over a value a declaration reads, a count or a
#: curve, remembers a summary per value: listing and sorting the whole folder each time would
#: cost more than the run).
_PRUNE_EVERY = 64
_remembered = [0]


def remember(key: str, value: dict[str, Any]) -> None:
    """Store ``value`` (JSON) under ``key`` for ``recall``; a cache that cannot be written is
    left as it is. At most ``MAX_SUMMARIES`` are kept (beyond by fewer than ``_PRUNE_EVERY``
    per process between looks), the least recently used go first."""
    folder = _summary_dir()
    _recalled.pop(key, None)  # the file is what the next ``recall`` reads
    with contextlib.suppress(OSError):
        write_atomic(folder / f"{key}.json", json.dumps(
            {"check": _summary_check(key, value), "value": value}, sort_keys=True))
        _remembered[0] += 1
        if (_remembered[0] - 1) % _PRUNE_EVERY:
            return
        entries = sorted(folder.glob("*.json"))
        if len(entries) > MAX_SUMMARIES:
            for path in sorted(entries, key=_last_use)[: len(entries) - MAX_SUMMARIES]:
                with contextlib.suppress(OSError):
                    path.unlink()


def _touch_file(path: Path) -> None:
    """A use of ``path`` (its time stamp), set on the file itself, never through a link."""
    with contextlib.suppress(OSError, NotImplementedError):
        os.utime(path, follow_symlinks=False)


def build(name: str, key: str, make_source: Callable[[], KernelSource]) -> Kernels:
    """The kernels of a model: ``name`` (system id and formulation), ``key`` everything its
    kernel source is made from; ``make_source`` (the derivation) runs only on a cache miss."""
    full_key = fingerprint(key, RUNTIME)
    if full_key in _kernels:
        return _kernels[full_key]
    module = load_module(name, key,
                         lambda: make_source().text(fingerprint(key, RUNTIME)))
    kernels = Kernels(name, module)
    _kernels[full_key] = kernels
    return kernels


# --- the cache on disk ------------------------------------------------------------------------


def _entries(folder: Path) -> list[Path]:
    return sorted(folder.glob(f"{_PREFIX}*.py")) if folder.is_dir() else []


def _last_use(path: Path) -> float:
    for p in (path.with_suffix(".used"), path):
        with contextlib.suppress(OSError):
            return p.stat().st_mtime
    return 0.0


def _remove_module(path: Path, keep_lock: bool = False) -> int:
    """Delete a generated module, its seal, use marker and compiled caches (and its lock,
    unless ``keep_lock``: held by the caller); bytes freed."""
    freed = 0
    stem = path.stem
    victims = [path, path.with_suffix(".used"), path.with_suffix(".sum"),
               *([] if keep_lock else [path.with_suffix(".lock")])]
    pycache = path.parent / "__pycache__"
    if pycache.is_dir():
        victims += [p for p in pycache.iterdir() if p.name.startswith(stem + ".")]
    for p in victims:
        with contextlib.suppress(OSError):
            freed += p.lstat().st_size
            p.unlink()
    return freed


def _evict(folder: Path) -> None:
    """Remove the least recently used modules beyond ``MAX_MODULES`` (not recently used ones)."""
    entries = _entries(folder)
    if len(entries) <= MAX_MODULES:
        return
    now = time.time()
    for path in sorted(entries, key=_last_use)[: len(entries) - MAX_MODULES]:
        if now - _last_use(path) > _EVICT_GRACE:
            _remove_module(path)


def _size(folder: Path) -> int:
    total = 0
    if folder.is_dir():
        for p in folder.rglob("*"):
            with contextlib.suppress(OSError):
                if p.is_file():
                    total += p.stat().st_size
    return total


def cache_info() -> dict[str, Any]:
    """Where the cache is, how many generated modules it holds and their size on disk."""
    folder = _module_dir()
    entries = _entries(folder)
    summaries = _summary_dir()
    return {"path": str(cache_dir()), "modules": len(entries),
            "loops": sum(1 for p in entries if p.stem.startswith(f"{_PREFIX}loops_")),
            "summaries": sum(1 for _ in summaries.glob("*.json")) if summaries.is_dir() else 0,
            "bytes": _size(cache_dir()) if cache_dir().is_dir() else 0,
            "limit": MAX_MODULES}


def cache_clear() -> int:
    """Delete every generated module, compiled cache and recalled summary (and leftovers of
    older layouts); returns how many modules were removed. Nothing else in the directory is
    touched."""
    folder = _module_dir()
    removed = 0
    for path in _entries(folder):
        _remove_module(path)
        removed += 1
    pycache = folder / "__pycache__"
    if pycache.is_dir():
        for p in pycache.iterdir():
            if p.name.startswith(_PREFIX):
                with contextlib.suppress(OSError):
                    p.unlink()
    summaries = _summary_dir()
    _recalled.clear()
    if summaries.is_dir():
        for p in summaries.glob("*.json"):
            with contextlib.suppress(OSError):
                p.unlink()
    derived = cache_dir() / "derived"  # an older layout kept derivations apart
    if derived.is_dir():
        for p in derived.glob("*.py"):
            with contextlib.suppress(OSError):
                p.unlink()
    _loaded.clear()
    _kernels.clear()
    return removed
