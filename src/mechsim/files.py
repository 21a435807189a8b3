"""Files written and read without surprises: the one home of mechsim's file safety.

Writing. A file is never written in place: :func:`atomic_file` (and :func:`write_atomic` on top of
it) creates a temporary next to the target with :func:`tempfile.mkstemp` (``O_CREAT|O_EXCL`` and
``O_NOFOLLOW``: a symlink or file planted at a predictable name is never followed or reused), and
renames it over the target only once it is complete and on disk (``fsync``). An interrupted or
failed write leaves the target as it was and removes the temporary. With ``replace=False`` the
rename refuses an existing target (a hard link, atomic on POSIX file systems), so an output is
never overwritten unless the caller was asked to. :func:`make_dir` creates a directory
exclusively: no check-then-create.

Reading. Text from outside (bag metadata, YAML in a recording) is read by
:func:`read_bounded`, which refuses anything but a regular file (a FIFO would block, a device
would never end) and anything larger than a bound; :func:`load_yaml` parses it with the safe
loader and refuses YAML aliases, so a few hundred bytes cannot expand into gigabytes when the
result is printed or copied.
"""

from __future__ import annotations

import contextlib
import errno
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

import yaml

from mechsim.errors import MechsimError

#: Default bound of :func:`read_bounded` (metadata files are kilobytes).
MAX_TEXT_BYTES = 8 * 1024 * 1024


@contextlib.contextmanager
def atomic_file(path: str | Path, *, replace: bool = True,
                mode: int = 0o644) -> Iterator[IO[bytes]]:
    """A binary file object whose content becomes ``path`` when the block ends without error.

    The temporary is ``.<name>.<random>.tmp`` in the target's directory, created exclusively
    and without following symlinks; it gets ``mode`` (default rw-r--r--, as a plain ``open``
    would under the usual umask), is fsynced and renamed onto ``path``. On any exception the
    temporary is removed and ``path`` is untouched. ``replace=False``: FileExistsError if
    ``path`` exists at the moment of the rename."""
    target = Path(path)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, mode)
        with os.fdopen(fd, "wb") as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        publish(tmp, target, replace=replace)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def write_atomic(path: str | Path, data: str | bytes, *, replace: bool = True) -> None:
    """Write ``data`` (text is UTF-8) to ``path`` through :func:`atomic_file`: readers, other
    processes included, see the old file or the complete new one, never a partial file."""
    with atomic_file(path, replace=replace) as f:
        f.write(data.encode() if isinstance(data, str) else data)


def publish(tmp: str | Path, path: str | Path, *, replace: bool = True) -> None:
    """Rename the finished temporary ``tmp`` onto ``path`` (same directory). ``replace=False``
    never overwrites: FileExistsError if ``path`` exists (a symlink included)."""
    if replace:
        os.replace(tmp, path)
        return
    try:
        os.link(tmp, path, follow_symlinks=False)
    except OSError as e:
        if e.errno == errno.EEXIST:
            raise
        # A file system without hard links: the check and the rename are two steps here.
        if os.path.lexists(path):
            raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST), str(path)) from None
        os.rename(tmp, path)
        return
    os.unlink(tmp)


def make_dir(path: str | Path) -> bool:
    """Create directory ``path`` (parents as needed). True if this call created it; False if
    it already was a directory (not a symlink to one); MechsimError otherwise."""
    d = Path(path)
    try:
        try:
            os.mkdir(d)
        except FileNotFoundError:
            d.parent.mkdir(parents=True, exist_ok=True)
            os.mkdir(d)
        return True
    except FileExistsError:
        st = os.lstat(d)
        if stat.S_ISLNK(st.st_mode):
            raise MechsimError(f"{d}: is a symbolic link (give the real directory)") from None
        if not stat.S_ISDIR(st.st_mode):
            raise MechsimError(f"{d}: exists and is not a directory") from None
        return False


def open_exclusive(path: str | Path) -> IO[bytes]:
    """A new file opened for writing: fails if anything (a symlink included) is at ``path``."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC,
                 0o644)
    return os.fdopen(fd, "wb")


def anonymous_file(directory: str | Path) -> IO[bytes]:
    """A new read-write file in ``directory`` that has no name, so nothing is left behind
    however the process ends: ``O_TMPFILE`` where the file system supports it, else created
    exclusively without following symlinks (``.<random>.tmp``) and unlinked at once."""
    flags = os.O_RDWR | os.O_CLOEXEC | os.O_NOFOLLOW
    tmpfile = getattr(os, "O_TMPFILE", 0)
    if tmpfile:
        try:
            return os.fdopen(os.open(directory, flags | tmpfile | os.O_EXCL, 0o600), "w+b")
        except OSError as e:  # not supported by the kernel or this file system
            if e.errno not in (errno.EOPNOTSUPP, errno.EISDIR, errno.EINVAL):
                raise
    fd, name = tempfile.mkstemp(dir=directory, prefix=".", suffix=".tmp")
    try:
        os.unlink(name)
    except BaseException:
        os.close(fd)
        raise
    return os.fdopen(fd, "w+b")


def open_regular(path: str | Path, *, follow: bool = True) -> IO[bytes]:
    """``path`` opened for reading if it is a regular file (never blocks on a FIFO, never
    reads a device); OSError otherwise. ``follow=False``: never through a symbolic link."""
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC
                 | (0 if follow else os.O_NOFOLLOW))
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise OSError(errno.EINVAL, "not a regular file", str(path))
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_bounded(path: str | Path, limit: int = MAX_TEXT_BYTES) -> bytes:
    """The bytes of regular file ``path``; OSError (EFBIG) if it holds more than ``limit``."""
    with open_regular(path) as f:
        data = f.read(limit + 1)
    if len(data) > limit:
        raise OSError(errno.EFBIG, f"larger than {limit} bytes", str(path))
    return data


class _NoAliasLoader(yaml.SafeLoader):
    """The safe loader, refusing aliases (``*name``): no expansion, no shared sub-trees."""

    def compose_node(self, parent: Any, index: Any) -> Any:
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.composer.ComposerError(None, None, "aliases are not allowed",
                                              event.start_mark)
        return super().compose_node(parent, index)


def load_yaml(text: str | bytes, what: str, limit: int = MAX_TEXT_BYTES) -> Any:
    """Parse YAML from outside: at most ``limit`` bytes of UTF-8, no aliases, no tags beyond
    the safe ones. MechsimError naming ``what`` and the reason (one line) otherwise."""
    if len(text) > limit:
        raise MechsimError(f"{what}: larger than {limit} bytes")
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as e:
            raise MechsimError(f"{what}: not UTF-8 (byte {e.start})") from None
    try:
        return yaml.load(text, Loader=_NoAliasLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.MarkedYAMLError as e:
        where = f" at line {e.problem_mark.line + 1}" if e.problem_mark else ""
        raise MechsimError(f"{what}: not valid YAML ({e.problem}{where})") from None
    except (yaml.YAMLError, RecursionError, ValueError) as e:  # ValueError: a huge integer
        raise MechsimError(f"{what}: not valid YAML ({type(e).__name__})") from None
