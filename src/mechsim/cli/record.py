"""`mechsim record`."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from mechsim.cli.common import (
    NODE_ENVIRONMENT,
    add_scene_options,
    print_summary,
    progress_bar,
    say,
)
from mechsim.cli.rosargs import add_ros_args, hand_over
from mechsim.errors import counted
from mechsim.ros.record import DEFAULT_BAG
from mechsim.runcore.stops import stop_on_sigterm

#: Exit status of a recording stopped by Ctrl-C / SIGTERM (128 + SIGINT, as shells report).
EXIT_INTERRUPTED = 130


def cmd_record(a: argparse.Namespace) -> int:
    stop_on_sigterm()  # from here on, a stop completes whatever files exist
    hand_over(a)  # --ros-args: checked by rcl, for every context this command starts
    from mechsim.cli.common import check_outputs, scene_of
    from mechsim.errors import ParameterError
    from mechsim.ros.graph_check import discovery_window, join_graph
    from mechsim.ros.record import run_with_outputs

    discovery_window()  # a bad MECHSIM_GRAPH_WAIT is refused before anything starts
    scene = scene_of(a, fast=True)
    if scene.duration is None:
        raise ParameterError("--duration", "required (the scene sets no duration and a "
                             "recording runs as fast as possible)")
    bag = a.bag or scene.bag or DEFAULT_BAG
    rrd = a.rrd or scene.rrd
    rrd = check_outputs(scene, bag, rrd)  # a bad path is refused before anything starts
    show = progress_bar(sys.stderr.isatty())
    say(f"recording scene {scene.name!r} ({counted(len(scene.systems), 'system')}, "
        f"{scene.duration:g} s simulated, as fast as possible)")
    join_graph()  # everything validated: discovery runs while the models load
    run, lines = run_with_outputs(scene, fast=True, duration=scene.duration, bag=bag, rrd=rrd,
                                  progress=show, lossless=a.lossless)
    if run.interrupted:
        say(f"interrupted at t = {run.sim_time:g} s; outputs completed up to there")
    print_summary(run)
    for line in lines:
        print(f"  {line}")
    if run.interrupted:
        return EXIT_INTERRUPTED
    return 1 if run.failures else 0


def add_parser(sub: Any) -> None:
    r = sub.add_parser("record", help="run a scene as fast as possible and record every "
                       "message to a rosbag2 (MCAP) bag", epilog=NODE_ENVIRONMENT)
    r.add_argument("target", help="scene YAML file or system id")
    r.add_argument("--duration", type=float, help="simulated seconds (default: the scene's)")
    add_scene_options(r, "record")
    r.add_argument("--bag", metavar="DIR", help="new bag directory (strftime fields expanded; "
                   f"default: scene outputs.bag, else {DEFAULT_BAG.replace('%', '%%')})")
    r.add_argument("--rrd", metavar="FILE", help="also write a Rerun recording (strftime "
                   "fields expanded)")
    r.add_argument("--lossless", action="store_true", help="live reliable subscribers get "
                   "every sample too (the run waits for the slowest one's acknowledgments)")
    add_ros_args(r)
    r.set_defaults(func=cmd_record)
