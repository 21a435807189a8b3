"""Sample batches from a live graph: ``<ns>/sample_batch`` messages as numpy arrays.

For a consumer in its own process that wants every sample of a system, many at a time
(``subscribe_batches("pendulum")`` is ``BatchSubscriber(["/pendulum/sample_batch"])``)::

    from mechsim.ros.batches import subscribe_batches

    with subscribe_batches("pendulum") as sub:
        for topic, batch in sub.batches(idle=5.0):      # until 5 s pass without one
            theta = batch.positions["angle"]            # (samples,) float64
            energy = batch.energy["total"]

``sub.take(timeout)`` instead returns what has arrived (waiting up to ``timeout`` for the
first), for a loop of one's own; on a node of one's own, ``subscribe(node, topic,
callback)``. The subscription is reliable and keeps every message until it is taken
(KEEP_ALL), so with a simulator run ``--lossless`` nothing is lost however long the consumer
takes; the bytes are decoded with numpy (``mechsim.outputs.batch.decode``), without rclpy's
message objects. The same arrays from a bag: ``mechsim.outputs.batch.read_batches``.
"""

from __future__ import annotations

import functools
import os
import time
from collections import deque
from collections.abc import Callable, Iterator
from types import TracebackType
from typing import Any

from mechsim.outputs.batch import SampleBatch, decode


def batch_qos() -> Any:
    """Reliable, every message kept until taken, volatile (what a simulator offers)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(depth=1, history=HistoryPolicy.KEEP_ALL,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


def subscribe(node: Any, topic: str, callback: Callable[[SampleBatch], None],
              qos: Any = None) -> Any:
    """A subscription of ``node`` that calls ``callback(batch)`` for each message on
    ``topic`` (``mechsim_msgs/msg/SampleBatch``), decoded; returns the subscription."""
    from mechsim_msgs.msg import SampleBatch as Message

    return node.create_subscription(Message, topic, lambda data: callback(decode(data)),
                                    batch_qos() if qos is None else qos, raw=True)


def batch_topic(name: str) -> str:
    """The batch topic of ``name``: a topic ending in ``/sample_batch`` as it is, otherwise an
    instance's namespace (``pendulum``, ``/pendulum``: ``/pendulum/sample_batch``)."""
    from mechsim.outputs.batch import TOPIC

    if name.rpartition("/")[2] == TOPIC:
        return name
    return f"/{name.strip('/')}/{TOPIC}"


def subscribe_batches(topics: str | list[str], *, context: Any = None) -> BatchSubscriber:
    """A :class:`BatchSubscriber` (a hidden node of its own, in a ROS context of its own
    unless one is given) to the batch topics of ``topics``: batch topics or instance names
    (``"pendulum"`` is ``/pendulum/sample_batch``). Use it as a context manager, or call
    ``close()``."""
    return BatchSubscriber([topics] if isinstance(topics, str) else list(topics),
                           context=context)


class BatchSubscriber:
    """A node of its own (hidden, in a context of its own unless one is given) subscribed to
    ``topics`` (batch topics or instance names, :func:`batch_topic`); :meth:`batches` yields
    (topic, batch) as they arrive, :meth:`take` returns them. A context manager: the node and
    its context go at the end."""

    def __init__(self, topics: list[str], *, context: Any = None) -> None:
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        from mechsim.ros.graph_check import start_context

        self._own = context is None
        self.context = start_context() if context is None else context
        self.node = Node(f"_mechsim_batches_{os.getpid()}", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._arrived: deque[tuple[str, SampleBatch]] = deque()
        self.topics = [batch_topic(t) for t in topics]
        self.subscriptions = [
            subscribe(self.node, t, functools.partial(self._arrive, t))
            for t in self.topics]

    def _arrive(self, topic: str, batch: SampleBatch) -> None:
        self._arrived.append((topic, batch))

    def matched(self) -> int:
        """How many publishers the subscriptions have matched, all topics together."""
        return sum(s.get_publisher_count() for s in self.subscriptions)

    def take(self, timeout: float = 0.0) -> list[tuple[str, SampleBatch]]:
        """The (topic, batch) pairs that arrived, in order, waiting up to ``timeout`` seconds
        for the first if none has (empty if none came)."""
        end = time.monotonic() + timeout
        while True:
            before = len(self._arrived)
            wait = 0.0 if before else min(0.05, max(0.0, end - time.monotonic()))
            self.executor.spin_once(timeout_sec=wait)
            # on while messages keep coming; once none did, stop if one has or time is up
            if len(self._arrived) == before and (before or time.monotonic() >= end):
                break
        got = list(self._arrived)
        self._arrived.clear()
        return got

    def batches(self, idle: float | None = None) -> Iterator[tuple[str, SampleBatch]]:
        """(topic, batch) in the order they arrive, until ``idle`` seconds pass without one
        (counted from the call, then from the latest batch; None: until the caller stops)."""
        last = time.monotonic()
        while True:
            got = self.take(0.05 if idle is None else min(idle, 0.05))
            if got:
                yield from got
                last = time.monotonic()
            elif idle is not None and time.monotonic() - last > idle:
                return

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        if self._own:
            self.context.try_shutdown()

    def __enter__(self) -> BatchSubscriber:
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
