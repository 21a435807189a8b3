"""The thread that serves a scene's callbacks while its loop steps (``ros.serving``): ended and
joined when the loop ends, also where a stop (Ctrl-C, SIGTERM) came between making a new
serving thread and starting it."""

from __future__ import annotations

from typing import Any

import pytest

from mechsim.environment import import_rclpy

import_rclpy()

from rclpy.executors import SingleThreadedExecutor  # noqa: E402

from mechsim.ros.serving import Serving  # noqa: E402


def test_the_serving_thread_ends_with_the_loop(ros_context: Any) -> None:
    serving = Serving(SingleThreadedExecutor(context=ros_context))
    with serving:
        assert serving._thread.is_alive()
        with serving.paused():
            assert not serving._thread.is_alive()
        assert serving._thread.is_alive()  # a new thread serves again
    assert not serving._thread.is_alive()


def test_a_stop_before_a_new_serving_thread_starts_leaves_nothing_to_join(
        ros_context: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """A stop raised in ``paused`` after the new thread is made, before it starts: the loop
    ends with the stop, not with "cannot join thread before it is started"."""
    serving = Serving(SingleThreadedExecutor(context=ros_context))

    class Stop(BaseException):
        pass

    def stopped(self: Any) -> None:
        raise Stop

    with pytest.raises(Stop), serving:
        monkeypatch.setattr(type(serving._thread), "start", stopped)
        with serving.paused():
            pass
    monkeypatch.undo()
    assert serving._thread.ident is None  # the thread made, never started
