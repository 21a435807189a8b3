"""`mechsim run`."""

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
from mechsim.outputs.rerun_live import DEFAULT_CONNECT
from mechsim.runcore.stops import stop_on_sigterm


def cmd_run(a: argparse.Namespace) -> int:
    stop_on_sigterm()  # from here on, a stop completes whatever files exist
    hand_over(a)  # --ros-args: checked by rcl, for every context this command starts
    from mechsim.cli.common import check_outputs, scene_of
    from mechsim.ros.graph_check import discovery_window

    discovery_window()  # a bad MECHSIM_GRAPH_WAIT is refused before anything starts
    scene = scene_of(a, fast=a.fast)
    bag = a.bag or scene.bag
    rrd = a.rrd or scene.rrd
    rrd = check_outputs(scene, bag, rrd)
    if a.only is not None:  # one node of the scene, e.g. one per host
        return _only(a, scene, bag, rrd)
    if a.processes:
        return _processes(a, scene, bag, rrd)
    return _in_process(a, scene, bag, rrd)


def _check_only(a: argparse.Namespace, names: list[str], bag: str | None,
                rrd: str | None) -> None:
    from mechsim.errors import ParameterError

    if a.lossless:
        raise ParameterError("--lossless", "not with --only (a lone simulator waits for "
                             "its recorder with --wait-for recorder)")
    if a.only not in ("diagnostics", "recorder") and a.only not in names:
        raise ParameterError("--only", f"no instance {a.only!r} in the scene (instances: "
                             f"{', '.join(names)}; or diagnostics, recorder)")
    for flag, given in (("--processes", a.processes), ("--viewer", a.viewer),
                        ("--connect", a.connect)):
        if given:
            raise ParameterError(flag, "not available with --only")
    if a.only == "recorder" and a.only not in names:
        if bag is None and rrd is None:
            raise ParameterError("--only", "recorder needs --bag and/or --rrd")
        return
    for flag, given in (("--bag", a.bag), ("--rrd", a.rrd)):
        if given:
            raise ParameterError(flag, "only with --only recorder")
    if a.wait_for and a.only == "diagnostics":
        raise ParameterError("--wait-for", "only for a simulator")


def _only(a: argparse.Namespace, scene: Any, bag: str | None, rrd: str | None) -> int:
    """One node of the scene in this process: the same function as a node process of
    ``--processes`` runs."""
    names = [i.name for i in scene.systems]
    _check_only(a, names, bag, rrd)
    from mechsim.environment import import_rclpy

    import_rclpy()  # the ROS environment set before the nodes import rclpy
    if a.only == "recorder" and a.only not in names:
        from mechsim.ros.recorder import run_recorder

        say(f"recording scene {scene.name!r} from the graph (Ctrl-C stops and completes "
            "the outputs)")
        for line in run_recorder(scene, bag, rrd):
            print(f"  outputs: {line}")
        return 0
    from mechsim.ros.processes import diagnostics_process, simulator_process

    say(f"running {'the diagnostics node' if a.only == 'diagnostics' else a.only} of "
        f"scene {scene.name!r} (Ctrl-C stops it)")
    if a.only == "diagnostics":
        return diagnostics_process(scene)
    waits = a.wait_for or []
    return simulator_process(scene, a.only, readers=len(set(waits)),
                             recorder="recorder" in waits)


def _processes(a: argparse.Namespace, scene: Any, bag: str | None, rrd: str | None) -> int:
    """One process per node."""
    from mechsim.errors import ParameterError

    for flag, given in (("--viewer", a.viewer), ("--connect", a.connect),
                        ("--lossless", a.lossless)):
        if given:
            raise ParameterError(flag, "not available with --processes (view in-process)")
    from mechsim.ros.processes import run_processes

    consumers = "a diagnostics process" + (" and a recorder process"
                                           if bag is not None or rrd is not None else "")
    say(f"{counted(len(scene.systems), 'simulator process')}, {consumers} (Ctrl-C stops "
        "them)")
    run, lines, status = run_processes(scene, bag=bag, rrd=rrd)
    if status == 2:  # a refused start: its process said why
        return status
    print_summary(run)
    for line in lines:
        print(f"  outputs: {line}")
    if run.interrupted:
        return 130  # stopped by Ctrl-C / SIGTERM: not a success (as every command)
    return status or (1 if run.failures else 0)


def _in_process(a: argparse.Namespace, scene: Any, bag: str | None, rrd: str | None) -> int:
    """Every node in this process, stepped by one loop."""
    from mechsim.ros.graph_check import join_graph
    from mechsim.ros.launch import run_scene

    duration = scene.duration
    fast = True if a.fast else None
    show = progress_bar(sys.stderr.isatty() and duration is not None)
    pace = "as fast as possible" if (fast or scene.pacing == "fast") else "real time"
    say(f"running scene {scene.name!r} ({counted(len(scene.systems), 'system')}, {pace}"
        f"{f', {duration:g} s' if duration else ', until Ctrl-C'})")
    lines: list[str] = []
    server, live = _live_view(a)
    try:
        join_graph()  # everything validated: discovery runs while the models load
        if bag is not None or rrd is not None or live is not None:
            from mechsim.ros.record import run_with_outputs
            run, lines = run_with_outputs(scene, fast=fast, duration=duration, bag=bag,
                                          rrd=rrd, live=live, progress=show,
                                          lossless=a.lossless)
        else:
            run = run_scene(scene, fast=fast, duration=duration, progress=show,
                            lossless=a.lossless)
        print_summary(run)
        for line in lines:
            print(f"  outputs: {line}")
        if server is not None and not run.interrupted:
            _keep_viewer(server)
    finally:
        if server is not None:
            server.stop()
    if run.interrupted:
        return 130
    return 1 if run.failures else 0


def _keep_viewer(server: Any) -> None:
    sys.stdout.flush()
    say(f"the run has ended; the live view stays at {server.web_url} until Ctrl-C")
    try:
        server.wait()
        say("Rerun's server has exited")
    except KeyboardInterrupt:
        pass  # the user has seen enough: the run's own result stands


def _live_view(a: argparse.Namespace) -> tuple[Any, str | None]:
    """(server, URL to stream to) for --viewer / --connect; (None, None) without either."""
    from mechsim.errors import ParameterError

    if a.viewer_port is not None and not a.viewer:
        raise ParameterError("--viewer-port", "only with --viewer")
    if a.viewer and a.connect:
        raise ParameterError("--connect", "not with --viewer (one live view)")
    if a.connect:
        from mechsim.outputs.rerun_live import check_url

        return None, check_url(a.connect)
    if not a.viewer:
        return None, None
    from mechsim.outputs.rerun_live import LiveViewer

    server = LiveViewer.start(a.viewer_port)
    say(f"live view: open {server.web_url} (on this machine; a native viewer: "
        f"`rerun --connect {server.grpc_url}`)")
    return server, server.grpc_url


def add_parser(sub: Any) -> None:
    r = sub.add_parser("run", help="run a scene file or a single system",
                       epilog=NODE_ENVIRONMENT)
    r.add_argument("target", help="scene YAML file or system id")
    add_scene_options(r, "run")
    r.add_argument("--duration", type=float, help="simulated seconds")
    r.add_argument("--fast", action="store_true", help="as fast as possible")
    r.add_argument("--processes", action="store_true", help="one process per node")
    r.add_argument("--lossless", action="store_true", help="every reliable subscriber gets "
                   "every sample: the run waits for the slowest one's acknowledgments "
                   "(default: a slow subscriber misses what its history cannot hold, as in "
                   "ROS)")
    r.add_argument("--only", metavar="NODE", help="run only this instance's simulator (or "
                   "`diagnostics`) of the scene: one node per host with the several-hosts "
                   "DDS profile; `recorder`: record the scene from the graph (--bag/--rrd)")
    r.add_argument("--wait-for", action="append", choices=["diagnostics", "recorder"],
                   help="with --only SIMULATOR: step only once these consumers subscribe "
                   "(nothing they would miss is sent before; repeatable)")
    r.add_argument("--bag", metavar="DIR", help="also record every message to a new rosbag2 "
                   "bag (strftime fields expanded)")
    r.add_argument("--rrd", metavar="FILE", help="also write a Rerun recording (.rrd; "
                   "strftime fields expanded)")
    r.add_argument("--viewer", action="store_true", help="serve Rerun's web viewer of the run "
                   "on 127.0.0.1 (this machine only) and print its URL; it shows the run live "
                   "with the .rrd's blueprint and stays up after the run ends until Ctrl-C "
                   "(Ctrl-C during the run stops both)")
    r.add_argument("--viewer-port", type=int, metavar="PORT", help="port of --viewer's web "
                   "page (default: a free port; a taken port is refused)")
    r.add_argument("--connect", nargs="?", const=DEFAULT_CONNECT, metavar="URL",
                   help="stream the run to a Rerun viewer already running (default URL: "
                   f"{DEFAULT_CONNECT}, where `rerun` listens); the viewer keeps it after "
                   "the run")
    add_ros_args(r)
    r.set_defaults(func=cmd_run)
