"""``mechsim topic list | echo | hz``: the live graph, shaped like ``ros2 topic`` (which the
PyPI wheels do not provide).

- ``list [-t]``: every topic seen after a short discovery wait, sorted; ``-t`` appends
  ``[type]``.
- ``echo TOPIC [--once]``: each message as YAML (``ros2 topic echo`` layout), separated by
  ``---``. The subscription QoS follows the publishers (reliable only if all are, transient
  local if all are), as ``ros2 topic echo`` does, so /clock and /tf_static work.
- ``hz TOPIC``: ``average rate`` / ``min`` / ``max`` / ``std dev`` / ``window`` about once a
  second, from the wall-clock arrival times.
``echo`` and ``hz`` wait for the topic to appear (``--timeout`` bounds the wait: then one error
line, exit 2) and run until Ctrl-C, ``--once``, ``--count N`` or ``--duration S``.
"""

from __future__ import annotations

import argparse
import array
import json
import math
import sys
import time
from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from mechsim.errors import MechsimError, ParameterError

DISCOVERY_WAIT = 1.0


@contextmanager
def _graph_node(name: str) -> Iterator[Any]:
    from mechsim.ros.environment import import_rclpy

    rclpy = import_rclpy()
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.signals import SignalHandlerOptions

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, signal_handler_options=SignalHandlerOptions.NO)
    node = Node(name, namespace="mechsim", context=ctx, start_parameter_services=False)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    try:
        yield node, ex
    finally:
        ex.shutdown()
        node.destroy_node()
        ctx.try_shutdown()


# --- YAML dump of a message (ros2 topic echo layout) ------------------------------------------
def _scalar(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        if math.isnan(v):
            return ".nan"
        if math.isinf(v):
            return ".inf" if v > 0 else "-.inf"
        return repr(v)
    if isinstance(v, str):
        return v if _plain_ok(v) else json.dumps(v, ensure_ascii=False)
    if isinstance(v, bytes):
        return str(list(v))
    return str(v)


def _plain_ok(v: str) -> bool:
    """Can ``v`` be written as a plain YAML scalar that reads back as the same string?"""
    import yaml

    if not v or "\n" in v or v != v.strip() or v[0] in "-?:,[]{}#&*!|>'\"%@`":
        return False
    if ": " in v or " #" in v:
        return False
    try:
        return yaml.safe_load(v) == v
    except yaml.YAMLError:
        return False


def _is_msg(v: Any) -> bool:
    return hasattr(v, "get_fields_and_field_types")


def message_yaml(msg: Any, indent: int = 0) -> str:
    """A message as ``ros2 topic echo`` prints it (block YAML, sequences as ``- item``)."""
    pad = " " * indent
    lines: list[str] = []
    for name in msg.get_fields_and_field_types():
        v = getattr(msg, name)
        if _is_msg(v):
            lines.append(f"{pad}{name}:")
            lines.append(message_yaml(v, indent + 2))
        elif isinstance(v, list | tuple | array.array) or type(v).__name__ == "ndarray":
            items = list(v)
            if not items:
                lines.append(f"{pad}{name}: []")
                continue
            lines.append(f"{pad}{name}:")
            for it in items:
                if _is_msg(it):
                    sub = message_yaml(it, indent + 2).splitlines()
                    lines.append(f"{pad}- {sub[0].lstrip()}")
                    lines.extend(sub[1:])
                else:
                    lines.append(f"{pad}- {_scalar(it.item() if hasattr(it, 'item') else it)}")
        else:
            lines.append(f"{pad}{name}: {_scalar(v.item() if hasattr(v, 'item') else v)}")
    return "\n".join(lines)


# --- commands ---------------------------------------------------------------------------------
def _wait_for_type(node: Any, ex: Any, topic: str, timeout: float | None) -> tuple[str, Any]:
    """(type name, QoS) of ``topic`` once it is published; MechsimError after ``timeout``."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    start = time.monotonic()
    said = False
    while True:
        types = dict(node.get_topic_names_and_types())
        infos = node.get_publishers_info_by_topic(topic) if topic in types else []
        if infos:
            reliable = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE
                           for i in infos)
            latched = all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                          for i in infos)
            qos = QoSProfile(
                depth=100 if reliable else 10, history=HistoryPolicy.KEEP_LAST,
                reliability=ReliabilityPolicy.RELIABLE if reliable
                else ReliabilityPolicy.BEST_EFFORT,
                durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                else DurabilityPolicy.VOLATILE)
            return types[topic][0], qos
        waited = time.monotonic() - start
        if timeout is not None and waited >= timeout:
            raise MechsimError(f"topic {topic}: not published (waited {timeout:g} s; "
                               "see `mechsim topic list`)")
        if not said and waited >= DISCOVERY_WAIT:
            print(f"mechsim: waiting for topic {topic} to be published ...", file=sys.stderr)
            said = True
        ex.spin_once(timeout_sec=0.05)


def _topic_name(topic: str) -> str:
    if not topic or topic != topic.strip():
        raise ParameterError("topic", f"invalid name {topic!r}")
    return topic if topic.startswith("/") else "/" + topic


def cmd_list(a: argparse.Namespace) -> int:
    with _graph_node("topic_list") as (node, ex):
        end = time.monotonic() + a.wait
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
        own = {"/rosout", "/parameter_events"}
        topics = sorted(node.get_topic_names_and_types())
        for name, types in topics:
            if name in own and not node.get_publishers_info_by_topic(name):
                continue  # only this tool's own endpoints
            print(f"{name} [{', '.join(types)}]" if a.show_types else name)
    return 0


def _run_until(ex: Any, done: Any, duration: float | None) -> None:
    end = None if duration is None else time.monotonic() + duration
    while not done():
        if end is not None and time.monotonic() >= end:
            return
        ex.spin_once(timeout_sec=0.1)


def cmd_echo(a: argparse.Namespace) -> int:
    from mechsim.ros.bag import message_class

    topic = _topic_name(a.topic)
    count = 1 if a.once else a.count
    with _graph_node("topic_echo") as (node, ex):
        type_name, qos = _wait_for_type(node, ex, topic, a.timeout)
        cls = message_class(type_name)
        seen = [0]

        def on_msg(msg: Any) -> None:
            if count is not None and seen[0] >= count:
                return
            seen[0] += 1
            sys.stdout.write(message_yaml(msg) + "\n---\n")
            sys.stdout.flush()

        node.create_subscription(cls, topic, on_msg, qos)
        _run_until(ex, lambda: count is not None and seen[0] >= count, a.duration)
    return 0


class RateWindow:
    """Arrival times of the last ``window`` messages and ``ros2 topic hz`` statistics."""

    def __init__(self, window: int) -> None:
        self.times: deque[float] = deque(maxlen=window + 1)

    def add(self, t: float) -> None:
        self.times.append(t)

    def stats(self) -> tuple[float, float, float, float, int] | None:
        """(rate, min, max, std dev, window) or None before two messages."""
        if len(self.times) < 2:
            return None
        ts = list(self.times)
        deltas = [b - a for a, b in zip(ts, ts[1:], strict=False)]
        n = len(deltas)
        mean = sum(deltas) / n
        std = math.sqrt(sum((d - mean) ** 2 for d in deltas) / n)
        return (1.0 / mean if mean > 0 else float("inf"), min(deltas), max(deltas), std, n)


def format_hz(s: tuple[float, float, float, float, int]) -> str:
    rate, lo, hi, std, n = s
    return (f"average rate: {rate:.3f}\n"
            f"\tmin: {lo:.3f}s max: {hi:.3f}s std dev: {std:.5f}s window: {n}")


def cmd_hz(a: argparse.Namespace) -> int:
    from mechsim.ros.bag import message_class

    topic = _topic_name(a.topic)
    if a.window < 1:
        raise ParameterError("--window", f"must be >= 1 (got {a.window})")
    with _graph_node("topic_hz") as (node, ex):
        type_name, qos = _wait_for_type(node, ex, topic, a.timeout)
        win = RateWindow(a.window)
        node.create_subscription(message_class(type_name), topic,
                                 lambda _m: win.add(time.monotonic()), qos)
        end = None if a.duration is None else time.monotonic() + a.duration
        next_print = time.monotonic() + 1.0
        while end is None or time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
            if time.monotonic() >= next_print:
                next_print += 1.0
                s = win.stats()
                print(format_hz(s) if s else "no new messages", flush=True)
    return 0


def add_parser(sub: Any) -> None:
    t = sub.add_parser("topic", help="list, echo and measure topics of the live graph")
    tsub = t.add_subparsers(dest="topic_command", required=True)
    lp = tsub.add_parser("list", help="topics of the live graph")
    lp.add_argument("-t", "--show-types", action="store_true", help="append the type")
    lp.add_argument("--wait", type=float, default=DISCOVERY_WAIT,
                    help="discovery wait [s] (default %(default)s)")
    lp.set_defaults(func=cmd_list)
    for name, func, hlp in (("echo", cmd_echo, "print messages as YAML"),
                            ("hz", cmd_hz, "print the publishing rate")):
        p = tsub.add_parser(name, help=hlp)
        p.add_argument("topic")
        p.add_argument("--timeout", type=float, help="give up if the topic does not appear "
                       "within this many seconds")
        p.add_argument("--duration", type=float, help="stop after this many wall seconds")
        if name == "echo":
            p.add_argument("--once", action="store_true", help="print one message and exit")
            p.add_argument("--count", type=int, help="print this many messages and exit")
        else:
            p.add_argument("--window", type=int, default=10000,
                           help="messages in the statistics window (default %(default)s)")
        p.set_defaults(func=func)
