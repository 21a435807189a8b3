"""Services, parameter sets and subscriptions of a scene's nodes served from their own thread,
so the loop that steps the nodes never builds a wait set (costly for a scene of many nodes).

Callbacks run one at a time holding ``lock``, the lock the stepping loop holds while it steps:
a callback always sees a node between two chunks of samples, never inside one. The loop lets a
waiting callback in between chunks (``let_in``); a node waiting for a controller's command
waits on the lock's condition (``wait``), which a callback's end signals.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator
from typing import Any

from rclpy.executors import (
    ConditionReachedException,
    ShutdownException,
    SingleThreadedExecutor,
    TimeoutException,
)

#: Longest wall time the stepping loop waits for one callback to finish in ``let_in``.
LET_IN_LIMIT = 5.0


class Serving:
    """``executor``'s callbacks, served by a thread of their own while the runner steps."""

    def __init__(self, executor: SingleThreadedExecutor) -> None:
        self.executor = executor
        self.lock = threading.Condition()
        self.error: BaseException | None = None
        self._asking = False  # a callback is ready and waits for the lock
        self._stop = False
        self._thread = self._new_thread()

    def _new_thread(self) -> threading.Thread:
        return threading.Thread(target=self._serve, name="mechsim-serving", daemon=True)

    def __enter__(self) -> Serving:
        self._thread.start()
        self.lock.acquire()  # the runner steps holding it
        return self

    def __exit__(self, *exc: Any) -> None:
        self._stop = True
        self.executor.wake()
        self.lock.release()
        if self._thread.ident is not None:  # (not a thread a stop kept from starting)
            self._thread.join(timeout=10.0)

    @contextlib.contextmanager
    def paused(self) -> Iterator[None]:
        """No callback served inside (the serving thread ended, the runner keeping the lock):
        entities made meanwhile wake no executor, which would otherwise rebuild its wait set
        over every entity of the scene for each one (a scene making many nodes' services at
        once). The thread serves again afterwards, the new entities included."""
        self._stop = True
        self.executor.wake()
        self.lock.release()  # a callback already waiting for it runs to its end first
        try:
            self._thread.join(timeout=LET_IN_LIMIT)
        finally:
            self.lock.acquire()
        try:
            yield
        finally:
            self._stop = False
            if not self._thread.is_alive():
                self._thread = self._new_thread()
                self._thread.start()

    def _stopping(self) -> bool:
        return self._stop

    def _serve(self) -> None:
        while not self._stop:
            try:
                handler, _, _ = self.executor.wait_for_ready_callbacks(
                    timeout_sec=None, condition=self._stopping)
            except (ShutdownException, ConditionReachedException, TimeoutException):
                return
            except Exception as e:  # noqa: BLE001 - e.g. the context shut down under us
                self.error = e
                return
            self._asking = True
            with self.lock:
                self._asking = False
                try:
                    handler()
                    if handler.exception() is not None:
                        self.error = handler.exception()
                finally:
                    self.lock.notify_all()

    def let_in(self) -> None:
        """Between two chunks: let a callback that is waiting run (the runner holds the lock
        otherwise, and a released lock is not handed over fairly). Raises what a callback
        raised."""
        if self._asking:
            self.lock.wait_for(lambda: not self._asking, timeout=LET_IN_LIMIT)
        if self.error is not None:
            error, self.error = self.error, None
            raise error

    def wait(self, timeout: float) -> None:
        """Wait (the lock released) until a callback has run, at most ``timeout`` seconds."""
        self.lock.wait(timeout)
