"""``mechsim replay DIR``: republish a recorded bag into the live ROS graph.

Messages go out in time order (their log times, as ``ros2 bag play``) with their original
relative timing (``--rate`` scales it;
``--rate 0`` = as fast as possible), each on its topic with its recorded type and the QoS of the
bag metadata (reliability, durability: /tf_static and system_info stay transient local, keeping
as many messages as the bag has on the topic, at most 100, so a late joiner gets the static
frames of every system as it would from the recorded publishers). The
player publishes ``/clock`` (best effort, depth 1) itself from the messages' log times, which
are the stamps the simulator wrote, so nodes with ``use_sim_time`` follow the recording; a
``/clock`` stored in the bag is not republished (as ``ros2 bag play --clock``). With ``--loop``
the bag starts over and the clock jumps back to its start, as with ``ros2 bag play --loop``.
``--delay`` (default 0.5 s) leaves time for discovery before the first message, so subscribers
that were already running get the first messages too. Each message is decoded (a corrupt bag
is an error) and published as ``mechsim.outputs.wire`` encodes it, padding zero, as the
simulator publishes it.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mechsim.errors import MechsimError, ParameterError


@dataclass
class ReplayStats:
    messages: int = 0
    clock: int = 0
    loops: int = 0
    per_topic: dict[str, int] = field(default_factory=dict)
    sim_span: float = 0.0
    wall: float = 0.0


def replay(path: str | Path, *, rate: float = 1.0, loop: bool = False,
           topics: list[str] | None = None, delay: float = 0.5,
           context: Any = None) -> ReplayStats:
    from mechsim.environment import import_rclpy

    import_rclpy()
    from rclpy.node import Node
    from rclpy.serialization import deserialize_message
    from rosgraph_msgs.msg import Clock

    from mechsim.outputs import messages
    from mechsim.outputs.bag import qos_profile, read_messages, read_metadata, topic_qos
    from mechsim.outputs.wire import cdr_bytes, message_class
    from mechsim.ros.outlet import CLOCK_QOS, wait_acked

    d = Path(path)
    known = topic_qos(read_metadata(d))
    check_topics(d, known, topics)
    selected = [t for t in (topics or list(known)) if t != "/clock"]
    classes = {t: message_class(known[t][0]) for t in selected}

    own_context = context is None
    if own_context:
        from mechsim.ros.graph_check import start_context

        context = start_context()
    node = Node("mechsim_replay", namespace="mechsim", context=context)
    stats = ReplayStats()
    start = 0.0
    try:
        pubs: dict[str, Any] = {
            t: node.create_publisher(classes[t], t, qos_profile(known[t][1], known[t][2]))
            for t in selected}
        clock_pub = node.create_publisher(Clock, "/clock", CLOCK_QOS)
        time.sleep(max(delay, 0.0))
        start = time.monotonic()
        while True:
            t0: int | None = None
            last_clock = -1
            wall0 = time.monotonic()
            for m in read_messages(d, selected or ["/clock"]):
                if m.topic not in pubs:
                    continue
                if t0 is None:
                    t0 = m.log_time
                if rate > 0:
                    wait = wall0 + (m.log_time - t0) / 1e9 / rate - time.monotonic()
                    if wait > 0:
                        time.sleep(wait)
                if m.log_time > last_clock:
                    clock_pub.publish(cdr_bytes(messages.clock(m.log_time)))
                    last_clock = m.log_time
                    stats.clock += 1
                try:
                    msg: Any = deserialize_message(m.data, classes[m.topic])
                except Exception:  # noqa: BLE001 - rclpy raises plain exceptions on bad CDR
                    raise MechsimError(f"bag {d}: a {known[m.topic][0]} message on {m.topic} "
                                       "does not deserialize (corrupt bag)") from None
                pubs[m.topic].publish(cdr_bytes(msg))  # decoded: checked, padding zero
                stats.messages += 1
                stats.per_topic[m.topic] = stats.per_topic.get(m.topic, 0) + 1
                if t0 is not None:
                    stats.sim_span = max(stats.sim_span, (m.log_time - t0) / 1e9)
            stats.loops += 1
            if not loop or stats.messages == 0:
                break
        wait_acked(list(pubs.values()))
    except KeyboardInterrupt:
        pass
    finally:
        stats.wall = time.monotonic() - start if start else 0.0
        node.destroy_node()
        if own_context:
            context.try_shutdown()
    return stats


def check_topics(path: Path, known: dict[str, Any], topics: list[str] | None) -> None:
    missing = [t for t in topics or [] if t not in known]
    if missing:
        raise ParameterError("--topics", f"{', '.join(missing)} not in bag {path} (it has: "
                             f"{', '.join(sorted(known))})")
