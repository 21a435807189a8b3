"""Sample batches from a live graph: ``<ns>/sample_batch`` messages as numpy arrays.

For a consumer in its own process that wants every sample of a system, many at a time::

    from mechsim.ros.batches import BatchSubscriber

    with BatchSubscriber(["/pendulum/sample_batch"]) as sub:
        for topic, batch in sub.batches(idle=5.0):      # until 5 s pass without one
            theta = batch.positions["theta"]            # (samples,) float64
            energy = batch.energy["total"]

or, on a node of one's own, ``subscribe(node, topic, callback)``. The subscription is
reliable and keeps every message until it is taken (KEEP_ALL), so with a simulator run
``--lossless`` nothing is lost however long the consumer takes; the bytes are decoded with
numpy (``mechsim.outputs.batch.decode``), without rclpy's message objects. The same arrays
from a bag: ``mechsim.outputs.batch.read_batches``.
"""

from __future__ import annotations

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


class BatchSubscriber:
    """A node of its own (hidden, in a context of its own unless one is given) subscribed to
    ``topics``; :meth:`batches` yields (topic, batch) as they arrive. A context manager: the
    node and its context go at the end."""

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
        self.subscriptions = [
            subscribe(self.node, t, lambda b, t=t: self._arrived.append((t, b)))
            for t in topics]

    def matched(self) -> int:
        """How many publishers the subscriptions have matched, all topics together."""
        return sum(s.get_publisher_count() for s in self.subscriptions)

    def batches(self, idle: float | None = None) -> Iterator[tuple[str, SampleBatch]]:
        """(topic, batch) in the order they arrive, until ``idle`` seconds pass without one
        (None: until the caller stops)."""
        last = time.monotonic()
        while True:
            while self._arrived:
                yield self._arrived.popleft()
                last = time.monotonic()
            if idle is not None and time.monotonic() - last > idle:
                return
            self.executor.spin_once(timeout_sec=0.05 if idle is None else min(idle, 0.05))

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
