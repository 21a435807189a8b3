"""``--lossless``: a live subscriber in another process gets every sample of a fast run.

Without it a fast run sends chunks of hundreds of samples at once and the publishers' history
(depth 10, as ROS nodes usually keep) overwrites what a Python subscriber has not yet
received; with it every chunk goes out in slices that every reliable subscriber acknowledges
before the next."""

from __future__ import annotations

import json
import select
import subprocess
import sys
from typing import Any

from mechsim.ros.launch import run_scene
from mechsim.scene import parse_scene

_COUNTER = """
import json, sys, time
from mechsim.environment import import_rclpy
rclpy = import_rclpy()
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from diagnostic_msgs.msg import DiagnosticArray
from mechsim_msgs.msg import Energy
from sensor_msgs.msg import JointState
types = {"/swing/state": JointState, "/swing/energy": Energy,
         "/diagnostics": DiagnosticArray}
rclpy.init()
n = rclpy.create_node("lossless_counter")
qos = QoSProfile(depth=1, history=HistoryPolicy.KEEP_ALL,
                 reliability=ReliabilityPolicy.RELIABLE)
got = {topic: [] for topic in json.loads(sys.argv[1])}
def keep(topic):
    return lambda m: got[topic].append((m.header.stamp.sec, m.header.stamp.nanosec))
for topic in got:
    n.create_subscription(types[topic], topic, keep(topic), qos)
print("ready", flush=True)
quiet, end = 0, time.monotonic() + 120.0
total = lambda: sum(map(len, got.values()))
while (quiet < 50 or total() == 0) and time.monotonic() < end:  # 5 s without a message
    before = total()
    rclpy.spin_once(n, timeout_sec=0.1)
    quiet = 0 if total() != before else quiet + 1
for topic, stamps in got.items():
    print(topic, len(stamps), len(set(stamps)), flush=True)
"""


def _line(proc: subprocess.Popen[str], timeout: float = 300.0) -> str:
    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], timeout)
    assert ready, f"no line from the counter within {timeout:g} s"
    return proc.stdout.readline().strip()


def test_a_lossless_fast_run_reaches_a_live_subscriber_with_every_sample(
        ros_context: Any, ros_env: dict[str, str]) -> None:
    from mechsim.testing import wait_until

    counter = subprocess.Popen([sys.executable, "-c", _COUNTER, json.dumps(
        ["/swing/state", "/swing/energy", "/diagnostics"])], env=ros_env,
                               stdout=subprocess.PIPE, text=True)
    try:
        assert _line(counter) == "ready"
        scene = parse_scene({"name": "lossless", "pacing": "fast", "publish_rate": 100.0,
                             "systems": [{"system": "pendulum", "name": "swing"}]})

        def matched(node: Any) -> None:
            """Before the first sample: both topics matched with the counter."""
            from rclpy.executors import SingleThreadedExecutor

            ex = SingleThreadedExecutor(context=ros_context)
            pubs = [node.outlet.channels[t].publisher
                    for t in (node.topics.t_state, node.topics.t_energy)]
            try:
                assert wait_until(ex, lambda: all(p.get_subscription_count() for p in pubs),
                                  120.0), "the counter never matched"
            finally:
                ex.shutdown()

        run = run_scene(scene, fast=True, duration=30.0, context=ros_context, lossless=True,
                        before_first_message=matched)
        assert not run.failures
        published = {t: run.messages[t] for t in ("/swing/state", "/swing/energy",
                                                  "/diagnostics")}
        assert published["/swing/state"] == 3001  # t = 0, 0.01, ..., 30
        # A report per simulated second, those of a chunk published at once: more than
        # the /diagnostics history (depth 10) holds.
        assert published["/diagnostics"] > 2 * 10
        counts = {}
        for _ in published:
            topic, received, distinct = _line(counter).split()
            counts[topic] = (int(received), int(distinct))
        # (every sample once; the last report may repeat the stamp of the one before)
        assert counts.pop("/diagnostics")[0] == published.pop("/diagnostics")
        assert counts == {t: (n, n) for t, n in published.items()}
    finally:
        if counter.poll() is None:
            counter.kill()
        counter.wait()


def test_lossless_reports_wait_for_a_stopped_subscriber(
        ros_context: Any, ros_env: dict[str, str], monkeypatch: Any) -> None:
    """A subscriber of /diagnostics in another process is stopped (SIGSTOP) before the first
    report, and continued only when the run waits for its acknowledgments: a lossless run
    publishes no more reports than the history holds without them, so the subscriber gets
    every report. (A run that did not wait would publish its hundreds of reports into the
    stopped subscriber's buffers, where many are lost; it is continued at the end.)"""
    import os
    import signal

    from mechsim.ros.outlet import DIAGNOSTICS_QOS, Outlet
    from mechsim.testing import wait_until

    counter = subprocess.Popen([sys.executable, "-c", _COUNTER, json.dumps(["/diagnostics"])],
                               env=ros_env, stdout=subprocess.PIPE, text=True)
    stopped = [False]
    published = [0]
    try:
        assert _line(counter) == "ready"
        scene = parse_scene({"name": "lossless", "pacing": "fast", "publish_rate": 10.0,
                             "systems": [{"system": "pendulum", "name": "swing"}]})

        def matched(node: Any) -> None:
            """Before the first report: /diagnostics matched, then the subscriber stopped."""
            from rclpy.executors import SingleThreadedExecutor

            ex = SingleThreadedExecutor(context=ros_context)
            try:
                assert wait_until(ex, lambda: node.count_subscribers("/diagnostics") > 0,
                                  120.0), "the subscriber never matched"
            finally:
                ex.shutdown()
            os.kill(counter.pid, signal.SIGSTOP)
            stopped[0] = True

        original_publish, original_wait = Outlet.publish_serialized, Outlet.acknowledged

        def publish(self: Outlet, topic: str, *args: Any) -> None:
            original_publish(self, topic, *args)
            published[0] += topic == "/diagnostics"

        def acknowledged(self: Outlet, topic: str) -> None:
            if stopped[0] and published[0] >= DIAGNOSTICS_QOS.depth:
                os.kill(counter.pid, signal.SIGCONT)  # the run waits now: let it answer
                stopped[0] = False
            original_wait(self, topic)

        monkeypatch.setattr(Outlet, "publish_serialized", publish)
        monkeypatch.setattr(Outlet, "acknowledged", acknowledged)
        run = run_scene(scene, fast=True, duration=600.0, context=ros_context, lossless=True,
                        before_first_message=matched)
        if stopped[0]:
            os.kill(counter.pid, signal.SIGCONT)
        assert not run.failures
        assert run.messages["/diagnostics"] == published[0] > 20 * DIAGNOSTICS_QOS.depth
        topic, received, _ = _line(counter).split()
        assert (topic, int(received)) == ("/diagnostics", published[0])
    finally:
        if counter.poll() is None:
            os.kill(counter.pid, signal.SIGCONT)
            counter.kill()
        counter.wait()
