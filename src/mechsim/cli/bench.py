"""`mechsim bench`."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from mechsim.cli.common import add_force, refuse_existing


def add_parser(sub: Any) -> None:
    b = sub.add_parser("bench", help="work-precision benchmark against scipy, REBOUND, MuJoCo, "
                       "Drake; or the cost of a scene's outputs (--scene)")
    b.add_argument("systems", nargs="*", metavar="PROBLEM",
                   help="benchmark problems (default: all; an unknown name lists them)")
    b.add_argument("--quick", action="store_true",
                   help="tiny horizons, 3 tolerances, scipy and hand-written peers (for CI)")
    b.add_argument("--out", required=True, metavar="DIR",
                   help="directory for results.json, results.md and PNGs")
    b.add_argument("--repeats", type=int, default=3, help="timed runs per point (median)")
    b.add_argument("--budget", type=float, help="seconds per run before a sweep stops")
    b.add_argument("--peers", help="comma-separated peer families to use (default: all)")
    b.add_argument("--no-cold", action="store_true",
                   help="skip the compile-time measurement in a fresh process")
    b.add_argument("--no-plots", action="store_true")
    b.add_argument("--scene", metavar="SCENE",
                   help="measure a scene with all outputs consumed vs state only")
    b.add_argument("--duration", type=float, help="simulated seconds for --scene")
    b.add_argument("--streaming", action="store_true",
                   help="real-time factor of each system recording at 100 Hz, of live "
                   "consumers of the per-sample and batch topics in another process beside "
                   "rclpy's ceiling, start-up of scenes of many instances, and the CPU share "
                   "of all systems streaming in real time (streaming.md, streaming.json)")
    b.add_argument("--throughput", action="store_true",
                   help="what one simulate() call costs beyond its steps, and ensembles "
                   "(simulate_many) against a loop of simulate, of scipy's solve_ivp and a "
                   "hand-written numba prange loop (throughput.md, throughput.json)")
    b.add_argument("--members", type=int, default=10_000,
                   help="ensemble members for --throughput (default 10000)")
    b.add_argument("--brouwer", action="store_true",
                   help="Brouwer's law: radau15's energy error against the number of steps "
                   "on perturbed Kepler orbits (brouwer.png, brouwer.json)")
    b.add_argument("--derive", action="store_true",
                   help="CPU of deriving and compiling each system (PROBLEM: system ids; "
                   "default all) in new processes against a warm start (derive.md, "
                   "derive.json)")
    b.add_argument("--steps", type=int, default=10_000_000,
                   help="steps per run for --brouwer (default 10^7)")
    b.add_argument("--runs", type=int, default=16, help="perturbed runs for --brouwer")
    add_force(b, "replace the files this command writes in --out (other files there are "
              "kept); without it an existing one is refused before anything runs")
    b.set_defaults(func=cmd_bench)


def cmd_bench(a: argparse.Namespace) -> int:
    from mechsim.errors import ParameterError

    out = Path(a.out)
    if a.brouwer:
        return _brouwer(a, out)
    if a.derive:
        from mechsim.bench.derive import run_derive
        from mechsim.systems import system_ids

        for s in a.systems:
            if s not in system_ids():
                raise ParameterError("PROBLEM", f"--derive: no system {s!r} (have: "
                                     f"{', '.join(system_ids())})")
        refuse_existing(a.out, ["derive.json", "derive.md"], a.force)
        run_derive(out, list(a.systems))
        return 0
    if a.throughput:
        return _throughput(a, out)
    if a.streaming:
        from mechsim.bench.streaming import run_streaming

        refuse_existing(a.out, ["streaming.json", "streaming.md"], a.force)
        run_streaming(out, list(a.systems), duration=a.duration or 1000.0)
        return 0
    if a.scene:
        if a.systems:
            raise ParameterError("--scene", "takes no PROBLEM arguments")
        from mechsim.bench.scene_cost import run_scene_cost

        refuse_existing(a.out, ["scene_cost.json", "scene_cost.md"], a.force)
        run_scene_cost(a.scene, out, duration=a.duration)
        return 0
    from mechsim.bench.run import known_systems, run_bench

    known = known_systems()
    systems = a.systems or known
    for s in systems:
        if s not in known:
            raise ParameterError("PROBLEM", f"no benchmark problem for {s!r} (have: "
                                 f"{', '.join(known)})")
    if a.repeats < 1:
        raise ParameterError("--repeats", "must be at least 1")
    families = tuple(a.peers.split(",")) if a.peers else None
    refuse_existing(a.out, ["results.json", "results.md",
                            *([] if a.no_plots else [f"{s}.png" for s in systems])], a.force)
    run_bench(systems, out, quick=a.quick, repeats=a.repeats, budget_s=a.budget,
              families=families, cold=False if a.no_cold else None, plots=not a.no_plots)
    return 0



def _brouwer(a: argparse.Namespace, out: Path) -> int:
    from mechsim.bench.brouwer import run_brouwer
    from mechsim.errors import ParameterError

    if a.systems:
        raise ParameterError("--brouwer", "takes no PROBLEM arguments")
    if a.steps < 10_000:
        raise ParameterError("--steps", f"must be at least 10000 (got {a.steps})")
    if a.runs < 2:
        raise ParameterError("--runs", f"must be at least 2 (got {a.runs})")
    refuse_existing(a.out, ["brouwer.json", "brouwer.png"], a.force)
    run_brouwer(out, n_steps=a.steps, runs=a.runs)
    return 0


def _throughput(a: argparse.Namespace, out: Path) -> int:
    from mechsim.bench.throughput import run_throughput
    from mechsim.errors import ParameterError

    if a.systems:
        raise ParameterError("--throughput", "takes no PROBLEM arguments")
    if a.members < 100:
        raise ParameterError("--members", f"must be at least 100 (got {a.members})")
    refuse_existing(a.out, ["throughput.json", "throughput.md"], a.force)
    run_throughput(out, members=a.members)
    return 0
