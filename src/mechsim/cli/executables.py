"""The node executables: ``mechsim simulator``, ``mechsim diagnostics``, ``mechsim recorder``,
``mechsim swing_up_controller``: verbs not listed by ``--help``, and the package's
executables under ``lib/mechsim`` (``ros2 run mechsim simulator``, launch_ros ``Node``
actions; the functions :func:`simulator`, :func:`diagnostics`, :func:`recorder` and
:func:`swing_up_controller` start a process as that node: ``simulator ARGS`` is ``mechsim
simulator ARGS``).

Two ways to start one: with ``--scene FILE``, one node of a scene its parent parsed, as data
(written by ``scene.scene_data``: the processes ``mechsim run --processes`` starts, never the
parent's command line to parse again; ``mechsim.ros.processes``); without it, the node alone,
configured by its ROS parameters (``mechsim.ros.standalone``). Either way the command line
may end with ``--ros-args ...`` (``cli.rosargs``: remaps, parameters, params files, log level,
parsed by rcl), and goes through the command's one entry point (same exit statuses, same
one-line errors).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any


def _common(a: argparse.Namespace) -> Any:
    """Stops handled from here on, the parent watched, the ROS arguments handed over, the
    scene read (None: the node alone)."""
    from mechsim.cli.rosargs import hand_over
    from mechsim.runcore.stops import die_with_parent, stop_on_sigterm

    stop_on_sigterm()
    if a.parent is not None:
        die_with_parent(a.parent)
    hand_over(a)
    if a.scene is None:
        return None
    from mechsim.ros.processes import read_scene

    return read_scene(a.scene)


def cmd_simulator(a: argparse.Namespace) -> int:
    from mechsim.errors import ParameterError

    if (a.scene is None) != (a.instance is None):
        raise ParameterError("--instance", "with --scene, and only then (alone, the "
                             "simulator is configured by its ROS parameters)")
    scene = _common(a)
    if scene is None:
        from mechsim.ros.standalone import simulator_alone

        return simulator_alone()
    from mechsim.ros.processes import simulator_process

    return simulator_process(scene, a.instance, readers=a.await_readers,
                             recorder=a.await_recorder, report=a.report)


def cmd_diagnostics(a: argparse.Namespace) -> int:
    scene = _common(a)
    from mechsim.ros.processes import diagnostics_process

    return diagnostics_process(scene, a.report)


def cmd_swing_up_controller(a: argparse.Namespace) -> int:
    _common(a)
    from mechsim.ros.swing_up import controller_alone

    return controller_alone()


def cmd_recorder(a: argparse.Namespace) -> int:
    scene = _common(a)
    from mechsim.errors import ParameterError

    if scene is None:
        from mechsim.ros.standalone import recorder_alone

        return recorder_alone(a.report)
    if scene.bag is None and scene.rrd is None:
        raise ParameterError("--scene", "the scene names no output (outputs.bag, outputs.rrd)")
    from mechsim.environment import import_rclpy

    import_rclpy()  # the ROS environment set before the recorder imports rclpy
    from mechsim.ros.recorder import run_recorder

    run_recorder(scene, scene.bag, scene.rrd, a.report)
    return 0


#: The function of each node verb (``cli.NODE_VERBS``).
COMMANDS = {"simulator": cmd_simulator, "diagnostics": cmd_diagnostics,
            "recorder": cmd_recorder, "swing_up_controller": cmd_swing_up_controller}


def add_parsers(sub: Any) -> None:
    """The node verbs (no ``help``: unlisted)."""
    from mechsim.cli import NODE_VERBS
    from mechsim.cli.rosargs import add_ros_args

    for kind in NODE_VERBS:
        func = COMMANDS[kind]
        p = sub.add_parser(kind, description=f"The {kind} node, in this process: alone, "
                           "configured by its ROS parameters (`ros2 run mechsim "
                           f"{kind} --ros-args -p NAME:=VALUE`), or one node of a scene "
                           "(--scene: what `mechsim run --processes` starts).")
        p.add_argument("--scene", metavar="FILE",
                       help="the scene as data (JSON), as its parent parsed it")
        p.add_argument("--report", metavar="FILE", help="JSON file of what this process did, "
                       "for the parent")
        p.add_argument("--parent", type=int, metavar="PID", help="die with this process")
        if kind == "simulator":
            p.add_argument("--instance", metavar="NAME",
                           help="which instance of the scene (with --scene)")
            p.add_argument("--await-readers", type=int, default=0, metavar="N",
                           help="step once N consumers subscribe")
            p.add_argument("--await-recorder", action="store_true",
                           help="and once a recorder subscribes to every topic")
        add_ros_args(p)
        p.set_defaults(func=func)


def _as(kind: str) -> None:
    from mechsim.cli import entry

    entry([kind, *sys.argv[1:]])


def simulator() -> None:
    """A process that is the simulator node: ``mechsim simulator`` with this command line."""
    _as("simulator")


def diagnostics() -> None:
    """A process that is the diagnostics node: ``mechsim diagnostics``."""
    _as("diagnostics")


def recorder() -> None:
    """A process that is the recorder node: ``mechsim recorder``."""
    _as("recorder")


def swing_up_controller() -> None:
    """A process that is the swing-up controller node: ``mechsim swing_up_controller``."""
    _as("swing_up_controller")
