"""The lock of a bag directory: a bag being written (recorded or repaired) is not touched.

``<bag>/.mechsim.lock`` holds the writer's PID, host, process start time and purpose (JSON). It
appears atomically with its content (written to an exclusive temporary, then hard-linked to
the lock name, which fails if a lock exists), and is removed when the writer finishes.
``repair``, ``convert``, ``replay`` and ``bag info`` refuse a bag whose lock is live.

A lock is stale when its process is gone: no process with that PID, or one that started at
another time (the PID was reused). A lock from another host cannot be checked and counts as
live; the message says which file to remove. A recorder never breaks a lock (it only starts in
an empty directory); ``repair`` replaces a stale one.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import secrets
import socket
from dataclasses import dataclass
from pathlib import Path

from mechsim.errors import MechsimError
from mechsim.files import read_bounded, write_atomic

LOCK_FILE = ".mechsim.lock"
_MAX_LOCK_BYTES = 4096


def _start_time(pid: int) -> int | None:
    """Start time of process ``pid`` in clock ticks since boot (Linux /proc), else None."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
        return int(text[text.rindex(")") + 2:].split()[19])
    except (OSError, ValueError, IndexError):
        return None


@dataclass(frozen=True)
class LockInfo:
    pid: int
    host: str
    started: int | None
    purpose: str
    token: str

    @classmethod
    def mine(cls, purpose: str) -> LockInfo:
        pid = os.getpid()
        return cls(pid, socket.gethostname(), _start_time(pid), purpose, secrets.token_hex(8))

    def to_json(self) -> str:
        return json.dumps(self.__dict__) + "\n"

    @classmethod
    def parse(cls, data: bytes) -> LockInfo | None:
        try:
            d = json.loads(data.decode())
            started = d.get("started")
            info = cls(int(d["pid"]), str(d["host"]),
                       int(started) if started is not None else None,
                       str(d["purpose"]), str(d["token"]))
        except (ValueError, KeyError, TypeError, AttributeError, UnicodeDecodeError):
            return None
        return info if info.pid > 0 else None

    def alive(self) -> bool:
        if self.host != socket.gethostname():
            return True  # cannot tell
        try:
            os.kill(self.pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            pass  # exists, another user's
        except OverflowError:
            return False
        now = _start_time(self.pid)
        return self.started is None or now is None or now == self.started

    def describe(self, directory: Path) -> str:
        doing = "recorded" if self.purpose == "recording" else "repaired"
        where = "" if self.host == socket.gethostname() else f" on host {self.host}"
        return (f"bag {directory}: being {doing} by process {self.pid}{where} (wait until it "
                f"finishes; if that process is gone, remove {directory / LOCK_FILE})")


def _read(directory: Path) -> tuple[LockInfo | None, bool]:
    """(lock info or None if unreadable, whether a lock file exists)."""
    try:
        data = read_bounded(directory / LOCK_FILE, _MAX_LOCK_BYTES)
    except FileNotFoundError:
        return None, False
    except OSError:
        return None, True
    return LockInfo.parse(data), True


def live_holder(directory: Path) -> LockInfo | None:
    """The live process holding ``directory``'s lock, or None (no lock, or a stale one)."""
    info, _ = _read(directory)
    return info if info is not None and info.alive() else None


def check_not_in_use(directory: Path) -> None:
    """MechsimError if a live process is writing the bag ``directory``."""
    holder = live_holder(directory)
    if holder is not None:
        raise MechsimError(holder.describe(directory))


def has_stale_lock(directory: Path) -> bool:
    info, exists = _read(directory)
    return exists and (info is None or not info.alive())


class BagLock:
    """A held lock; :meth:`release` (or the ``with`` block's end) removes it."""

    def __init__(self, directory: Path, info: LockInfo) -> None:
        self.directory, self.info = directory, info

    @classmethod
    def acquire(cls, directory: Path, purpose: str, *, break_stale: bool) -> BagLock:
        """Take the lock of ``directory`` (MechsimError if a live process holds it; a stale
        lock is replaced only with ``break_stale``). OSError if the directory is not
        writable."""
        info = LockInfo.mine(purpose)
        path = directory / LOCK_FILE
        for _ in range(3):
            try:
                write_atomic(path, info.to_json(), replace=False)
                return cls(directory, info)
            except FileExistsError:
                other, exists = _read(directory)
                if other is not None and other.alive():
                    raise MechsimError(other.describe(directory)) from None
                if not break_stale:
                    raise MechsimError(f"bag {directory}: has a stale lock "
                                       f"{path.name} of an interrupted writer") from None
                if exists:
                    _remove_if_unchanged(path, other)
        raise MechsimError(f"bag {directory}: another process keeps taking its lock")

    def release(self) -> None:
        """Remove the lock if it is still this one (idempotent)."""
        info, _ = _read(self.directory)
        if info is not None and info.token == self.info.token:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.directory / LOCK_FILE)

    def __enter__(self) -> BagLock:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def _remove_if_unchanged(path: Path, seen: LockInfo | None) -> None:
    """Remove a stale lock unless another process replaced it since it was read."""
    try:
        now = LockInfo.parse(read_bounded(path, _MAX_LOCK_BYTES))
    except FileNotFoundError:
        return
    except OSError as e:
        if e.errno not in (errno.EINVAL, errno.EFBIG):
            raise
        now = None
    if now == seen:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)
