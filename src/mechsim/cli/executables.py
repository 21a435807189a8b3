"""The node executables: ``mechsim simulator``, ``mechsim diagnostics``, ``mechsim recorder``.

Verbs not listed by ``--help``: the processes ``mechsim run --processes`` starts, one per node,
each given the scene the parent parsed, as data (``--scene FILE``, written by
``scene.scene_data``), never the parent's command line to parse again. Each verb is one
function of its node kind (``mechsim.ros.processes``, ``mechsim.ros.recorder``) and goes
through the command's one entry point (same exit statuses, same one-line errors). The
functions :func:`simulator`, :func:`diagnostics` and :func:`recorder` start a process as that
node directly (``simulator ARGS`` is ``mechsim simulator ARGS``).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any


def _common(a: argparse.Namespace) -> Any:
    """Stops handled from here on, the parent watched, the scene read."""
    from mechsim.runcore.stops import die_with_parent, stop_on_sigterm

    stop_on_sigterm()
    if a.parent is not None:
        die_with_parent(a.parent)
    from mechsim.ros.processes import read_scene

    return read_scene(a.scene)


def cmd_simulator(a: argparse.Namespace) -> int:
    scene = _common(a)
    from mechsim.ros.processes import simulator_process

    return simulator_process(scene, a.instance, readers=a.await_readers,
                             recorder=a.await_recorder, report=a.report)


def cmd_diagnostics(a: argparse.Namespace) -> int:
    scene = _common(a)
    from mechsim.ros.processes import diagnostics_process

    return diagnostics_process(scene, a.report)


def cmd_recorder(a: argparse.Namespace) -> int:
    scene = _common(a)
    from mechsim.errors import ParameterError

    if scene.bag is None and scene.rrd is None:
        raise ParameterError("--scene", "the scene names no output (outputs.bag, outputs.rrd)")
    from mechsim.environment import import_rclpy

    import_rclpy()  # the ROS environment set before the recorder imports rclpy
    from mechsim.ros.recorder import run_recorder

    run_recorder(scene, scene.bag, scene.rrd, a.report)
    return 0


def add_parsers(sub: Any) -> None:
    """The three node verbs (no ``help``: unlisted)."""
    from mechsim.cli import NODE_VERBS

    commands = {"simulator": cmd_simulator, "diagnostics": cmd_diagnostics,
                "recorder": cmd_recorder}
    for kind in NODE_VERBS:
        func = commands[kind]
        p = sub.add_parser(kind, description=f"The {kind} node of a scene, in this process "
                           "(what `mechsim run --processes` starts).")
        p.add_argument("--scene", required=True, metavar="FILE",
                       help="the scene as data (JSON), as its parent parsed it")
        p.add_argument("--report", metavar="FILE", help="JSON file of what this process did, "
                       "for the parent")
        p.add_argument("--parent", type=int, metavar="PID", help="die with this process")
        if kind == "simulator":
            p.add_argument("--instance", required=True, metavar="NAME",
                           help="which instance of the scene")
            p.add_argument("--await-readers", type=int, default=0, metavar="N",
                           help="step once N consumers subscribe")
            p.add_argument("--await-recorder", action="store_true",
                           help="and once a recorder subscribes to every topic")
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
