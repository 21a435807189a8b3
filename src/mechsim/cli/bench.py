"""`mechsim bench`."""

from __future__ import annotations

import argparse
from collections.abc import Callable
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
    b.add_argument("--all", action="store_true",
                   help="every report in one run, in the order of docs/results.md: the long "
                   "problems (--budget 2, no cold start) and the short ones (DIR/short), "
                   "--streaming, --throughput, --derive, --scene scenes/pendulum.yaml and "
                   "--brouwer; each page records its own date, machine and load")
    add_force(b, "replace the files this command writes in --out (other files there are "
              "kept); without it an existing one is refused before anything runs")
    b.set_defaults(func=cmd_bench)


def cmd_bench(a: argparse.Namespace) -> int:
    from mechsim.errors import ParameterError

    out = Path(a.out)
    if a.all:
        return _all(a, out)
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


#: What ``--all`` writes into DIR (and DIR/short), checked before anything runs.
_ALL_FILES = ["results.json", "results.md", "short/results.json", "short/results.md",
              "streaming.json", "streaming.md", "throughput.json", "throughput.md",
              "derive.json", "derive.md", "scene_cost.json", "scene_cost.md",
              "brouwer.json", "brouwer.png"]
#: The scene ``--all`` measures with every output consumed against state only.
ALL_SCENE = "scenes/pendulum.yaml"


def _all(a: argparse.Namespace, out: Path) -> int:
    """Every report, one after the other, each section in a new process (``_section``): a
    section is measured as a user's process would run it, without the peers, kernels and
    threads an earlier section left behind (a quiet machine: nothing else)."""
    import time

    from mechsim.bench.problems import SHORT_OF
    from mechsim.bench.run import known_systems
    from mechsim.errors import MechsimError, ParameterError

    if a.systems:
        raise ParameterError("--all", "takes no PROBLEM arguments")
    if not Path(ALL_SCENE).is_file():
        raise ParameterError("--all", f"run it from the checkout ({ALL_SCENE} not found)")
    short = [f"{name}_short" for name in SHORT_OF]
    long = [name for name in known_systems() if name not in short]
    refuse_existing(a.out, _ALL_FILES, a.force)
    options = {"long": long, "short": short, "members": a.members, "steps": a.steps,
               "runs": a.runs}
    start = time.monotonic()
    for k, name in enumerate(_SECTIONS, 1):
        print(f"mechsim bench --all: [{k}/{len(_SECTIONS)}] {name} "
              f"({time.monotonic() - start:.0f} s so far)", flush=True)
        status = _run_apart(name, out, options)
        if status != 0:
            raise MechsimError(f"bench --all: the {name} section failed (exit status "
                               f"{status}); the sections before it are written")
    print(f"mechsim bench --all: done in {time.monotonic() - start:.0f} s", flush=True)
    return 0


def _bench(module: str) -> Any:
    """A module of ``mechsim.bench``, imported when its section runs."""
    import importlib

    return importlib.import_module(f"mechsim.bench.{module}")


#: The sections of ``--all``, in their order: each section's run, given the output folder
#: and the options ``_all`` gathers.
_SECTIONS: dict[str, Callable[[Path, dict[str, Any]], None]] = {
    "long problems": lambda out, o: _bench("run").run_bench(o["long"], out, budget_s=2.0,
                                                            cold=False),
    "short problems": lambda out, o: _bench("run").run_bench(o["short"], out / "short",
                                                             budget_s=2.0, cold=False),
    "streaming": lambda out, o: _bench("streaming").run_streaming(out, []),
    "throughput": lambda out, o: _bench("throughput").run_throughput(out,
                                                                     members=o["members"]),
    "derive": lambda out, o: _bench("derive").run_derive(out, []),
    "scene cost": lambda out, o: _bench("scene_cost").run_scene_cost(ALL_SCENE, out),
    "brouwer": lambda out, o: _bench("brouwer").run_brouwer(out, n_steps=o["steps"],
                                                            runs=o["runs"]),
}


def _run_apart(name: str, out: Path, options: dict[str, Any]) -> int:
    """Section ``name`` of ``--all`` in a new interpreter (multiprocessing's spawn); its exit
    status."""
    import multiprocessing

    p = multiprocessing.get_context("spawn").Process(
        target=_section, args=(name, out, options), name=f"bench {name}")
    p.start()
    p.join()
    return p.exitcode if p.exitcode is not None else 1


def _section(name: str, out: Path, options: dict[str, Any]) -> None:
    """One section of ``--all``, in a process of its own (its error: one line, exit 2)."""
    import sys

    from mechsim.cli import report

    try:
        _run_section(name, out, options)
    except KeyboardInterrupt:
        sys.exit(130)
    except Exception as e:  # noqa: BLE001 - the one line of any other command
        sys.exit(report(e))


def _run_section(name: str, out: Path, options: dict[str, Any]) -> None:
    from mechsim.errors import MechsimError

    run = _SECTIONS.get(name)
    if run is None:
        raise MechsimError(f"bench --all: no section {name!r} (one of {', '.join(_SECTIONS)})")
    run(out, options)
