"""The host's speed at a moment: a shared machine runs the same work at different speeds in
stretches (another tenant on the same physical core, frequency changes), which a figure
measured in the run should be read beside."""

from __future__ import annotations

import statistics
import time

#: Iterations of the reference loop: long beside the clock's resolution, short beside the
#: figures it is read with.
REFERENCE_ITERATIONS = 20_000


def reference_loop() -> int:
    s = 0
    for i in range(REFERENCE_ITERATIONS):
        s += i * i
    return s


def reference_ms(repeats: int = 5) -> float:
    """Milliseconds a fixed pure-Python loop takes now (median of ``repeats``): lower is a
    faster host. Only its changes within one run mean anything."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        reference_loop()
        times.append(1e3 * (time.perf_counter() - t0))
    return statistics.median(times)
