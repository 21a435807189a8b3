"""`mechsim node list`: the nodes of the live graph (like ``ros2 node list``)."""

from __future__ import annotations

import argparse
from typing import Any


def cmd_node_list(a: argparse.Namespace) -> int:
    from mechsim.ros.graph import node_names

    for name in node_names(wait=a.wait, all_nodes=a.all):
        print(name.encode("unicode_escape").decode("ascii"))
    return 0


def add_parser(sub: Any) -> None:
    n = sub.add_parser("node", help="nodes of the live graph (like `ros2 node`)")
    nsub = n.add_subparsers(dest="node_command", required=True)
    lst = nsub.add_parser("list", help="every node seen after a short discovery wait")
    lst.add_argument("--wait", type=float, default=1.0, metavar="S",
                     help="discovery wait in seconds (default 1)")
    lst.add_argument("-a", "--all", action="store_true", help="also the hidden nodes (a name "
                     "starting with _, such as the ros2 command's own)")
    lst.set_defaults(func=cmd_node_list)
