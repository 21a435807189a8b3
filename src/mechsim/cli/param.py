"""`mechsim param list|get|set`: a node's ROS parameters (like ``ros2 param``)."""

from __future__ import annotations

import argparse
import json
from typing import Any


def _show(value: Any) -> str:
    """A value as one printable line (control characters from the graph escaped)."""
    text = json.dumps(value, ensure_ascii=True) if isinstance(value, str) else repr(value)
    return text.encode("unicode_escape").decode("ascii") if not text.isprintable() else text


def cmd_param_list(a: argparse.Namespace) -> int:
    from mechsim.ros.graph import list_parameters

    for p in list_parameters(a.node, timeout=a.timeout):
        ro = "  (read-only)" if p.read_only else ""
        desc = f"  # {_show(p.description)[1:-1]}" if p.description and a.describe else ""
        print(f"  {p.name}: {_show(p.value)}{ro}{desc}")
    return 0


def cmd_param_get(a: argparse.Namespace) -> int:
    from mechsim.ros.graph import get_parameter

    print(_show(get_parameter(a.node, a.name, timeout=a.timeout)))
    return 0


def cmd_param_set(a: argparse.Namespace) -> int:
    from mechsim.ros.graph import set_parameter

    value = set_parameter(a.node, a.name, a.value, timeout=a.timeout)
    print(f"Set parameter successful: {a.name} = {_show(value)}")
    return 0


def add_parser(sub: Any) -> None:
    p = sub.add_parser("param", help="list, get and set a node's ROS parameters "
                       "(like `ros2 param`)")
    psub = p.add_subparsers(dest="param_command", required=True)
    lst = psub.add_parser("list", help="every parameter of NODE with its value")
    lst.add_argument("node", metavar="NODE", help="e.g. /pendulum/simulator")
    lst.add_argument("--describe", action="store_true", help="also print descriptions")
    lst.set_defaults(func=cmd_param_list)
    get = psub.add_parser("get", help="one parameter's value")
    get.add_argument("node", metavar="NODE")
    get.add_argument("name", metavar="NAME")
    get.set_defaults(func=cmd_param_get)
    st = psub.add_parser("set", help="set one parameter (the node validates it; a rejected "
                         "value is one error line with the node's reason and exit status 2, "
                         "where `ros2 param set` prints the failure and exits 0)")
    st.add_argument("node", metavar="NODE")
    st.add_argument("name", metavar="NAME")
    st.add_argument("value", metavar="VALUE", help="YAML scalar: 2.5, true, dop853")
    st.set_defaults(func=cmd_param_set)
    for q in (lst, get, st):
        q.add_argument("--timeout", type=float, default=5.0, metavar="S",
                       help="how long to wait for the node (default 5 s)")
