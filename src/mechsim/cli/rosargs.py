"""``--ros-args``: a verb that starts nodes takes the ROS arguments of any ROS 2 executable.

``mechsim run``, ``mechsim record`` and the node executables (``simulator``, ``diagnostics``,
``recorder``, ``swing_up_controller``) end their command line with ``--ros-args ...`` as any
ROS 2 program does: remappings (``-r __ns:=/demo``, ``-r __node:=name``, topic remaps),
parameters (``-p name:=value``, ``--params-file FILE``), ``--log-level``, and the rest of rcl's
arguments. They are not interpreted here: rcl parses them when the command's ROS context starts
(``rclpy.init(args=...)``), checked first (``rclpy.utilities.remove_ros_args``) so that a
malformed one is one error line before anything starts. A verb's own options go before
``--ros-args``.
"""

from __future__ import annotations

import argparse
from typing import Any


def add_ros_args(parser: argparse.ArgumentParser) -> None:
    """``--ros-args ...``: everything after it, for rcl."""
    parser.add_argument("--ros-args", nargs=argparse.REMAINDER, metavar="ARG",
                        dest="ros_args", help="ROS arguments, to the end of the command line "
                        "(-r remaps, -p name:=value, --params-file FILE, --log-level LEVEL), "
                        "as any ROS 2 executable takes them")


def hand_over(a: Any) -> None:
    """The command line's ROS arguments (none without ``--ros-args``) become the ones every
    ROS context of this command starts with (``mechsim.ros.graph_check.start_context``);
    ParameterError if rcl cannot parse them."""
    from mechsim.ros.graph_check import use_ros_arguments

    given = getattr(a, "ros_args", None)
    use_ros_arguments([] if given is None else ["--ros-args", *given])
