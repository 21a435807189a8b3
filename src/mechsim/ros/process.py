"""Process plumbing shared by the node processes of a multi-process run: a consumer draining
before it stops, reports to the parent, a quick exit. (Stops, and a child that dies with its
parent: ``mechsim.runcore.stops``.) Standard library only (and the project's atomic files)."""

from __future__ import annotations

import contextlib
import faulthandler
import functools
import json
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import IO, Any

#: A consumer process stops once nothing arrived for this long after its stop signal (the
#: simulators waited for every reader's acknowledgment before they exited).
DRAIN_QUIET = 0.5
#: Longest drain, however busy the graph.
DRAIN_LIMIT = 60.0
#: A file the launcher of a multi-process run leaves beside the consumers' reports when none
#: of its simulators published anything (a refused start): nothing of the run to drain. (What
#: arrives then comes from another graph's nodes of the same names, and never stops.)
NOTHING_PUBLISHED = "nothing-published"
#: Longest a node process waits for DDS to destroy its endpoints or shut its context down.
#: Normally well under a second; Fast DDS can deadlock there (its discovery thread removing a
#: participant that left while a writer of ours is deleted, each holding the lock the other
#: waits for), and a process stuck there would hold its whole multi-process run forever.
TEARDOWN_LIMIT = 20.0


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


@contextlib.contextmanager
def bounded_teardown(what: str, code: Callable[[], int],
                     limit: float = TEARDOWN_LIMIT) -> Iterator[None]:
    """Run the block (DDS teardown); if it has not returned within ``limit`` s, say so in one
    line on stderr and end the process with ``code()`` (exit handlers not run: a thread of
    the interpreter is stuck in DDS). If the stuck call holds the interpreter lock (as
    rclpy's destruction of a publisher does), no Python thread can run: ``HELD_LOCK_GRACE``
    s later the interpreter's fault handler, which needs no lock, ends the process with
    status 1 (its traceback dump sent to the null device)."""
    done = threading.Event()

    def expire() -> None:
        if not done.wait(limit):
            print(f"mechsim: {what} did not return within {limit:g} s (DDS teardown stuck); "
                  "exiting", file=sys.stderr, flush=True)
            os._exit(code())

    threading.Thread(target=expire, name="teardown-limit", daemon=True).start()
    faulthandler.dump_traceback_later(limit + HELD_LOCK_GRACE, exit=True, file=_null_device())
    try:
        yield
    finally:
        done.set()
        faulthandler.cancel_dump_traceback_later()


def end_node_process(what: str, code: Callable[[], int], executor: Any, node: Any,
                     context: Any) -> None:
    """A node process's DDS teardown, bounded (``bounded_teardown``): its executor, its node
    (None: never made) and its context (which destroys any node of it still alive)."""
    with bounded_teardown(what, code):
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        context.try_shutdown()


#: Seconds after ``TEARDOWN_LIMIT`` at which a teardown stuck holding the interpreter lock
#: ends the process (``bounded_teardown``).
HELD_LOCK_GRACE = 5.0


@functools.cache
def _null_device() -> IO[str]:
    """The null device, open for the fault handler's dump (kept open: it writes there
    from its own thread)."""
    return open(os.devnull, "w")  # noqa: SIM115 - open for the life of the process


def write_report(path: str | None, data: dict[str, Any]) -> None:
    """What a child process did, as JSON for its parent (written atomically)."""
    if path is not None:
        from mechsim.files import write_atomic

        write_atomic(path, json.dumps(data))


def exit_process(code: int) -> None:
    """End a command's process with ``code`` without tearing the interpreter down.

    By the time a command returns, its outputs are complete and its ROS contexts shut down;
    what a normal exit adds is the interpreter's finalization, a noticeable share of a short
    command's CPU with sympy, numba and rclpy loaded. Exit handlers still run. If a thread
    that a normal exit would wait for is still alive, the process exits normally instead."""
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
