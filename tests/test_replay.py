"""``mechsim replay``: the committed bag republished into the graph, received by a subscriber
in another process, compared with the bag as ``rosbags`` reads it."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[1]
REFERENCE = REPO / "bags" / "reference"

LISTENER = r"""
import json, sys, time
from mechsim.environment import import_rclpy
rclpy = import_rclpy()
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from mechsim_msgs.msg import Energy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from tf2_msgs.msg import TFMessage

want = json.loads(sys.argv[1])
rclpy.init()
node = Node("replay_listener")
got = {t: [] for t in [*want, "/clock"]}
types = {}

def keep(topic, f):
    def cb(msg):
        got[topic].append(f(msg))
        if topic not in types:
            types.update({k: v for k, v in node.get_topic_names_and_types() if k in want})
    return cb

ns = lambda st: st.sec * 1_000_000_000 + st.nanosec
reliable = QoSProfile(depth=1000)
node.create_subscription(JointState, "/pendulum/state", keep(
    "/pendulum/state", lambda m: [ns(m.header.stamp), list(m.position), list(m.velocity)]),
    reliable)
node.create_subscription(Energy, "/kepler/energy", keep(
    "/kepler/energy", lambda m: [ns(m.header.stamp), m.total]), reliable)
node.create_subscription(TFMessage, "/tf_static", keep(
    "/tf_static", lambda m: [t.child_frame_id for t in m.transforms]),
    QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL))
node.create_subscription(Clock, "/clock", keep("/clock", lambda m: ns(m.clock)),
    QoSProfile(depth=1000, reliability=ReliabilityPolicy.BEST_EFFORT))
print("READY", flush=True)
end = time.monotonic() + 60
while time.monotonic() < end and any(len(got[t]) < n for t, n in want.items()):
    rclpy.spin_once(node, timeout_sec=0.1)
print(json.dumps({"got": got, "types": types}), flush=True)
"""


def _bag(topics: list[str]) -> dict[str, list[Any]]:
    """The committed bag as the independent reader ``rosbags`` sees it."""
    from rosbags.highlevel import AnyReader

    out: dict[str, list[Any]] = {t: [] for t in topics}
    with AnyReader([REFERENCE]) as reader:
        out["_types"] = {c.topic: c.msgtype for c in reader.connections}  # type: ignore[assignment]
        out["_times"] = sorted({ts for _, ts, _ in reader.messages()})  # type: ignore[assignment]
        for con, ts, raw in reader.messages([c for c in reader.connections
                                             if c.topic in topics]):
            out[con.topic].append((ts, reader.deserialize(raw, con.msgtype)))
    return out


def test_replay_reaches_a_subscriber_in_another_process(ros_env: dict[str, str],
                                                        ros_context: Any) -> None:
    from mechsim.ros.replay import replay

    topics = ["/pendulum/state", "/kepler/energy", "/tf_static"]
    bag = _bag(topics)
    want = {t: len(bag[t]) for t in topics}
    listener = subprocess.Popen([sys.executable, "-c", LISTENER, json.dumps(want)],
                                env=ros_env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
    try:
        assert listener.stdout is not None
        assert listener.stdout.readline().strip() == "READY", listener.stderr
        stats = replay(REFERENCE, rate=2.0, delay=1.5, context=ros_context)
        out, err = listener.communicate(timeout=60)
        assert out.strip(), err
    finally:
        listener.kill()
    assert stats.per_topic["/pendulum/state"] == 201 and "/clock" not in stats.per_topic
    res = json.loads(out.strip().splitlines()[-1])
    got, types = res["got"], res["types"]
    for t in topics:
        assert types[t] == [bag["_types"][t]], t  # type: ignore[call-overload]
    # every message, in order, with the recorded values
    assert got["/pendulum/state"] == [
        [ts, list(m.position), list(m.velocity)] for ts, m in bag["/pendulum/state"]]
    assert got["/kepler/energy"] == [[ts, m.total] for ts, m in bag["/kepler/energy"]]
    assert sorted(f for msg in got["/tf_static"] for f in msg) == sorted(
        t.child_frame_id for _, m in bag["/tf_static"] for t in m.transforms)
    # /clock from the log times: advancing, from the first stamp to the last
    clock = got["/clock"]
    assert clock == sorted(set(clock)) and len(clock) > 100
    times = bag["_times"]
    # /clock is best effort (ROS convention): the listener may stop before the very last one
    # arrives, or it may be dropped under load; what arrives is on the recorded times and
    # reaches the end of the run.
    assert set(clock) <= set(times)  # type: ignore[arg-type]
    assert clock[-1] >= times[int(0.9 * (len(times) - 1))]  # type: ignore[arg-type]
    assert clock[0] <= 1_100_000_000


def test_replay_selected_topics_as_fast_as_possible(ros_context: Any) -> None:
    from mechsim.ros.replay import replay

    stats = replay(REFERENCE, rate=0.0, delay=0.0, topics=["/pendulum/state", "/tf"],
                   context=ros_context)
    assert stats.per_topic == {"/pendulum/state": 201, "/tf": 603}
    assert stats.clock == 201 and stats.loops == 1


def test_replay_paces_at_the_requested_rate(ros_context: Any) -> None:
    from mechsim.ros.replay import replay

    stats = replay(REFERENCE, rate=4.0, delay=0.0, topics=["/clock", "/kepler/state"],
                   context=ros_context)
    assert stats.per_topic == {"/kepler/state": 201}
    assert stats.wall == pytest.approx(2.0 / 4.0, abs=0.3)  # 2 s of bag at 4x
