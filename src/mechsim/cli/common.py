"""Helpers every verb shares: progress bar, the conservation table, one-line messages, the
checks of the options every running verb has (same ranges as scenes and nodes)."""

from __future__ import annotations

import sys
from typing import Any

#: What a verb that starts nodes reads from the environment (the end of its --help).
NODE_ENVIRONMENT = (
    "environment: ROS_DOMAIN_ID (the graph); MECHSIM_GRAPH_WAIT (seconds of DDS discovery in "
    "which a start is refused if its instance name or /clock is in use; default 2, 0: no "
    "check); MECHSIM_DDS_INTERFACE and MECHSIM_DDS_PEERS (several hosts, opt-in); "
    "MECHSIM_CACHE_DIR (the generated kernels)")


def check_duration(value: float) -> float:
    """``--duration``: simulated seconds, in the range scenes and nodes accept."""
    from mechsim.params import DURATION

    return float(DURATION.check(value, "--duration"))


def check_rate(value: float, option: str = "--publish-rate") -> float:
    """``--publish-rate``: publish rate, in the range scenes and nodes accept."""
    from mechsim.params import PUBLISH_RATE

    return float(PUBLISH_RATE.check(value, option))


def add_scene_options(parser: Any, verb: str) -> None:
    """The options of a verb that runs a scene: ``--set``, ``--name``, ``--publish-rate``
    (and its deprecated spelling ``--rate``), ``--force``."""
    import argparse

    parser.add_argument("--set", action="extend", nargs="+", default=[], metavar="NAME=VALUE",
                        help="parameter or run setting (method, tolerance, publish_rate, ...: "
                        "the names of the nodes' ROS parameters); INSTANCE:NAME=VALUE for one "
                        "instance; several after one --set")
    parser.add_argument("--name", metavar="NS", help="instance name (ROS namespace) of a "
                        "single SYSTEM (default: the system id)")
    parser.add_argument("--publish-rate", type=float, metavar="HZ",
                        help="samples published per second of simulation time (the "
                        "publish_rate setting)")
    # One name per meaning: `--rate` is replay's speed factor (as in `ros2 bag play`).
    parser.add_argument("--rate", type=float, dest="deprecated_rate", help=argparse.SUPPRESS)
    parser.add_argument("--bag-topics", metavar="WHAT", help="what the bag records: samples "
                        "(every topic but <ns>/sample_batch; the default), batches "
                        "(<ns>/sample_batch instead of the per-sample topics) or both; "
                        "default: the scene's outputs.bag_topics")
    add_force(parser)
    parser.set_defaults(verb=verb)


def scene_of(a: Any, *, fast: bool = False) -> Any:
    """The scene a running verb names (``target``, ``--set``, ``--name``), parsed and
    validated once, with the run's ``--publish-rate``, ``--duration`` and ``fast`` (as fast as
    possible) set on it: the one scene object handed on to the nodes."""
    from mechsim.scene import scene_from_target

    scene = scene_from_target(a.target, a.set, a.name)
    scene.force = bool(getattr(a, "force", False))
    rate = getattr(a, "publish_rate", None)
    old = getattr(a, "deprecated_rate", None)
    if old is not None:
        from mechsim.errors import ParameterError

        if rate is not None:
            raise ParameterError("--rate", "not with --publish-rate (the same setting)")
        say(f"warning: `{getattr(a, 'verb', 'run')} --rate` is deprecated: use --publish-rate "
            "(samples per second of simulation time); --rate is replay's speed factor")
        rate = old
        option = "--rate"
    else:
        option = "--publish-rate"
    if rate is not None:
        scene.publish_rate = check_rate(rate, option)
    if a.duration is not None:
        scene.duration = check_duration(a.duration)
    if getattr(a, "bag_topics", None) is not None:
        from mechsim.scene import bag_topics

        scene.bag_topics = bag_topics("--bag-topics", a.bag_topics)
    if fast:
        scene.pacing = "fast"
    return scene


def check_outputs(scene: Any, bag: str | None, rrd: str | None) -> str | None:
    """The output paths of a run, refused before anything starts if they are no paths or
    would replace something: an existing .rrd without ``--force`` (``scene.force``), a bag
    directory that exists with content (never replaced: a recording is never deleted).
    Returns the .rrd path with its strftime fields expanded (as a bag's are)."""
    import os

    from mechsim.errors import ParameterError
    from mechsim.outputs.bag import expand_path
    from mechsim.params import check_text
    from mechsim.ros.record import bag_path

    if bag is not None:
        d = expand_path(bag_path(bag, scene))
        try:
            taken = os.path.lexists(d) and (d.is_symlink() or not d.is_dir()
                                            or any(d.iterdir()))
        except OSError:
            taken = False  # unreadable: the bag writer says why when it claims the path
        if taken:
            raise ParameterError("--bag", f"{d} exists{' and is not empty' if d.is_dir() else ''}"
                                 " (a bag is never replaced, not even with --force: choose a "
                                 "new path or remove it)")
    if rrd is not None:
        rrd = str(expand_path(check_text("--rrd", rrd)))
        if os.path.isdir(rrd):
            raise ParameterError("--rrd", f"{rrd} is a directory")
        if os.path.lexists(rrd) and not scene.force:
            raise ParameterError("--rrd", f"{rrd} exists (add --force to replace it)")
    return rrd


def refuse_existing(out: str, names: list[str], force: bool) -> None:
    """Before a verb writes ``names`` into the directory ``out``: none of them may exist,
    unless ``--force`` (ParameterError naming the first that does)."""
    import os

    from mechsim.errors import ParameterError
    from mechsim.params import check_text

    check_text("--out", out)
    if force:
        return
    for name in names:
        path = os.path.join(out, name)
        if os.path.lexists(path):
            raise ParameterError("--out", f"{path} exists (add --force to replace what this "
                                 "command writes there)")


def add_force(parser: Any, help_text: str = "replace an --rrd recording that exists, once "
              "the new one is complete (without it nothing is replaced; a bag never is)"
              ) -> None:
    """The ``--force`` option of a verb that writes files."""
    parser.add_argument("--force", action="store_true", help=help_text)


def progress_bar(enabled: bool) -> Any:
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
    for name in getattr(run, "efforts", []):
        print(f"  {name}: an effort was applied, so only the laws that hold under an outside "
              "force are checked from then on (work_balance, constraint residuals): energy, "
              "energy_function and the invariants change with its work and impulse and are "
              "left out")
    for name, reason in run.failures.items():
        print(f"  {name}: integration stopped: {reason}")


def say(text: str) -> None:
    """One line on stderr, prefixed like every mechsim message."""
    print(f"mechsim: {text}", file=sys.stderr)
