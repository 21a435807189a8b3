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


def check_rate(value: float) -> float:
    """``--rate``: publish rate, in the range scenes and nodes accept."""
    from mechsim.params import PUBLISH_RATE

    return float(PUBLISH_RATE.check(value, "--rate"))


def scene_of(a: Any, *, fast: bool = False) -> Any:
    """The scene a running verb names (``target``, ``--set``, ``--name``), parsed and
    validated once, with the run's ``--rate``, ``--duration`` and ``fast`` (as fast as
    possible) set on it: the one scene object handed on to the nodes."""
    from mechsim.scene import scene_from_target

    scene = scene_from_target(a.target, a.set, a.name)
    if a.rate is not None:
        scene.publish_rate = check_rate(a.rate)
    if a.duration is not None:
        scene.duration = check_duration(a.duration)
    if fast:
        scene.pacing = "fast"
    return scene


def check_outputs(scene: Any, bag: str | None, rrd: str | None) -> None:
    """The output paths of a run, refused before anything starts if they are no paths."""
    from mechsim.params import check_text
    from mechsim.ros.record import bag_path

    if bag is not None:
        bag_path(bag, scene)
    if rrd is not None:
        check_text("--rrd", rrd)


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
    for name, reason in run.failures.items():
        print(f"  {name}: integration stopped: {reason}")


def say(text: str) -> None:
    """One line on stderr, prefixed like every mechsim message."""
    print(f"mechsim: {text}", file=sys.stderr)
