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

import array
import json
import math
import sys
import time
from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from mechsim.errors import MechsimError

DISCOVERY_WAIT = 1.0


@contextmanager
def graph_node(name: str) -> Iterator[Any]:
    from mechsim.ros.graph_check import quiet_node, start_context

    ctx = start_context()
    from rclpy.executors import SingleThreadedExecutor

    node = quiet_node(name, "mechsim", ctx)
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
def wait_for_type(node: Any, ex: Any, topic: str, timeout: float | None) -> tuple[str, Any]:
    """(type name, QoS) of ``topic`` once it is published; MechsimError after ``timeout``."""
    from mechsim.ros.outlet import subscription_qos

    start = time.monotonic()
    said = False
    while True:
        types = dict(node.get_topic_names_and_types())
        infos = node.get_publishers_info_by_topic(topic) if topic in types else []
        if infos:
            qos = subscription_qos([i.qos_profile for i in infos])
            return types[topic][0], qos
        waited = time.monotonic() - start
        if timeout is not None and waited >= timeout:
            raise MechsimError(f"topic {topic}: not published (waited {timeout:g} s; "
                               "see `mechsim topic list`)")
        if not said and waited >= DISCOVERY_WAIT:
            print(f"mechsim: waiting for topic {topic} to be published ...", file=sys.stderr)
            said = True
        ex.spin_once(timeout_sec=0.05)


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
