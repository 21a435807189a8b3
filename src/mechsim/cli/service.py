"""`mechsim service call NODE reset|pause true|false|step N` (like ``ros2 service call``)."""

from __future__ import annotations

import argparse
from typing import Any


def cmd_service_call(a: argparse.Namespace) -> int:
    from mechsim.ros.graph import call_service

    ok, message = call_service(a.node, a.service, a.value, timeout=a.timeout)
    text = message.encode("unicode_escape").decode("ascii")
    print(f"{a.service}: {'success' if ok else 'failed'}{f' ({text})' if text else ''}")
    return 0 if ok else 1


def add_parser(sub: Any) -> None:
    s = sub.add_parser("service", help="call a simulator node's services (like "
                       "`ros2 service call`)")
    ssub = s.add_subparsers(dest="service_command", required=True)
    c = ssub.add_parser("call", help="~/reset (std_srvs/Trigger), ~/pause "
                        "(std_srvs/SetBool, true|false) or ~/step (mechsim_msgs/Step, "
                        "samples: while paused)")
    c.add_argument("node", metavar="NODE", help="e.g. /pendulum/simulator")
    c.add_argument("service", choices=("reset", "pause", "step"))
    c.add_argument("value", nargs="?", metavar="true|false|N", help="for pause: true or "
                   "false; for step: the number of samples")
    c.add_argument("--timeout", type=float, default=5.0, metavar="S",
                   help="how long to wait for the service (default 5 s)")
    c.set_defaults(func=cmd_service_call)
