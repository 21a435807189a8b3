"""The one output path: every message a node sends goes through an Outlet, which publishes it
on ROS and hands it, with its topic and time, to any attached sinks (the bag recorder, the
Rerun logger). In-process sinks see every message, so a recording cannot drop one."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from mechsim.outputs.messages import column_rows
from mechsim.outputs.sink import Sink
from mechsim.outputs.wire import cdr_bytes

# QoS by role (ROS_CONVENTIONS §1, §2, §5).
STATE_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                       durability=DurabilityPolicy.VOLATILE, history=HistoryPolicy.KEEP_LAST)
TF_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE, history=HistoryPolicy.KEEP_LAST)
LATCHED_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL,
                         history=HistoryPolicy.KEEP_LAST)
CLOCK_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT,
                       durability=DurabilityPolicy.VOLATILE, history=HistoryPolicy.KEEP_LAST)
DIAGNOSTICS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.VOLATILE,
                             history=HistoryPolicy.KEEP_LAST)


#: History a publisher keeps for a reliable subscriber in a lossless run: a chunk is sent in
#: slices of this many samples, each acknowledged by every such subscriber before the next
#: (Fast DDS acknowledges about every heartbeat, 10 ms with the project's profile, so with
#: the usual depth of 10 a topic could carry ~1700 messages per second at most).
LOSSLESS_DEPTH = 1000
#: Longest wait for one slice's acknowledgments (a reader that stopped answering is given up
#: on after it, with one warning).
LOSSLESS_WAIT = 10.0


def subscription_qos(offered: list[QoSProfile], reliable_depth: int = 100,
                     best_effort_depth: int = 10) -> QoSProfile:
    """A reader's QoS that matches every publisher offering ``offered``, as ``ros2 topic echo``
    and rosbag2 choose it: reliable only if all are (else best effort, which matches both),
    transient local only if all are (late joiners then get the latched message)."""
    reliable = all(q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
    latched = all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
    return QoSProfile(
        depth=reliable_depth if reliable else best_effort_depth, history=HistoryPolicy.KEEP_LAST,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


def wait_acked(pubs: list[Any], timeout: float = 2.0) -> None:
    """Let reliable subscribers receive the tail of what was published before the publishers
    go (a process about to exit, a replay ending)."""
    from rclpy.duration import Duration

    end = time.monotonic() + timeout
    for p in pubs:
        if p.qos_profile.reliability == ReliabilityPolicy.RELIABLE:
            left = end - time.monotonic()
            if left <= 0:
                break
            try:
                p.wait_for_all_acked(Duration(seconds=left))
            except Exception:  # noqa: BLE001 - best effort at shutdown
                pass


def streamed(qos: QoSProfile) -> bool:
    """A reliable, volatile topic (a sample stream, as opposed to latched or best effort)."""
    return (qos.reliability == ReliabilityPolicy.RELIABLE
            and qos.durability == DurabilityPolicy.VOLATILE)


@dataclass
class _Channel:
    publisher: Publisher
    type_name: str
    qos: QoSProfile


def type_name(msg_type: type) -> str:
    """'sensor_msgs/msg/JointState' for the class JointState."""
    module = msg_type.__module__.split(".")
    return f"{module[0]}/msg/{msg_type.__name__}"


class _SinkKinds(NamedTuple):
    """What the sinks of an outlet take (``Outlet._sink_kinds``)."""

    immediate: bool  # a sink takes every sample as it is published
    rows: bool  # a sink records CDR bytes (``write_chunk``)
    column_wants: list[Any]  # the ``wants`` (or None: every topic) of the column sinks
    columns: dict[str, bool]  # per topic: does a column sink want it (filled as asked)


class Outlet:
    """Publishers of one node plus the process's sinks (shared list, attached by the runner)."""

    def __init__(self, node: Node, sinks: list[Sink] | None = None,
                 lossless: bool = False) -> None:
        """``lossless``: chunks wait for every reliable subscriber's acknowledgment (of each
        ``LOSSLESS_DEPTH`` samples) instead of letting the history overwrite what a slow
        reader has not taken: no message lost, at the pace of the slowest reader."""
        self.node = node
        self.lossless = lossless
        self._unacknowledged: list[_Channel] = []  # the last slice's channels (lossless)
        self._gave_up: set[str] = set()
        self.sinks: list[Sink] = sinks if sinks is not None else []
        self.channels: dict[str, _Channel] = {}
        self.counts: dict[str, int] = {}
        #: Subscribers per topic as last counted (``refresh``): asking the middleware costs
        #: microseconds per topic, too much for every sample of a paced run.
        self.subscribers: dict[str, int] = {}
        #: Published samples not yet handed to the sinks: [stamps, topics, columns, first,
        #: end] of one chunk (``hand_over``).
        self._held: list[Any] | None = None
        #: The topics with subscribers, with their rows, of the chunk ``_live_for``.
        self._live: list[tuple[_Channel, np.ndarray]] = []
        self._live_for: Any = None
        self._kinds_for: tuple[int, ...] | None = None
        self._kinds = _SinkKinds(False, False, [], {})

    def channel(self, topic: str, msg_type: type, qos: QoSProfile) -> str:
        resolved = self.node.resolve_topic_name(topic)
        if resolved not in self.channels:
            if self.lossless and streamed(qos):
                qos = QoSProfile(depth=max(qos.depth, LOSSLESS_DEPTH), history=qos.history,
                                 reliability=qos.reliability, durability=qos.durability)
            pub = self.node.create_publisher(msg_type, resolved, qos)
            self.channels[resolved] = _Channel(pub, type_name(msg_type), qos)
            self.counts[resolved] = 0
        return resolved

    def refresh(self) -> None:
        """Count every topic's subscribers now (read by ``wanted`` and ``publish_chunk``)."""
        for topic, ch in self.channels.items():
            self.subscribers[topic] = ch.publisher.get_subscription_count()
        self._live_for = None

    def needs_rows(self, topic: str) -> bool:
        """Are the CDR bytes of ``topic``'s samples needed (a subscriber as counted at the
        last ``refresh``, or a sink that records bytes: ``write_chunk``)? Other sinks take
        values or messages, so a chunk nobody reads as bytes is not encoded."""
        return self.subscribers.get(topic, 0) > 0 or self._sink_kinds().rows

    def needs_columns(self, topic: str) -> bool:
        """Are the evaluated values of ``topic``'s samples needed (a sink that takes them,
        ``write_columns``, wants the topic)? Otherwise a chunk's values are not gathered
        into columns: the sinks get CDR rows or messages."""
        kinds = self._sink_kinds()
        known = kinds.columns.get(topic)
        if known is None:
            known = kinds.columns[topic] = any(wants is None or wants(topic)
                                               for wants in kinds.column_wants)
        return known

    def wanted(self, topic: str) -> bool:
        """Does anything consume ``topic`` (a sink, or a subscriber anywhere as counted at the
        last ``refresh``)?"""
        for sink in self.sinks:
            wants = getattr(sink, "wants", None)
            if wants is None or wants(topic):
                return True
        return self.subscribers.get(topic, 0) > 0

    def publish_chunk(self, ns: np.ndarray,
                      topics: list[tuple[str, np.ndarray | None, Callable[[int], Any]]],
                      columns: Mapping[str, Any] | None = None,
                      part: slice | None = None) -> None:
        """The messages of a chunk of samples stamped ``ns``, already encoded: for each
        (topic, rows, message), row i holds the CDR bytes of sample i (rows None where
        ``needs_rows`` was false when the chunk was encoded). The bytes are
        published at once (only on topics with subscribers at the last ``refresh``); the
        sinks get them later, in one hand-off per chunk (``hand_over``). ``part``: only these
        samples of the chunk."""
        a = 0 if part is None else part.start
        b = len(ns) if part is None else part.stop
        n = b - a
        if self._live_for is not topics:  # once per chunk (and count of subscribers)
            self._live = [(self.channels[topic], rows) for topic, rows, _ in topics
                          if rows is not None and self.subscribers.get(topic, 0) > 0]
            self._live_for = topics
        live = self._live
        step = LOSSLESS_DEPTH if self.lossless else max(n, 1)
        for start in range(a, b, step):
            # The previous slice is acknowledged before this one goes out: the history then
            # never holds more than one slice unacknowledged, and a subscriber takes a slice
            # while the node computes the next.
            self.settle()
            for ch, rows in live:
                publish = ch.publisher.publish
                for r in rows[start:min(start + step, b)]:
                    publish(r.tobytes())
            if self.lossless:
                self._unacknowledged = [ch for ch, _ in live]
        for topic, _, _ in topics:
            self.counts[topic] += n
        if not self.sinks or not n:
            return
        held = self._held
        if held is not None and held[1] is topics and held[4] == a:
            held[4] = b  # the next samples of the chunk held: handed over together
        else:
            self.hand_over()
            self._held = [ns, topics, columns, a, b]
        if self._immediate():
            self.hand_over()

    def _sink_kinds(self) -> _SinkKinds:
        """What the sinks take, asked again only when the sinks change (what a sink takes is
        fixed when it is made)."""
        key = tuple(map(id, self.sinks))  # the sinks themselves, not the list holding them
        if key != self._kinds_for:
            self._kinds_for = key
            self._kinds = _SinkKinds(
                any(getattr(sink, "immediate", False) for sink in self.sinks),
                any(hasattr(sink, "write_chunk") for sink in self.sinks),
                [getattr(sink, "wants", None) for sink in self.sinks
                 if hasattr(sink, "write_columns")], {})
        return self._kinds

    def _immediate(self) -> bool:
        """Does a sink take every sample as it is published (``immediate``)?"""
        return self._sink_kinds().immediate

    def hand_over(self) -> None:
        """Hand the published samples held for the sinks over to them, in one call per sink
        (per topic for ``write_columns``): ``write_chunk`` (the recorder) gets the CDR rows;
        a sink with ``write_columns`` gets the evaluated values the rows were encoded from
        (for the topics that have them) instead of messages; any other sink gets messages,
        built only for the topics it wants, sample by sample in time order.

        Samples are held from their publication to the end of their chunk (``publish_chunk``),
        so a paced run that publishes a sample or two per tick hands each sink a whole chunk
        at once; every other message of this outlet (``publish``, ``record``) hands the held
        ones over first, so each sink sees this outlet's messages in the order they were
        published. A sink that must see every sample as it is published (a live view) says
        so with a true ``immediate`` attribute. The runner hands over what is held before it
        reports diagnostics and when it stops: nothing published is left out."""
        held, self._held = self._held, None
        if held is None:
            return
        ns, topics, columns, a, b = held
        part = None if a == 0 and b == len(ns) else slice(a, b)
        if part is not None:
            ns = ns[part]
        n = b - a
        columns = columns or {}
        for sink in self.sinks:
            write_chunk = getattr(sink, "write_chunk", None)
            if write_chunk is not None:
                write_chunk(ns, [(topic, self.channels[topic].type_name,
                                  self.channels[topic].qos,
                                  rows if part is None else rows[part])
                                 for topic, rows, _ in topics])
                continue
            wants = getattr(sink, "wants", None)
            chosen = [(topic, message) for topic, _, message in topics
                      if wants is None or wants(topic)]
            write_columns = getattr(sink, "write_columns", None)
            if write_columns is not None:
                for topic, _ in chosen:
                    if topic in columns:
                        values = columns[topic]
                        write_columns(topic, ns, values if part is None
                                      else column_rows(values, part))
                chosen = [(t, m) for t, m in chosen if t not in columns]
            for i in range(n):
                for topic, message in chosen:
                    sink.write(topic, self.channels[topic].type_name, message(a + i),
                               self.channels[topic].qos, int(ns[i]))

    def settle(self) -> None:
        """Wait for the acknowledgment of the last slice published (``lossless``; the runner
        calls this when a run ends)."""
        if self._unacknowledged:
            channels, self._unacknowledged = self._unacknowledged, []
            self._acknowledged(channels)

    def _acknowledged(self, channels: list[_Channel]) -> None:
        """Wait until every reliable subscriber of ``channels`` has acknowledged what was
        published (``lossless``), giving up on a topic whose reader stopped answering."""
        from rclpy.duration import Duration

        for ch in channels:
            topic = ch.publisher.topic_name
            if not streamed(ch.qos) or topic in self._gave_up:
                continue
            if not ch.publisher.wait_for_all_acked(Duration(seconds=LOSSLESS_WAIT)):
                self._gave_up.add(topic)
                self.node.get_logger().warning(
                    f"{topic}: a reliable subscriber acknowledged nothing for "
                    f"{LOSSLESS_WAIT:g} s; no longer waiting for it (messages may be lost)")

    def publish(self, topic: str, msg: Any, ns: int) -> None:
        self.hand_over()
        ch = self.channels[topic]
        # The CDR bytes with zero padding (reproducible), made once: published as they are
        # and handed to a recorder.
        data = cdr_bytes(msg)
        ch.publisher.publish(data)
        self.counts[topic] += 1
        for sink in self.sinks:
            if hasattr(sink, "write_serialized"):
                sink.write_serialized(topic, ch.type_name, msg, ch.qos, ns, data)
            else:
                sink.write(topic, ch.type_name, msg, ch.qos, ns)

    def publish_serialized(self, topic: str, data: bytes, ns: int,
                           message: Callable[[], Any]) -> None:
        """Publish a message already encoded (``data``: CDR bytes, padding zero). A sink that
        records bytes (``write_bytes``) gets them; any other gets ``message()``, made only if
        it wants the topic. A volatile topic without a subscriber is not written to DDS (a
        fast run reports a thousand times a second; nobody could receive it later)."""
        self.hand_over()
        ch = self.channels[topic]
        if ch.qos.durability != DurabilityPolicy.VOLATILE \
                or ch.publisher.get_subscription_count():
            ch.publisher.publish(data)
        self.counts[topic] += 1
        msg = None
        for sink in self.sinks:
            write_bytes = getattr(sink, "write_bytes", None)
            if write_bytes is not None:
                write_bytes(topic, ch.type_name, ch.qos, ns, data)
                continue
            wants = getattr(sink, "wants", None)
            if wants is None or wants(topic):
                msg = message() if msg is None else msg
                sink.write(topic, ch.type_name, msg, ch.qos, ns)

    def record(self, topic: str, msg: Any, qos: QoSProfile, ns: int) -> None:
        """Hand a message this node did not publish (an input it applied, such as an effort
        command) to the sinks only, so a recording holds it like a published one; counted
        with the published ones."""
        self.hand_over()
        self.counts[topic] = self.counts.get(topic, 0) + 1
        name = type_name(type(msg))
        for sink in self.sinks:
            wants = getattr(sink, "wants", None)
            if wants is None or wants(topic):
                sink.write(topic, name, msg, qos, ns)
