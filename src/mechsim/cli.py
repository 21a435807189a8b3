"""The ``mechsim`` command. Every user error is one line on stderr and exit status 2."""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path
from typing import Any

from mechsim.errors import MechsimError

EXIT_USAGE = 2


def _progress(enabled: bool) -> Any:
    """A one-line progress bar on a terminal; nothing otherwise."""
    if not enabled:
        return None
    state = {"last": -1}

    def show(t: float, total: float) -> None:
        pct = int(100 * t / total) if total > 0 else 100
        if pct != state["last"]:
            state["last"] = pct
            bar = "#" * (pct // 4) + "." * (25 - pct // 4)
            sys.stderr.write(f"\r[{bar}] {pct:3d}%  t = {t:8.3f} / {total:g} s")
            if pct >= 100:
                sys.stderr.write("\n")
            sys.stderr.flush()
    return show


def _scene_from(target: str, sets: list[str]) -> Any:
    from mechsim.ros.launch import apply_overrides
    from mechsim.scene import load_scene, single_system_scene
    from mechsim.systems import system_ids

    if target.endswith((".yaml", ".yml")) or Path(target).is_file():
        scene = load_scene(target)
    elif target in system_ids():
        scene = single_system_scene(target)
    else:
        from mechsim.errors import UnknownSystemError
        raise UnknownSystemError(target, system_ids())
    apply_overrides(scene, sets)
    return scene


def print_summary(run: Any) -> None:
    from mechsim.ros.diagnostics import LEVEL_NAMES

    print(f"\nConservation results ({run.scene.name}: {run.sim_time:g} s simulated in "
          f"{run.wall_time:.2f} s wall after {run.startup_time:.2f} s start-up):")
    rows = sorted(run.summary)
    w1 = max([len("system")] + [len(r[0]) for r in rows])
    w2 = max([len("law")] + [len(r[1]) for r in rows])
    print(f"  {'system':<{w1}}  {'law':<{w2}}  {'max relative drift':>18}  level")
    for system, law, drift, level in rows:
        print(f"  {system:<{w1}}  {law:<{w2}}  {drift:>18.3e}  {LEVEL_NAMES[level]}")
    for name, reason in run.failures.items():
        print(f"  {name}: integration stopped: {reason}")


def cmd_systems(a: argparse.Namespace) -> int:
    from mechsim.systems import system_class, system_ids

    described = []
    for sid in system_ids():
        cls = system_class(sid)
        model = cls()
        d = model.describe()
        d["oracles"] = cls.oracles
        described.append(d)
    if a.json:
        print(json.dumps(described, indent=2, ensure_ascii=False))
        return 0
    for d in described:
        coords = ", ".join(f"{c['name']} [{c['unit']}]" for c in d["coordinates"])
        print(f"{d['id']}: {d['title']}\n  source: {d['source']}\n  coordinates: {coords}")
        if len(d["formulations"]) > 1:
            print(f"  formulations: {', '.join(d['formulations'])}")
        print(f"  laws: {', '.join(d['laws'])}")
        for p in d["parameters"]:
            unit = f" [{p['unit']}]" if p["unit"] else ""
            print(f"    {p['name']} = {p['default']!r}{unit}  {p['description']}")
    return 0


def cmd_run(a: argparse.Namespace) -> int:
    scene = _scene_from(a.target, a.set)
    if a.rate is not None:
        from mechsim.scene import _number
        scene.publish_rate = _number("--rate", a.rate)
    bag = a.bag or scene.bag
    rrd = a.rrd or scene.rrd
    if a.processes:
        if a.bag:
            from mechsim.errors import ParameterError
            raise ParameterError("--bag", "not available with --processes (record in-process)")
        if a.rrd:
            from mechsim.errors import ParameterError
            raise ParameterError("--rrd", "not available with --processes (record in-process)")
        from mechsim.ros.launch import run_processes
        if scene.bag or scene.rrd:
            print("mechsim: the scene's outputs (bag, rrd) are recorded in-process only; "
                  "not with --processes (use `mechsim record`)", file=sys.stderr)
        print(f"mechsim: {len(scene.systems)} simulator processes and a diagnostics process "
              "(Ctrl-C stops them)", file=sys.stderr)
        return run_processes(Path(a.target), scene, a.set, a.duration or scene.duration)
    from mechsim.ros.launch import run_scene

    duration = a.duration if a.duration is not None else scene.duration
    fast = True if a.fast else None
    show = _progress(sys.stderr.isatty() and duration is not None)
    print(f"mechsim: running scene {scene.name!r} ({len(scene.systems)} systems, "
          f"{'as fast as possible' if (fast or scene.pacing == 'fast') else 'real time'}"
          f"{f', {duration:g} s' if duration else ', until Ctrl-C'})", file=sys.stderr)
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


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="mechsim", description="Simulated classical mechanics "
                                 "streamed as ROS 2 topics.")
    sub = ap.add_subparsers(dest="command", required=True)
    s = sub.add_parser("systems", help="list systems, parameters, coordinates and sources")
    s.add_argument("--json", action="store_true")
    s.set_defaults(func=cmd_systems)
    r = sub.add_parser("run", help="run a scene file or a single system")
    r.add_argument("target", help="scene YAML file or system id")
    r.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                   help="parameter override; INSTANCE:NAME=VALUE for one instance")
    r.add_argument("--duration", type=float, help="simulated seconds")
    r.add_argument("--fast", action="store_true", help="as fast as possible")
    r.add_argument("--rate", type=float, help="publish rate [Hz of simulation time]")
    r.add_argument("--processes", action="store_true", help="one process per node")
    r.add_argument("--bag", metavar="DIR", help="also record every message to a new rosbag2 "
                   "bag (strftime fields expanded)")
    r.add_argument("--rrd", metavar="FILE", help="also write a Rerun recording (.rrd)")
    r.set_defaults(func=cmd_run)
    from mechsim.ros import record, replay, topic_tools  # parsers only; ROS imported lazily
    record.add_parser(sub)
    record.add_bag_parser(sub)
    replay.add_parser(sub)
    topic_tools.add_parser(sub)
    from mechsim.bench import add_parser as add_bench_parser  # registers only; lazy imports
    add_bench_parser(sub)
    from mechsim.stress import add_parser as add_stress_parser  # registers only; lazy
    add_stress_parser(sub)
    from mechsim import rerun_log  # parsers only; Rerun imported lazily
    rerun_log.add_parsers(sub)
    return ap


def main(argv: list[str] | None = None) -> int:
    ap = build_parser()
    a = ap.parse_args(argv)
    try:
        return int(a.func(a))
    except MechsimError as e:
        print(f"mechsim: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # Output piped into `head` and the like: stop quietly, as command-line tools do.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except RuntimeError as e:  # RosEnvironmentError and rclpy start-up failures
        print(f"mechsim: error: {str(e).splitlines()[0] if str(e) else type(e).__name__}",
              file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
