"""`mechsim topic`."""

from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Any

from mechsim.errors import ParameterError
from mechsim.ros.topic_tools import (
    DISCOVERY_WAIT,
    RateWindow,
    format_hz,
    graph_node,
    message_yaml,
    wait_for_type,
)


def _topic_name(topic: str) -> str:
    if not topic or topic != topic.strip():
        raise ParameterError("topic", f"invalid name {topic!r}")
    return topic if topic.startswith("/") else "/" + topic


#: Largest wall-clock wait an option takes [s] (a day): beyond it a typo, not a wish.
MAX_WAIT = 86400.0


def _seconds(option: str, value: float | None) -> float | None:
    """A wall-clock option (``--timeout``, ``--duration``, ``--wait``): None (not given) or a
    finite number of seconds in [0, MAX_WAIT]; ``nan`` or ``inf`` would wait for ever."""
    if value is not None and not (math.isfinite(value) and 0.0 <= value <= MAX_WAIT):
        raise ParameterError(option, f"must be a finite number of seconds in [0, {MAX_WAIT:g}] "
                             f"(got {value})")
    return value


def _checked(a: argparse.Namespace) -> None:
    """Every wall-clock option of ``a`` checked (ParameterError naming it)."""
    for name in ("timeout", "duration", "wait"):
        _seconds(f"--{name}", getattr(a, name, None))
    if getattr(a, "count", None) is not None and a.count < 1:
        raise ParameterError("--count", f"must be >= 1 (got {a.count})")


def cmd_list(a: argparse.Namespace) -> int:
    _checked(a)
    with graph_node("topic_list") as (node, ex):
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
    from mechsim.outputs.bag import message_class

    topic = _topic_name(a.topic)
    _checked(a)
    count = 1 if a.once else a.count
    with graph_node("topic_echo") as (node, ex):
        type_name, qos = wait_for_type(node, ex, topic, a.timeout)
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


def cmd_hz(a: argparse.Namespace) -> int:
    from mechsim.outputs.bag import message_class

    topic = _topic_name(a.topic)
    _checked(a)
    if a.window < 1:
        raise ParameterError("--window", f"must be >= 1 (got {a.window})")
    with graph_node("topic_hz") as (node, ex):
        type_name, qos = wait_for_type(node, ex, topic, a.timeout)
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

