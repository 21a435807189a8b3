"""A paced run resumes real-time pacing from where it stands: after a reset (t = 0) and after a
pause, its samples become due one period after another from the moment it was reset or
resumed, never in a burst through the simulated time it did not run.

Measured as a condition on the stamps against the test's own wall clock: a sample of
simulated time t after a reset requested at wall time W (read before the request) cannot
have been published before W + t / real_time_factor, so it arrives no earlier; allowing one
sample period, t ≤ (arrival − W) + 1/rate. Load only delays arrivals, which loosens the bound.
Both ways a scene is paced: the loop of an in-process scene (`mechsim run`, in a child
process) and each node's own timer (nodes started by the pytest plugin)."""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import Any

import pytest

from mechsim.outputs.messages import DEFAULT_TIME_OFFSET

RATE = 100.0  # the plugin's publish rate (Hz of simulation time), real time factor 1
PERIOD = 1.0 / RATE
SCENE = """\
name: paced
systems:
  - {system: pendulum, name: a, parameters: {initial.angle: 1.0}}
  - {system: pendulum, name: b, parameters: {initial.angle: 0.5}}
"""


class Arrivals:
    """(wall time of arrival, simulated time) of every sample of one state topic."""

    def __init__(self, graph: Any, topic: str) -> None:
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState

        self.rows: list[tuple[float, float]] = []
        graph.probe.create_subscription(
            JointState, topic, self._take,
            QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))

    def _take(self, msg: Any) -> None:
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9 - DEFAULT_TIME_OFFSET
        self.rows.append((time.monotonic(), t))

    def latest(self) -> float:
        return self.rows[-1][1] if self.rows else -1.0

    def since_reset(self, after: int) -> list[tuple[float, float]]:
        """The samples of the epoch a reset started: from the first whose time went back,
        among those that arrived after row ``after``."""
        rows = self.rows
        for i in range(max(after, 1), len(rows)):
            if rows[i][1] <= rows[i - 1][1]:
                return rows[i:]
        return []


def _ahead(rows: list[tuple[float, float]], wall0: float, sim0: float) -> list[str]:
    """The samples published more than one period ahead of the wall clock since ``wall0``
    (when pacing restarted from ``sim0`` at the latest)."""
    return [f"t = {t:.3f} s arrived {w - wall0:.3f} s after the request"
            for w, t in rows if t - sim0 > (w - wall0) + PERIOD + 1e-9]


@pytest.mark.parametrize("paced_by", ["scene loop", "node timers"])
def test_reset_and_resume_pace_from_the_current_sample(mechsim_graph: Any, tmp_path: Path,
                                                        paced_by: str) -> None:
    from std_srvs.srv import SetBool, Trigger

    scene = tmp_path / "paced.yaml"
    scene.write_text(SCENE)
    graph = mechsim_graph
    a, b = Arrivals(graph, "/a/state"), Arrivals(graph, "/b/state")
    graph.start(str(scene), process=paced_by == "scene loop", publish_rate=RATE,
                diagnostics=False)

    # A second of the run first, so that a burst to catch up would be a second of samples.
    graph.spin_until(lambda: a.latest() >= 1.0, 120, "/a/state: a second of samples")
    before = len(a.rows)
    wall0 = time.monotonic()
    answer = graph.call("/a/simulator/reset", Trigger.Request())
    assert answer.success, answer.message
    graph.spin_until(lambda: any(t >= 0.5 for _, t in a.since_reset(before)), 120,
                     "/a/state: half a second of samples after the reset")
    after_reset = a.since_reset(before)
    assert after_reset[0][1] == 0.0
    assert not _ahead(after_reset, wall0, 0.0)

    # Paused while the other system runs on for a second of its samples; then resumed.
    answer = graph.call("/a/simulator/pause", SetBool.Request(data=True))
    assert answer.success and answer.message.startswith("paused at t = "), answer.message
    paused_at = len(a.rows)
    b_then = b.latest()
    graph.spin_until(lambda: b.latest() >= b_then + 1.0, 120, "/b/state: a second more")
    wall0 = time.monotonic()
    answer = graph.call("/a/simulator/pause", SetBool.Request(data=False))
    m = re.fullmatch(r"running from t = (\S+) s", answer.message)
    assert answer.success and m, answer.message
    sim0 = float(m.group(1))
    graph.spin_until(lambda: a.latest() >= sim0 + 0.5, 120,
                     "/a/state: half a second of samples after the pause")
    resumed = [(w, t) for w, t in a.rows[paused_at:] if t > sim0 + 1e-9]
    assert resumed[0][1] == pytest.approx(sim0 + PERIOD)  # on from where it stood
    assert not _ahead(resumed, wall0, sim0)
