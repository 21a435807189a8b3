"""The one output path: every message a node sends goes through an Outlet, which publishes it
on ROS and hands it, with its topic and time, to any attached sinks (the bag recorder, the
Rerun logger). In-process sinks see every message, so a recording cannot drop one."""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from mechsim.outputs.sink import ChunkTopic, Sink, Sinks
from mechsim.outputs.wire import encode

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


#: A lossless run sends a chunk in slices of this many samples and keeps up to
#: ``LOSSLESS_SLICES`` of them in flight: each streamed publisher's history holds that many
#: samples' messages, and before a slice that would not fit the node waits until every
#: reliable subscriber has acknowledged everything (Fast DDS acknowledges about once per
#: heartbeat period of the project's profile: a slice acknowledged before the next one goes
#: out would leave the subscriber idle for a heartbeat per slice).
LOSSLESS_DEPTH = 1000
LOSSLESS_SLICES = 8
#: Longest wait for one slice's acknowledgments (a reader that stopped answering is given up
#: on after it, with one warning).
LOSSLESS_WAIT = 10.0
#: A wait that only looks (acknowledged now or not).
_NOW = Duration(seconds=0)


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


def _message(data: bytes, ch: _Channel) -> Any:
    """The rclpy message of a channel's CDR bytes (for a sink that takes messages)."""
    from rclpy.serialization import deserialize_message

    return deserialize_message(data, ch.publisher.msg_type)


@dataclass
class _Channel:
    publisher: Publisher
    type_name: str
    qos: QoSProfile


def type_name(msg_type: type) -> str:
    """'sensor_msgs/msg/JointState' for the class JointState."""
    module = msg_type.__module__.split(".")
    return f"{module[0]}/msg/{msg_type.__name__}"


class Outlet:
    """Publishers of one node plus the process's sinks (shared list, attached by the runner).

    Everything handed to the sinks goes through one :class:`~mechsim.outputs.sink.Sinks`
    (made again when the list changes): each sink gets, in the form it declares, only the
    topics it wants, on every path (:meth:`publish`, :meth:`publish_chunk` and
    :meth:`hand_over`, :meth:`publish_serialized`, :meth:`record`)."""

    def __init__(self, node: Node, sinks: list[Sink] | None = None,
                 lossless: bool = False) -> None:
        """``lossless``: chunks wait for every reliable subscriber's acknowledgment (of each
        ``LOSSLESS_DEPTH`` samples) instead of letting the history overwrite what a slow
        reader has not taken: no message lost, at the pace of the slowest reader."""
        self.node = node
        self.lossless = lossless
        #: The channels with samples in flight, and how many samples (lossless).
        self._unacknowledged: dict[str, _Channel] = {}
        self._in_flight = 0
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
        #: Messages of sparse topics (batches, trail bodies) published and not yet handed to
        #: the sinks: (topic, stamp, bytes).
        self._held_sparse: list[tuple[str, int, bytes]] = []
        #: The topics with subscribers, with their rows, of the chunk ``_live_for``.
        self._live: list[tuple[_Channel, np.ndarray]] = []
        self._live_for: Any = None
        self._dispatch_for: tuple[int, ...] = ()
        self._dispatch = Sinks([])

    def channel(self, topic: str, msg_type: type, qos: QoSProfile) -> str:
        resolved = self.node.resolve_topic_name(topic)
        if resolved not in self.channels:
            if self.lossless and streamed(qos):
                qos = QoSProfile(depth=max(qos.depth, LOSSLESS_DEPTH * LOSSLESS_SLICES),
                                 history=qos.history, reliability=qos.reliability,
                                 durability=qos.durability)
            pub: Any = self.node.create_publisher(msg_type, resolved, qos)
            self.channels[resolved] = _Channel(pub, type_name(msg_type), qos)
            self.counts[resolved] = 0
        return resolved

    def refresh(self) -> None:
        """Count every topic's subscribers now (read by ``wanted`` and ``publish_chunk``)."""
        for topic, ch in self.channels.items():
            self.subscribers[topic] = ch.publisher.get_subscription_count()
        self._live_for = None

    def _sinks(self) -> Sinks:
        """The dispatch of the attached sinks, made again only when they change (what a sink
        takes and wants is declared when it is made)."""
        key = tuple(map(id, self.sinks))  # the sinks themselves, not the list holding them
        if key != self._dispatch_for:
            self._dispatch = Sinks(self.sinks)
            self._dispatch_for = key
        return self._dispatch

    def needs_rows(self, topic: str) -> bool:
        """Are the CDR bytes of ``topic``'s samples needed (a subscriber as counted at the
        last ``refresh``, or a sink that wants the topic as bytes)? Other sinks take values
        or messages, so a chunk nobody reads as bytes is not encoded."""
        return self.subscribers.get(topic, 0) > 0 or self._sinks().needs_rows(topic)

    def needs_columns(self, topic: str) -> bool:
        """Are the evaluated values of ``topic``'s samples needed (a sink that takes columns
        wants the topic)? Otherwise a chunk's values are not gathered into columns: the
        sinks get CDR rows or messages."""
        return self._sinks().needs_columns(topic)

    def wanted(self, topic: str) -> bool:
        """Does anything consume ``topic`` (a sink that wants it, or a subscriber anywhere as
        counted at the last ``refresh``)?"""
        return self._sinks().wants(topic) or self.subscribers.get(topic, 0) > 0

    def publish_chunk(self, ns: np.ndarray,
                      topics: list[tuple[str, np.ndarray | None, Callable[[int], Any]]],
                      columns: Mapping[str, Any] | None = None,
                      part: slice | None = None,
                      sparse: list[tuple[str, Callable[[int, int], list[tuple[int, bytes]]]]]
                      | None = None) -> None:
        """The messages of a chunk of samples stamped ``ns``, already encoded: for each
        (topic, rows, message), row i holds the CDR bytes of sample i (rows None where
        ``needs_rows`` was false when the chunk was encoded). The bytes are
        published at once (only on topics with subscribers at the last ``refresh``); the
        sinks get them later, in one hand-off per chunk (``hand_over``). ``part``: only these
        samples of the chunk. ``sparse``: the topics with messages at some samples only, each
        (topic, make) where ``make(i, j)`` gives the messages of samples i to j (exclusive)
        as (sample, CDR bytes) (a batch of samples; a trail body where it changes), asked
        only where a subscriber or a sink takes the topic; the sinks get them after the
        samples of the chunk."""
        a = 0 if part is None else part.start
        b = len(ns) if part is None else part.stop
        n = b - a
        if self._live_for is not topics:  # once per chunk (and count of subscribers)
            self._live = [(self.channels[topic], rows) for topic, rows, _ in topics
                          if rows is not None and self.subscribers.get(topic, 0) > 0]
            self._live_for = topics
        live = self._live
        extra = [p for p in map(self._sparse_outlet, sparse or ()) if p is not None]
        step = LOSSLESS_DEPTH if self.lossless else max(n, 1)
        for start in range(a, b, step):
            end = min(start + step, b)
            self._make_room(end - start)
            for ch, rows in live:
                publish = ch.publisher.publish
                for r in rows[start:end]:
                    publish(r.tobytes())
            for publish_sparse in extra:
                publish_sparse(start, end, ns)
            if self.lossless:
                self._in_flight += end - start
                self._unacknowledged.update((ch.publisher.topic_name, ch) for ch, _ in live)
        for topic, _, _ in topics:
            self.counts[topic] += n
        if not self.sinks or not n:
            return
        held = self._held
        if held is not None and held[1] is topics and held[4] == a:
            held[4] = b  # the next samples of the chunk held: handed over together
        else:
            self._hand_over_chunk()
            self._held = [ns, topics, columns, a, b]
        if self._sinks().immediate:
            self.hand_over()

    def _sparse_outlet(self, sparse: tuple[str, Callable[[int, int], list[tuple[int, bytes]]]]
                       ) -> Callable[[int, int, np.ndarray], None] | None:
        """What publishes the messages of a sparse topic (``publish_chunk``) of samples i to
        j of a chunk, or None if nothing takes them."""
        topic, make = sparse
        ch = self.channels[topic]
        live = self.subscribers.get(topic, 0) > 0
        held = self._sinks().wants(topic)
        if not (live or held):
            return None

        def publish(i: int, j: int, ns: np.ndarray) -> None:
            for k, data in make(i, j):
                if live:
                    ch.publisher.publish(data)
                if held:
                    self._held_sparse.append((topic, int(ns[k]), data))
                self.counts[topic] += 1
            if live and self.lossless:
                self._unacknowledged[topic] = ch
        return publish

    def hand_over(self) -> None:
        """Hand the published samples held for the sinks over to them, in one call per sink
        (``Sinks.chunk``: rows, columns or messages, each sink the topics it wants).

        Samples are held from their publication to the end of their chunk (``publish_chunk``),
        so a paced run that publishes a sample or two per tick hands each sink a whole chunk
        at once; every other message of this outlet (``publish``, ``record``) hands the held
        ones over first, so each sink sees this outlet's messages in the order they were
        published. A sink declared ``immediate`` (a live view) gets every sample as it is
        published. The runner hands over what is held before it reports diagnostics and when
        it stops: nothing published is left out."""
        self._hand_over_chunk()
        if self._held_sparse:
            batches, self._held_sparse = self._held_sparse, []
            for topic, ns, data in batches:
                ch = self.channels[topic]
                self._sinks().message(topic, ch.type_name, ch.qos, ns, data=data,
                                      make=functools.partial(_message, data, ch))

    def _hand_over_chunk(self) -> None:
        """The held samples of the per-sample topics to the sinks (``hand_over``)."""
        held, self._held = self._held, None
        if held is None:
            return
        ns, topics, columns, a, b = held
        part = None if a == 0 and b == len(ns) else slice(a, b)
        channels = self.channels
        self._sinks().chunk(ns, [ChunkTopic(topic, channels[topic].type_name,
                                            channels[topic].qos, rows, message)
                                 for topic, rows, message in topics], columns, part)

    @property
    def in_flight(self) -> int:
        """Samples published (lossless) that a reliable subscriber may not have acknowledged
        yet, as last looked at."""
        return self._in_flight

    def _make_room(self, samples: int) -> None:
        """Before ``samples`` more samples go out (lossless): if they would not fit in the
        publishers' history beside those in flight, wait until every reliable subscriber has
        acknowledged everything; otherwise only look (without waiting) whether it has."""
        if not self._in_flight:
            return
        if self._in_flight + samples > LOSSLESS_DEPTH * LOSSLESS_SLICES:
            self.settle()
        elif all(ch.publisher.wait_for_all_acked(_NOW)
                 for ch in self._unacknowledged.values()):
            self._unacknowledged.clear()
            self._in_flight = 0

    def settle(self) -> None:
        """Wait for the acknowledgment of every sample in flight (``lossless``; the runner
        calls this when a run ends)."""
        if self._unacknowledged:
            channels = list(self._unacknowledged.values())
            self._unacknowledged.clear()
            self._acknowledged(channels)
        self._in_flight = 0

    def acknowledged(self, topic: str) -> None:
        """Wait until every reliable subscriber of ``topic`` has acknowledged what was
        published on it (``lossless``: before more single messages than its history holds go
        out at once), giving up as :meth:`settle` does."""
        self._acknowledged([self.channels[topic]])

    def _acknowledged(self, channels: list[_Channel]) -> None:
        """Wait until every reliable subscriber of ``channels`` has acknowledged what was
        published (``lossless``), giving up on a topic whose reader stopped answering."""
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
        """Publish one message: its CDR bytes (padding zero, reproducible) are made once,
        published as they are and handed to the sinks that take bytes."""
        self.hand_over()
        ch = self.channels[topic]
        data = encode(ch.type_name, msg)
        ch.publisher.publish(data)
        self.counts[topic] += 1
        self._sinks().message(topic, ch.type_name, ch.qos, ns, msg=msg, data=data)

    def publish_serialized(self, topic: str, data: bytes, ns: int,
                           message: Callable[[], Any]) -> None:
        """Publish a message already encoded (``data``: CDR bytes, padding zero). A sink that
        takes bytes gets them; one that takes messages gets ``message()``, made only if such
        a sink wants the topic. A volatile topic without a subscriber is not written to DDS
        (a fast run reports many times a second; nobody could receive it later)."""
        self.hand_over()
        ch = self.channels[topic]
        if ch.qos.durability != DurabilityPolicy.VOLATILE \
                or ch.publisher.get_subscription_count():
            ch.publisher.publish(data)
        self.counts[topic] += 1
        self._sinks().message(topic, ch.type_name, ch.qos, ns, data=data, make=message)

    def record(self, topic: str, msg: Any, qos: QoSProfile, ns: int) -> None:
        """Hand a message this node did not publish (an input it applied, such as an effort
        command) to the sinks only, so a recording holds it like a published one; counted
        with the published ones."""
        self.hand_over()
        self.counts[topic] = self.counts.get(topic, 0) + 1
        self._sinks().message(topic, type_name(type(msg)), qos, ns, msg=msg)
