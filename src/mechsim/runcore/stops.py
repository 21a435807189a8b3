"""Stops: Ctrl-C and SIGTERM take one clean path through a run, and never split a sample.

SIGTERM raises KeyboardInterrupt like Ctrl-C (``stop_on_sigterm``), so every stop completes the
outputs and destroys the nodes the same way. A stop that lands in compiled or C code comes out
wrapped in another exception; ``raise_if_stop`` finds it there, so a handler for a system's own
failures never takes a stop for one. While samples are released (published, recorded and the
run's state moved on to them) or files are created or completed, ``held_signals`` holds the
stop until the block ends: what was published and the run's time always agree.
A child process stops with its parent (``die_with_parent``). Standard library only.
"""

from __future__ import annotations

import _signal
import ctypes
import os
import signal
import threading
from typing import Any

_PR_SET_PDEATHSIG = 1

#: Set once a stop signal arrived (a stop that rclpy converted into another exception on its
#: way out is still recognised as a stop).
stopping = threading.Event()


def die_with_parent(parent_pid: int) -> None:
    """Make this process receive SIGTERM when its parent dies (Linux ``PR_SET_PDEATHSIG``, also
    after a SIGKILL of the parent); if the parent is already gone, SIGTERM now."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    except (OSError, AttributeError):  # not Linux: the parent's own handler still stops us
        pass
    if os.getppid() != parent_pid:
        os.kill(os.getpid(), signal.SIGTERM)


def stop_on_sigterm() -> None:
    """SIGTERM raises KeyboardInterrupt from now on (main thread only), so every stop takes the
    same clean path as Ctrl-C: outputs completed, nodes destroyed. Both also set ``stopping``:
    a stop whose KeyboardInterrupt lands in a finalizer (``__del__``, where Python prints and
    drops it) still ends a loop that checks it."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _interrupt)
        signal.signal(signal.SIGINT, _interrupt)


def _interrupt(signum: int, frame: Any) -> None:
    stopping.set()
    raise KeyboardInterrupt


def raise_if_stop(error: BaseException) -> None:
    """Re-raise the stop inside ``error``, if any. A Ctrl-C or SIGTERM that lands while compiled
    or C code runs comes out wrapped (``SystemError: ... returned a result with an exception
    set``, the KeyboardInterrupt as its cause): without this, a handler for a system's own
    failures would take the stop for one and the run would go on."""
    seen: set[int] = set()
    e: BaseException | None = error
    while e is not None and id(e) not in seen:
        if not isinstance(e, Exception):
            raise e
        seen.add(id(e))
        e = e.__cause__ or e.__context__


def is_stop(error: BaseException) -> bool:
    """Is ``error`` a stop (Ctrl-C, SIGTERM), itself or wrapped, or did one arrive already?"""
    if stopping.is_set():
        return True
    try:
        raise_if_stop(error)
    except BaseException:  # noqa: BLE001 - the stop found inside
        return True
    return False


_held = threading.local()
_HELD = (int(signal.SIGINT), int(signal.SIGTERM))


class held_signals:  # noqa: N801 - used like the function it was: ``with held_signals():``
    """Hold SIGINT and SIGTERM for the block (files being created or completed) and raise
    KeyboardInterrupt after it if one came. Main thread only (elsewhere: no effect). Nested
    blocks cost next to nothing (a paced run enters one per sample and node): the outermost
    one holds them."""

    __slots__ = ("_got", "_previous")

    def __enter__(self) -> None:
        self._previous: dict[Any, Any] | None = None
        if getattr(_held, "depth", 0) or threading.current_thread() \
                is not threading.main_thread():
            return
        got: list[int] = []
        self._got = got
        # (_signal's own function: signal.signal's enum conversions cost more than the
        # system calls, and a fast run enters this block several times per chunk)
        self._previous = {s: _signal.signal(s, lambda n, f: got.append(n))
                          for s in _HELD}
        _held.depth = 1

    def __exit__(self, exc_type: object, *exc: object) -> None:
        if self._previous is None:
            return
        _held.depth = 0
        for s, handler in self._previous.items():
            _signal.signal(s, handler)
        if self._got and exc_type is None:
            stopping.set()
            raise KeyboardInterrupt
