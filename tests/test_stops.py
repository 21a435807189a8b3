"""Stops (``mechsim.runcore.stops``): a Ctrl-C or SIGTERM whose KeyboardInterrupt lands in a
finalizer, where Python prints and drops it, still ends a node's loop, which checks
``stopping`` (as rclpy's ``Future.__del__`` once swallowed launch's SIGINT and the node ran on
until launch escalated to SIGTERM)."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import pytest

_LOOP = textwrap.dedent("""
    import gc, os, signal, sys
    from mechsim.runcore.stops import stop_on_sigterm, stopping
    stop_on_sigterm()
    SIGNAL = getattr(signal, sys.argv[1])

    class Finalized:
        def __del__(self):
            os.kill(os.getpid(), SIGNAL)  # handled here, between two of these bytecodes
            for _ in range(10_000):
                pass

    Finalized()  # collected at once: its interrupt printed and dropped
    spins = 0
    while not stopping.is_set():  # a node's spin loop
        spins += 1
    print("stopped")
""")


@pytest.mark.parametrize("name", ["SIGINT", "SIGTERM"])
def test_a_stop_dropped_in_a_finalizer_still_ends_the_loop(name: str) -> None:
    done = subprocess.run([sys.executable, "-c", _LOOP, name], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "stopped", done.stderr
    assert "KeyboardInterrupt" in done.stderr  # (it was dropped, not taken)
