"""The recorder node: a scene's messages recorded from the ROS graph, in a process of its own
(``mechsim recorder``, started by ``mechsim run --processes``; ``mechsim run --only recorder``).

In-process runs record through the nodes' outlets (every message, by construction). When the
nodes run in other processes (``mechsim run --processes``) or on other hosts (``mechsim run
--only recorder`` with the several-hosts profile), this node records what arrives over DDS
instead: every topic under the scene's instance namespaces plus ``/tf``, ``/tf_static``,
``/clock`` and ``/diagnostics``, subscribed as they appear, with the durability and reliability
their publishers offer (latched topics transient-local, so late joiners still get them).

Each message is decoded (for its stamp and the Rerun sink), written to the bag as the outlets
write it (the same CDR bytes), and stamped with the time it carries (header stamp, the first
transform's stamp, the clock's time), so bags from both paths are the same. Reliable delivery
is lossless while the recorder keeps up (a simulator recorded from another process waits for
its acknowledgments); the counts received are reported next to what was published.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message

from mechsim.errors import MechsimError
from mechsim.outputs.sink import Sinks
from mechsim.outputs.wire import message_class
from mechsim.ros.graph_check import start_context
from mechsim.ros.outlet import subscription_qos
from mechsim.ros.process import drain, end_node_process, write_report
from mechsim.runcore.stops import held_signals

#: Topics outside the instances' namespaces that a scene's nodes publish.
GLOBAL_TOPICS = ("/tf", "/tf_static", "/clock", "/diagnostics")
#: Name of the recorder node (the simulators wait for its subscriptions before stepping).
NODE_NAME = "mechsim_recorder"
#: The recorder's parameters, read when it starts alone (``ros/standalone.py``).
_PARAMETERS = {
    "scene": "scene file whose instances are recorded (empty: every mechsim system in the "
             "graph)",
    "bag": "new bag directory (strftime fields and {scene} expanded; empty: no bag)",
    "rrd": "Rerun recording file (empty: none)"}
#: How often the graph is scanned for new topics [s].
SCAN_PERIOD = 0.2
#: Reader history: room for bursts of a simulator running ahead (a best-effort topic loses
#: what does not fit).
RECORD_DEPTH = 10_000


def stamp_ns(msg: Any) -> int | None:
    """The time a message carries, in ns; None if it carries none."""
    header = getattr(msg, "header", None)
    if header is not None:
        stamp = header.stamp
    elif getattr(msg, "transforms", None):
        stamp = msg.transforms[0].header.stamp
    elif getattr(msg, "markers", None):
        stamp = msg.markers[0].header.stamp
    elif hasattr(msg, "clock"):
        stamp = msg.clock
    else:
        return None
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


class RecorderNode(Node):
    """Subscribes to the scene's topics as they appear and hands every message to ``sinks``
    (each the topics it wants, in its form: ``mechsim.outputs.sink``).
    Without instances: the topics of every mechsim system in the graph (each namespace
    with a ``system_info`` topic)."""

    def __init__(self, instances: list[str], sinks: list[Any], *, context: Any = None) -> None:
        super().__init__(NODE_NAME, context=context)
        for name, text in _PARAMETERS.items():  # what it was started with, to see
            self.declare_parameter(name, "", ParameterDescriptor(description=text,
                                                                 read_only=True))
        self.instances = list(instances)
        self.every_system = not self.instances
        self.sinks = Sinks(sinks)
        self.counts: dict[str, int] = {}
        #: Topics whose publishers deliver best effort (by convention: /clock).
        self.best_effort: set[str] = set()
        self._subs: dict[str, Any] = {}
        self._last_ns = 0
        self.scan()
        self.create_timer(SCAN_PERIOD, self.scan)

    def wanted(self, topic: str) -> bool:
        """A topic of the scene that a sink takes (a bag of ``bag_topics: samples`` no
        sample batches: subscribing would make the simulators compute them)."""
        return (topic in GLOBAL_TOPICS or any(topic.startswith(f"/{ns}/")
                                              for ns in self.instances)) \
            and self.sinks.wants(topic)

    def scan(self) -> None:
        """Subscribe to every wanted topic that has appeared since the last scan."""
        topics = self.get_topic_names_and_types()
        if self.every_system:
            self.instances = sorted({t.removesuffix("/system_info").lstrip("/")
                                     for t, _ in topics if t.endswith("/system_info")})
        for topic, types in topics:
            if topic in self._subs or not self.wanted(topic) or len(types) != 1:
                continue
            offered = [p.qos_profile for p in self.get_publishers_info_by_topic(topic)]
            if not offered:
                continue  # its publisher is not visible yet: next scan
            cls = message_class(types[0])
            self.counts[topic] = 0
            if subscription_qos(offered).reliability == ReliabilityPolicy.BEST_EFFORT:
                self.best_effort.add(topic)
            # The bag states the QoS offered (as rosbag2 does); the reader matches them all.
            self._subs[topic] = self.create_subscription(
                cls, topic, self._receiver(topic, types[0], cls, offered[0]),
                subscription_qos(offered, RECORD_DEPTH, RECORD_DEPTH), raw=True)

    def _receiver(self, topic: str, type_name: str, cls: type,
                  qos: QoSProfile) -> Callable[[bytes], None]:
        def receive(data: bytes) -> None:
            msg: Any = deserialize_message(data, cls)
            ns = stamp_ns(msg)
            ns = self._last_ns if ns is None else ns
            self._last_ns = max(self._last_ns, ns)
            self.counts[topic] += 1
            # Re-encoded for the sinks that take bytes, not the received bytes: rmw's buffer
            # may end in alignment padding that strict readers (rosbags) reject, and holds
            # whatever the publisher left in its padding; the outlets' bytes do not.
            self.sinks.message(topic, type_name, qos, ns, msg=msg)
        return receive

    def subscribed(self, topic: str) -> bool:
        return topic in self._subs


@contextlib.contextmanager
def _stop_requested() -> Iterator[threading.Event]:
    """An event that Ctrl-C or SIGTERM sets while the block runs (main thread; elsewhere it
    is never set and a stop raises as usual). Raised as KeyboardInterrupt, a stop landing
    inside rclpy's deserialisation came out as "TypeError: Unable to convert function return
    value to a Python type" (seen: the import a message's constructor makes was
    interrupted), which stopped the recorder as an error and lost the message being taken."""
    stop = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return
    signals = (signal.SIGINT, signal.SIGTERM)
    previous = {s: signal.getsignal(s) for s in signals}
    for s in signals:
        signal.signal(s, lambda signum, frame: stop.set())
    try:
        yield stop
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def run_recorder(scene: Any, bag: str | None, rrd: str | None, report: str | None = None,
                 *, context: Any = None, probe: Any = None) -> list[str]:
    """The scene's topics from the graph into ``bag`` / ``rrd`` until SIGINT/SIGTERM, then
    what is in flight, then the outputs completed. Returns the lines describing them.
    ``context``: a started context to record in (default: a new one; one given is the caller's
    to shut down if this raises); ``probe``: a node of it that read the recorder's parameters,
    destroyed once the recorder's node exists (one DDS participant a process: ``graph_check``)."""
    from rclpy.executors import SingleThreadedExecutor

    from mechsim.ros.record import open_outputs

    with held_signals():
        out = open_outputs(scene, bag, rrd)
    try:
        context = start_context() if context is None else context
    except BaseException:
        with held_signals():
            out.finish_after_error()
        raise
    executor = SingleThreadedExecutor(context=context)
    node = RecorderNode([i.name for i in scene.systems], out.sinks, context=context)
    if probe is not None:
        probe.destroy_node()
    executor.add_node(node)
    lines: list[str] = []
    try:
        try:
            with _stop_requested() as stop:
                while not stop.is_set():
                    executor.spin_once(timeout_sec=0.1)
        except KeyboardInterrupt:
            pass
        with held_signals():
            drain(executor, lambda: sum(node.counts.values()), report)
            lines = out.close()
    except BaseException as e:
        with held_signals():
            kept = out.finish_after_error()
        if isinstance(e, KeyboardInterrupt):
            raise
        raise MechsimError(f"recorder: {(str(e).splitlines() or [type(e).__name__])[0]}; "
                           f"{kept}") from None
    finally:
        write_report(report, {"lines": lines, "counts": node.counts,
                               "best_effort": sorted(node.best_effort)})
        end_node_process("the recorder's teardown", lambda: 0, executor, node, context)
    return lines
