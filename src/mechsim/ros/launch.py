"""Start a scene: all nodes in one process (stepped in lockstep by one loop), or one process
per node (``--processes``). Used by ``mechsim run`` and the scripts in ``launch_scripts/``."""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mechsim.errors import MechsimError, ParameterError
from mechsim.scene import Scene, apply_overrides, load_scene


@dataclass
class SceneRun:
    """What a finished run reports."""

    scene: Scene
    sim_time: float
    wall_time: float  # stepping and publishing, after start-up
    startup_time: float  # building the nodes (kernel loading or compilation)
    samples: dict[str, int]
    messages: dict[str, int]
    summary: list[tuple[str, str, float, int]] = field(default_factory=list)
    failures: dict[str, str] = field(default_factory=dict)
    interrupted: bool = False


class _Stop(Exception):
    pass


class DiagnosticsFeed:
    """In-process sink that hands energy/invariant/system_info messages straight to the
    diagnostics node: lossless, whatever the executor's pace."""

    def __init__(self, diag: Any) -> None:
        self.diag = diag

    def wants(self, topic: str) -> bool:
        return topic.rpartition("/")[2] in ("system_info", "energy", "invariants")

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        base, _, leaf = topic.rpartition("/")
        if leaf == "system_info":
            self.diag._on_info(base, msg)
        elif leaf == "energy":
            self.diag._on_energy(base, msg)
        elif leaf == "invariants":
            self.diag._on_invariants(base, msg)


def run_scene(scene: Scene, *, fast: bool | None = None, duration: float | None = None,
              sinks: list[Any] | None = None, context: Any = None,
              progress: Callable[[float, float], None] | None = None,
              diagnostics_period: float = 1.0) -> SceneRun:
    """Run every system of ``scene`` in this process until ``duration`` (simulated seconds)
    or Ctrl-C / SIGTERM. ``fast``: as fast as possible instead of the scene's pacing."""
    from mechsim.environment import import_rclpy

    rclpy = import_rclpy()
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from mechsim.ros.diagnostics import DiagnosticsNode
    from mechsim.ros.simulator import SimulatorNode

    own_context = context is None
    if own_context:
        context = rclpy.context.Context()
        rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    fast = scene.pacing == "fast" if fast is None else fast
    duration = duration if duration is not None else scene.duration
    sinks = list(sinks or [])
    nodes: list[Any] = []
    executor = SingleThreadedExecutor(context=context)
    diag = DiagnosticsNode(context=context, warn_drift=scene.warn_drift,
                           error_drift=scene.error_drift, period=3600.0, sinks=sinks,
                           discover=False)
    diag_sinks = [*sinks, DiagnosticsFeed(diag)]
    previous_term = signal.getsignal(signal.SIGTERM)

    def on_term(signum: int, frame: Any) -> None:
        raise _Stop()

    interrupted = False
    start = time.monotonic()
    startup = 0.0
    t = 0.0
    try:
        signal.signal(signal.SIGTERM, on_term)
        for i, inst in enumerate(scene.systems):
            nodes.append(SimulatorNode(inst, context=context, publish_rate=scene.publish_rate,
                                       real_time_factor=0.0, publish_clock=(i == 0),
                                       sinks=diag_sinks))
        executor.add_node(diag)
        for n in nodes:
            executor.add_node(n)
        startup = time.monotonic() - start
        start = time.monotonic()
        dt = 1.0 / scene.publish_rate
        next_diag = diagnostics_period
        wall0 = time.monotonic()
        next_spin = wall0
        k = 0
        while duration is None or t < duration - 1e-12:
            k += 1
            t_next = k * dt if duration is None else min(k * dt, duration)
            if not fast:
                wait = wall0 + t_next / scene.real_time_factor - time.monotonic()
                while wait > 0:
                    executor.spin_once(timeout_sec=min(wait, 0.05))
                    wait = wall0 + t_next / scene.real_time_factor - time.monotonic()
            for n in nodes:
                n.advance_to(t_next)
            t = t_next
            # Services and parameter requests are served every 20 ms of wall time: building
            # the executor's wait set costs ~0.5 ms, more than a sample, so not every tick.
            now = time.monotonic()
            if now >= next_spin:
                executor.spin_once(timeout_sec=0)
                next_spin = now + 0.02
            if t >= next_diag - 1e-12:
                diag.publish_now()
                next_diag += diagnostics_period
            if progress is not None and duration is not None:
                progress(t, duration)
    except (KeyboardInterrupt, _Stop):
        interrupted = True
    finally:
        signal.signal(signal.SIGTERM, previous_term)
        try:
            diag.publish_now()
        except Exception:  # noqa: BLE001 - shutting down: the run's data matters more
            pass
        run = SceneRun(scene=scene, sim_time=t, wall_time=time.monotonic() - start,
                       startup_time=startup,
                       samples={n.instance.name: n.samples_published for n in nodes},
                       messages={}, summary=diag.summary(),
                       failures={n.instance.name: n.failed for n in nodes if n.failed},
                       interrupted=interrupted)
        for n in [*nodes, diag]:
            for topic, count in n.outlet.counts.items():
                run.messages[topic] = run.messages.get(topic, 0) + count
        executor.shutdown()
        for n in [*nodes, diag]:
            n.destroy_node()
        if own_context:
            context.try_shutdown()
    return run


# --- one process per node ---------------------------------------------------------------------
def _spawn(args: list[str]) -> subprocess.Popen[bytes]:
    return subprocess.Popen([sys.executable, "-m", "mechsim.ros.launch", *args],
                            env=dict(os.environ))


def run_processes(scene_path: Path, scene: Scene, sets: list[str],
                  duration: float | None) -> int:
    """Each simulator node and the diagnostics node in its own process, paced in real time."""
    extra = [a for s in sets for a in ("--set", s)]
    procs = [_spawn(["--node", inst.name, str(scene_path), *extra])
             for inst in scene.systems]
    procs.append(_spawn(["--node", "diagnostics", str(scene_path), *extra]))
    end = None if duration is None else time.monotonic() + duration / scene.real_time_factor
    try:
        while end is None or time.monotonic() < end:
            if all(p.poll() is not None for p in procs):
                break
            time.sleep(0.1)
    except KeyboardInterrupt:
        pass
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    for p in procs:
        try:
            p.wait(timeout=5)
        except subprocess.TimeoutExpired:
            p.kill()
    return 0


def run_single_node(scene: Scene, which: str) -> int:
    """Body of one process of ``run_processes``: one node, spun until SIGINT/SIGTERM."""
    from mechsim.environment import import_rclpy

    rclpy = import_rclpy()
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    context = rclpy.context.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGTERM, lambda s, f: (_ for _ in ()).throw(KeyboardInterrupt()))
    if which == "diagnostics":
        from mechsim.ros.diagnostics import DiagnosticsNode
        node: Any = DiagnosticsNode(context=context, warn_drift=scene.warn_drift,
                                    error_drift=scene.error_drift)
    else:
        from mechsim.ros.simulator import SimulatorNode
        names = [i.name for i in scene.systems]
        if which not in names:
            raise ParameterError("--node", f"no instance {which!r} in the scene")
        idx = names.index(which)
        node = SimulatorNode(scene.systems[idx], context=context,
                             publish_rate=scene.publish_rate,
                             real_time_factor=scene.real_time_factor, publish_clock=(idx == 0))
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        executor.spin()
    except KeyboardInterrupt:
        pass
    finally:
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()
    return 0


def _main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m mechsim.ros.launch")
    ap.add_argument("scene")
    ap.add_argument("--node", required=True)
    ap.add_argument("--set", action="append", default=[])
    a = ap.parse_args(argv)
    try:
        scene = load_scene(a.scene)
        apply_overrides(scene, a.set)
        return run_single_node(scene, a.node)
    except MechsimError as e:
        print(f"mechsim: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # stopped (SIGINT/SIGTERM) while still starting up
        return 130


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
