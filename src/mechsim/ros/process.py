"""Process plumbing shared by the launcher, the recorder and helper processes: a child that dies
with its parent, SIGTERM taking the same clean path as Ctrl-C, and stops held while files are
being created or completed; a consumer draining before it stops, and reports to the parent.
Standard library only (and the project's atomic files)."""

from __future__ import annotations

import _signal
import ctypes
import json
import os
import signal
import threading
import time
from collections.abc import Callable
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
    same clean path as Ctrl-C: outputs completed, nodes destroyed."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, _interrupt)


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
            raise KeyboardInterrupt


#: A consumer process stops once nothing arrived for this long after its stop signal (the
#: simulators waited for every reader's acknowledgment before they exited).
DRAIN_QUIET = 0.5
#: Longest drain, however busy the graph.
DRAIN_LIMIT = 60.0
#: A file the launcher of a multi-process run leaves beside the consumers' reports when none
#: of its simulators published anything (a refused start): nothing of the run to drain. (What
#: arrives then comes from another graph's nodes of the same names, and never stops.)
NOTHING_PUBLISHED = "nothing-published"


def drain(executor: Any, received: Callable[[], int], report: str | None = None) -> None:
    """Spin ``executor`` until ``received()`` has not changed for ``DRAIN_QUIET`` s: the
    messages in flight when a consumer was told to stop are taken, not dropped. None when
    ``NOTHING_PUBLISHED`` lies beside ``report``."""
    if report is not None and os.path.exists(
            os.path.join(os.path.dirname(report), NOTHING_PUBLISHED)):
        return
    end = time.monotonic() + DRAIN_LIMIT
    last, quiet_since = received(), time.monotonic()
    while time.monotonic() < end and time.monotonic() - quiet_since < DRAIN_QUIET:
        executor.spin_once(timeout_sec=0.05)
        if received() != last:
            last, quiet_since = received(), time.monotonic()


def write_report(path: str | None, data: dict[str, Any]) -> None:
    """What a child process did, as JSON for its parent (written atomically)."""
    if path is not None:
        from mechsim.files import write_atomic

        write_atomic(path, json.dumps(data))


def exit_process(code: int) -> None:
    """End a command's process with ``code`` without tearing the interpreter down.

    By the time a command returns, its outputs are complete and its ROS contexts shut down;
    what a normal exit adds is the interpreter's finalization, about 0.3 s of CPU with sympy,
    numba and rclpy loaded, on every command. Exit handlers still run. If a thread that a
    normal exit would wait for is still alive, the process exits normally instead."""
    import atexit
    import sys

    main = threading.main_thread()
    if any(t is not main and not t.daemon and t.is_alive() for t in threading.enumerate()):
        sys.exit(code)
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe or stream: nothing left to deliver
            pass
    os._exit(code)
