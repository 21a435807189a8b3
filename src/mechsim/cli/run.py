"""`mechsim run`."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from mechsim.cli.common import print_summary, progress_bar, say
from mechsim.ros.process import stop_on_sigterm


def cmd_run(a: argparse.Namespace) -> int:
    stop_on_sigterm()  # from here on, a stop completes whatever files exist
    from mechsim.cli.common import check_duration, check_rate
    from mechsim.errors import ParameterError
    from mechsim.scene import scene_from_target

    scene = scene_from_target(a.target, a.set, a.name)
    if a.rate is not None:
        scene.publish_rate = check_rate(a.rate)
    duration = check_duration(a.duration) if a.duration is not None else scene.duration
    bag = a.bag or scene.bag
    rrd = a.rrd or scene.rrd
    if a.processes:
        if a.bag:
            raise ParameterError("--bag", "not available with --processes (record in-process)")
        if a.rrd:
            raise ParameterError("--rrd", "not available with --processes (record in-process)")
        from mechsim.ros.launch import run_processes
        if scene.bag or scene.rrd:
            say("the scene's outputs (bag, rrd) are recorded in-process only; not with "
                "--processes (use `mechsim record`)")
        say(f"{len(scene.systems)} simulator processes and a diagnostics process "
            "(Ctrl-C stops them)")
        return run_processes(a.target, scene, a.set, duration, rate=a.rate, fast=a.fast,
                             name=a.name)
    from mechsim.ros.launch import run_scene

    fast = True if a.fast else None
    show = progress_bar(sys.stderr.isatty() and duration is not None)
    pace = "as fast as possible" if (fast or scene.pacing == "fast") else "real time"
    say(f"running scene {scene.name!r} ({len(scene.systems)} systems, {pace}"
        f"{f', {duration:g} s' if duration else ', until Ctrl-C'})")
    lines: list[str] = []
    if bag is not None or rrd is not None:
        from mechsim.ros.record import run_with_outputs
        run, lines = run_with_outputs(scene, fast=fast, duration=duration, bag=bag, rrd=rrd,
                                      progress=show)
    else:
        run = run_scene(scene, fast=fast, duration=duration, progress=show)
    print_summary(run)
    for line in lines:
        print(f"  outputs: {line}")
    return 1 if run.failures else 0


def add_parser(sub: Any) -> None:
    r = sub.add_parser("run", help="run a scene file or a single system")
    r.add_argument("target", help="scene YAML file or system id")
    r.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="parameter override; INSTANCE:NAME=VALUE for one instance")
    r.add_argument("--name", metavar="NS", help="instance name (ROS namespace) of a single "
                   "SYSTEM (default: the system id)")
    r.add_argument("--duration", type=float, help="simulated seconds")
    r.add_argument("--fast", action="store_true", help="as fast as possible")
    r.add_argument("--rate", type=float, help="publish rate [Hz of simulation time]")
    r.add_argument("--processes", action="store_true", help="one process per node")
    r.add_argument("--bag", metavar="DIR", help="also record every message to a new rosbag2 "
                   "bag (strftime fields expanded)")
    r.add_argument("--rrd", metavar="FILE", help="also write a Rerun recording (.rrd)")
    r.set_defaults(func=cmd_run)
