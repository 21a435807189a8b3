"""`mechsim replay`."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from mechsim.errors import ParameterError, counted
from mechsim.ros.replay import check_topics, replay


def cmd_replay(a: argparse.Namespace) -> int:
    if not (a.rate >= 0 and a.rate < float("inf")):
        raise ParameterError("--rate", f"must be >= 0 (0: as fast as possible; got {a.rate!r})")
    if not (a.delay >= 0 and a.delay < 3600):
        raise ParameterError("--delay", f"must be between 0 and 3600 s (got {a.delay!r})")
    from mechsim.outputs.bag import check_bag, topic_qos

    meta = check_bag(Path(a.bag))  # a bad bag fails here, before ROS starts
    check_topics(Path(a.bag), topic_qos(meta), a.topics)
    pace = "as fast as possible" if a.rate == 0 else f"at {a.rate:g}x"
    print(f"mechsim: replaying {a.bag} ({meta['message_count']} messages, "
          f"{meta['duration']['nanoseconds'] / 1e9:g} s) {pace}"
          f"{', looping' if a.loop else ''}", file=sys.stderr)
    s = replay(a.bag, rate=a.rate, loop=a.loop, topics=a.topics or None, delay=a.delay)
    print(f"mechsim: replayed {counted(s.messages, 'message')} on "
          f"{counted(len(s.per_topic), 'topic')} "
          f"({s.loops} pass{'es' if s.loops != 1 else ''}, {s.clock} /clock ticks) "
          f"in {s.wall:.2f} s", file=sys.stderr)
    return 0


def add_parser(sub: Any) -> None:
    r = sub.add_parser("replay", help="republish a recorded bag (with /clock)")
    r.add_argument("bag", metavar="DIR")
    r.add_argument("--rate", type=float, default=1.0,
                   help="speed factor (default 1; 0 = as fast as possible)")
    r.add_argument("--loop", action="store_true", help="start over at the end, until Ctrl-C")
    r.add_argument("--topics", nargs="+", metavar="TOPIC", help="only these topics")
    r.add_argument("--delay", type=float, default=0.5,
                   help="wall seconds to wait for discovery before the first message")
    r.set_defaults(func=cmd_replay)

