"""Streaming throughput (``mechsim bench --streaming --out DIR``).

1. The largest real-time factor of each system recording at 100 Hz output: one instance with
   default parameters, run through the real node graph as fast as possible (``run_scene``) with
   the bag writer attached, so every message is built, published, serialized and written.
   Real-time factor = simulated seconds / wall seconds after start-up, up to the bag being
   complete on disk (the writer's queue drained), measured after a warm-up recording
   (compilation excluded): the fastest of ``RECORDING_REPEATS`` recordings, made in rounds
   (every system once a round), the median beside it. The per-sample cost split: wall time
   per sample in each stage (integrate, evaluate, encode, publish incl. the hand-off to the
   recorder, diagnostics, and write: the bag writer's thread, which overlaps the others on a
   second core).
2. Live consumers in another process of a fast ``--lossless`` run (no bag): on the per-sample
   topics (one subscription per streamed topic: Python, or a subscriber written against rcl
   alone) and on the batch topic (``mechsim.bench.live_batches``: the Python helper, the rcl
   subscriber, every system), each beside its ceiling: a bare rclpy loop sending the same
   messages the same way to a new consumer of the same kind, with nothing to simulate.
3. The CPU share of a scene with every system streaming in real time at 100 Hz (one instance
   each), without and with a bag and a Rerun recording: process CPU time / wall time from the
   first sample to the end (start-up excluded; also given with it), so 1.0 is one full core.
4. Start-up of scenes of 1 to 100 instances, where it goes, and the alternatives
   (``mechsim.bench.startup``); and the wall time from launching ``mechsim run pendulum`` in a
   new process to the first ``/clock`` message arriving in this process (warm kernel cache),
   3 runs, and for a few systems the first run with the model not derived yet against the
   two after it.

Writes ``streaming.json`` and ``streaming.md``; every figure is measured in the run.
"""

from __future__ import annotations

import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from mechsim.bench.host import reference_ms
from mechsim.bench.live_batches import stop
from mechsim.bench.streaming_report import STAGES, report_lines


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


#: Recordings of each system in the first pass (timeit's default repeat count): its figure is
#: the fastest one's (timeit's convention: a slower one met other work on the host), the
#: median beside it.
RECORDING_REPEATS = 5


def _record(scene: Any, duration: float, bag: str) -> dict[str, Any]:
    from mechsim.ros.record import run_with_outputs

    reference = reference_ms()
    t0 = time.monotonic()
    run, _ = run_with_outputs(scene, fast=True, duration=duration, bag=bag)
    wall = time.monotonic() - t0 - run.startup_time  # to the bag closed
    samples = max(1, sum(run.samples.values()))
    return {"sim_s": run.sim_time, "wall_s": wall, "startup_s": run.startup_time,
            "rtf": run.sim_time / wall, "messages": sum(run.messages.values()),
            "us_per_sample": 1e6 * wall / samples,
            "split_us": {k: 1e6 * v / samples for k, v in run.costs.items()},
            "reference_ms": reference}


def recording_rtf(system: str, duration: float, repeats: int = 1) -> dict[str, Any]:
    """The real-time factor of ``system`` recorded ``repeats`` times after a warm-up: the
    fastest recording's figures, the median real-time factor (``median_rtf``), and every
    recording's real-time factor (``runs``) and host speed before it (``reference_ms``, see
    :mod:`mechsim.bench.host`)."""
    return recordings_in_rounds([system], duration, repeats)[0]


def recordings_in_rounds(systems: list[str], duration: float,
                         rounds: int) -> list[dict[str, Any]]:
    """:func:`recording_rtf` of each of ``systems``, its ``rounds`` recordings made in rounds
    (every system once a round, after a warm-up recording of each): a slow stretch of the host
    meets one recording of several systems, not every recording of one (as the compared runs
    of the long problems are timed again in rounds, ``paired``)."""
    import shutil
    import statistics

    from mechsim.ros.record import run_with_outputs
    from mechsim.scene import single_system_scene

    scenes = {s: single_system_scene(s) for s in systems}
    got: dict[str, list[dict[str, Any]]] = {s: [] for s in systems}
    with tempfile.TemporaryDirectory() as tmp:
        for scene in scenes.values():
            # Warm-up: kernels loaded or compiled (numba compiles a loop at its first call).
            run_with_outputs(scene, fast=True, duration=0.2, bag=os.path.join(tmp, "warm"))
            shutil.rmtree(os.path.join(tmp, "warm"))
        for _ in range(rounds):
            for s, scene in scenes.items():
                bag = os.path.join(tmp, "bag")
                got[s].append(_record(scene, duration, bag))
                shutil.rmtree(bag)  # (the bench's own scratch recording)
    rows = []
    for s in systems:
        fastest = max(got[s], key=lambda g: g["rtf"])
        rows.append({"system": s, **fastest,
                     "median_rtf": statistics.median(g["rtf"] for g in got[s]),
                     "runs": [g["rtf"] for g in got[s]],
                     "reference_ms": [g["reference_ms"] for g in got[s]]})
    return rows


#: Systems (the slowest to record of those without events, which integrate their blocks one
#: after the other anyway) recorded again with each design of ``recording_designs`` in turn,
#: ``VARIANT_REPEATS`` times each.
VARIANT_SYSTEMS = 3
VARIANT_REPEATS = 2


def recording_variants(systems: list[str], duration: float) -> list[dict[str, Any]]:
    """``recording_rtf`` of each system with each recording design
    (``recording_designs.DESIGNS``), made in turn: the median real-time factor of each and
    every run's."""
    import statistics

    from mechsim.bench.recording_designs import DESIGNS, design

    rows = []
    for s in systems:
        got: dict[str, list[float]] = {name: [] for name in DESIGNS}
        for _ in range(VARIANT_REPEATS):
            for name in DESIGNS:
                with design(name):
                    got[name].append(recording_rtf(s, duration)["rtf"])
        row = {"system": s, "designs": {name: {"median": statistics.median(runs), "runs": runs}
                                        for name, runs in got.items()}}
        print(f"  {s:22s} RTF " + ", ".join(f"{name} {statistics.median(runs):.0f}"
                                            for name, runs in got.items()), file=sys.stderr)
        rows.append(row)
    return rows


#: A live subscriber in another process: raw (no deserialisation), reliable, KEEP_ALL, one
#: subscription per streamed topic given as JSON [[topic, type], ...]; prints "ready", then,
#: once nothing arrived for 3 s, the count per topic and the time.monotonic() of the last
#: take as JSON.
_SUBSCRIBER = """
import importlib, json, sys, time
from mechsim.environment import import_rclpy
rclpy = import_rclpy()
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
rclpy.init()
node = rclpy.create_node("live_subscriber")
qos = QoSProfile(depth=1, history=HistoryPolicy.KEEP_ALL,
                 reliability=ReliabilityPolicy.RELIABLE)
got, subs, last = {}, {}, [0.0]
drain = sys.argv[2] == "drain"
for topic, type_name in json.loads(sys.argv[1]):
    pkg, _, name = type_name.split("/")
    cls = getattr(importlib.import_module(f"{pkg}.msg"), name)
    got[topic] = 0
    def take(data, topic=topic):
        got[topic] += 1
        # drain: take what else waits on the topic without the executor's per-message work
        sub = subs[topic]
        while drain and sub.handle.take_message(sub.msg_type, True) is not None:
            got[topic] += 1
        last[0] = time.monotonic()
    subs[topic] = node.create_subscription(cls, topic, take, qos, raw=True)
print("ready", flush=True)
quiet = 0
while quiet < 30 or not any(got.values()):
    before = sum(got.values())
    rclpy.spin_once(node, timeout_sec=0.1)
    quiet = 0 if sum(got.values()) != before else quiet + 1
print(json.dumps({"counts": got, "last": last[0]}), flush=True)
"""


#: Live-subscriber runs on the per-sample topics: (system, simulated seconds, subscriber).
#: The Python subscriber takes each message through rclpy's executor ("executor": one
#: callback a message) or, woken by the executor, takes every waiting message of the topic
#: in a loop ("drain"); "c": the rcl subscriber (``rcl_subscriber.c``), every topic in one
#: wait set, where it can be built. 200 s shows the sustained rate: a subscriber that falls
#: behind has the reliable protocol's repairs pace the writer.
LIVE_RUNS = (("pendulum", 30.0, "drain"), ("kepler", 30.0, "drain"),
             ("rigid_body", 30.0, "drain"), ("double_pendulum", 30.0, "drain"),
             ("pendulum", 200.0, "drain"), ("pendulum", 200.0, "c"),
             ("pendulum", 30.0, "executor"))


def _live_subscriber(topics: list[list[str]], mode: str, c_exe: Path | None = None) -> Any:
    """The subscriber process (``_SUBSCRIBER``, or the rcl one for ``mode`` "c"), started
    and ready."""
    import json as json_
    import subprocess

    from mechsim.bench.live_batches import start_consumer

    if mode == "c":
        return start_consumer("c", "", c_exe, others=tuple((t, ty) for t, ty in topics))
    sub = subprocess.Popen([sys.executable, "-c", _SUBSCRIBER, json_.dumps(topics), mode],
                           stdout=subprocess.PIPE, text=True)
    assert sub.stdout is not None
    if sub.stdout.readline().strip() != "ready":
        sub.kill()
        sub.wait()
        raise RuntimeError("the live subscriber did not start")
    return sub


def _received(sub: Any, mode: str, sent: int) -> tuple[int, float]:
    """Messages the subscriber took (all topics) and the time.monotonic() of its last take,
    once it is done (``sent``: how many were published)."""
    import json as json_

    from mechsim.bench.live_batches import finish_consumer

    if mode == "c":
        got = finish_consumer(sub, sent)
        return int(got["messages"]), float(got["last"])
    try:
        got = json_.loads(sub.stdout.readline())
    finally:
        stop(sub)
    return sum(got["counts"].values()), float(got["last"])


def _wait_matched(publishers: list[Any]) -> None:
    end = time.monotonic() + 60
    while not all(p.get_subscription_count() for p in publishers):
        if time.monotonic() > end:
            raise RuntimeError("the live subscriber never matched")
        time.sleep(0.01)


class _FirstRows:
    """A sink keeping one recorded payload of each topic (the bare loop's messages)."""

    def __init__(self) -> None:
        from mechsim.outputs.sink import Capabilities, Takes

        self.capabilities = Capabilities(Takes.BYTES)
        self.rows: dict[str, bytes] = {}

    def write_rows(self, ns: Any, topics: list[tuple[str, str, Any, Any]]) -> None:
        for topic, _, _, rows in topics:
            if len(rows):
                self.rows.setdefault(topic, rows[0].tobytes())

    def write_bytes(self, topic: str, type_name: str, qos: Any, ns: int, data: bytes) -> None:
        self.rows.setdefault(topic, data)


def live_subscriber_rtf(system: str, duration: float, mode: str = "drain",
                        c_exe: Path | None = None) -> dict[str, Any]:
    """Real-time factor of a fast, lossless run (no recording) with one live subscriber to
    every per-sample topic in another process (``mode``, see ``LIVE_RUNS``), from the first
    sample to the last one taken, and whether every message arrived; and the ceiling: the
    same messages, as many of each, sent to the same kind of subscriber by a bare rclpy loop
    that simulates nothing (``bare_rtf``)."""
    from mechsim.outputs.batch import is_batch_topic
    from mechsim.ros.launch import run_scene
    from mechsim.ros.outlet import streamed
    from mechsim.scene import single_system_scene

    scene = single_system_scene(system)
    topics: list[list[str]] = []
    qos: dict[str, Any] = {}
    first = _FirstRows()

    def listed(node: Any) -> None:
        topics[:] = [[t, ch.type_name] for t, ch in node.outlet.channels.items()
                     if streamed(ch.qos) and not is_batch_topic(t)]
        qos.update({t: node.outlet.channels[t].publisher.qos_profile for t, _ in topics})

    run_scene(scene, fast=True, duration=0.2, before_first_message=listed,  # warm-up
              sinks=[first])
    sub = _live_subscriber(topics, mode, c_exe)
    try:
        def matched(node: Any) -> None:
            _wait_matched([node.outlet.channels[t].publisher for t, _ in topics])

        t0 = time.monotonic()
        run = run_scene(scene, fast=True, duration=duration, lossless=True,
                        before_first_message=matched)
        ended = time.monotonic()
    except BaseException:
        stop(sub)
        raise
    published = {t: run.messages.get(t, 0) for t, _ in topics}
    sent = sum(published.values())
    received, last = _received(sub, mode, sent)
    wall = max(ended, last) - (t0 + run.startup_time)
    bare = _bare_loop_wall(topics, qos, first.rows, published, mode, c_exe)
    return {"system": system, "subscriber": mode, "sim_s": run.sim_time, "wall_s": wall,
            "rtf": run.sim_time / wall, "messages": sent, "every_message": received == sent,
            "lost": sent - received, "bare_rtf": run.sim_time / bare}


def _bare_loop_wall(topics: list[list[str]], qos: dict[str, Any], rows: dict[str, bytes],
                    counts: dict[str, int], mode: str, c_exe: Path | None = None) -> float:
    """Wall seconds a bare rclpy loop takes to send ``counts[topic]`` copies of each topic's
    payload, sample by sample in slices of ``LOSSLESS_DEPTH``, at most ``LOSSLESS_SLICES``
    of them unacknowledged (as ``--lossless`` does), to a new subscriber process of the same
    kind, up to its last take: what the machine allows an rclpy publisher with nothing to
    simulate."""
    from mechsim.environment import import_rclpy

    rclpy = import_rclpy()
    from rclpy.duration import Duration
    from rclpy.qos import QoSProfile

    from mechsim.outputs.bag import message_class
    from mechsim.ros.outlet import LOSSLESS_DEPTH, LOSSLESS_SLICES

    context = rclpy.context.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("bare_publisher", context=context)
    try:
        pubs = {}
        for t, type_name in topics:
            q = qos[t]
            pubs[t] = node.create_publisher(
                message_class(type_name), t,
                QoSProfile(depth=max(q.depth, LOSSLESS_DEPTH * LOSSLESS_SLICES),
                           history=q.history, reliability=q.reliability,
                           durability=q.durability))
        sub = _live_subscriber(topics, mode, c_exe)
        try:
            _wait_matched(list(pubs.values()))
            samples = max(counts.values())
            t0 = time.monotonic()
            window = LOSSLESS_DEPTH * LOSSLESS_SLICES
            for start in range(0, samples, LOSSLESS_DEPTH):
                if start and start % window == 0:
                    for p in pubs.values():
                        p.wait_for_all_acked(Duration(seconds=60))
                for t, p in pubs.items():
                    data, publish = rows.get(t, b""), p.publish
                    # a topic sent less often than every sample (diagnostics) keeps its count
                    for _ in range(max(0, min(start + LOSSLESS_DEPTH, counts[t]) - start)):
                        publish(data)
            for p in pubs.values():
                p.wait_for_all_acked(Duration(seconds=60))
            ended = time.monotonic()
        except BaseException:
            stop(sub)
            raise
        _, last = _received(sub, mode, sum(counts.values()))
        return max(ended, last) - t0
    finally:
        node.destroy_node()
        rclpy.shutdown(context=context)


def _split(split: dict[str, float]) -> str:
    return " ".join(f"{k} {split.get(k, 0.0):.1f}" for k in STAGES)


def all_systems_realtime(duration: float, record: bool = False) -> dict[str, Any]:
    """CPU share of every system streaming in real time at 100 Hz in one process (``record``:
    also writing a bag and a Rerun recording)."""
    from mechsim.ros.record import run_with_outputs
    from mechsim.scene import parse_scene
    from mechsim.systems import system_ids

    ids = system_ids()
    scene = parse_scene({"name": "all", "pacing": "realtime", "real_time_factor": 1.0,
                         "publish_rate": 100.0,
                         "systems": [{"system": s, "origin": [3.0 * i, 0.0, 0.0]}
                                     for i, s in enumerate(ids)]})
    marks: list[tuple[float, float]] = []

    def progress(t: float, d: float) -> None:
        # The first call follows the first sample (start-up is over): kept as marks[0];
        # marks[1] is the latest.
        marks[1:] = [(_cpu(), time.monotonic())]

    with tempfile.TemporaryDirectory() as tmp:
        cpu0, wall0 = _cpu(), time.monotonic()
        run, _ = run_with_outputs(scene, fast=False, duration=duration,
                                  bag=os.path.join(tmp, "bag") if record else None,
                                  rrd=os.path.join(tmp, "run.rrd") if record else None,
                                  progress=progress)
        cpu1, wall1 = _cpu(), time.monotonic()
    (c0, w0), (c1, w1) = marks[0], marks[-1]
    return {"systems": len(ids), "sim_s": run.sim_time, "wall_s": run.wall_time,
            "startup_s": run.startup_time, "cpu_s_total": cpu1 - cpu0,
            "cpu_share_total": (cpu1 - cpu0) / (wall1 - wall0),
            "cpu_share_run": (c1 - c0) / max(w1 - w0, 1e-9), "recording": record,
            "samples": sum(run.samples.values()), "failures": run.failures}


def _first_message(executor: Any, got: list[float], system: str,
                   env: dict[str, str] | None = None) -> float | None:
    """Seconds from launching ``mechsim run SYSTEM`` to its first /clock message here."""
    import signal
    import subprocess

    got.clear()
    t0 = time.monotonic()
    proc = subprocess.Popen([sys.executable, "-m", "mechsim.cli", "run", system,
                             "--duration", "30"], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        while not got and time.monotonic() - t0 < 120:
            executor.spin_once(timeout_sec=0.005)
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:  # a probe that does not stop: no output to keep
            proc.kill()
            proc.wait()
    return got[0] - t0 if got else None


#: Systems whose start-up is measured with their model not yet derived (cold).
COLD_SYSTEMS = ("pendulum", "kepler", "double_pendulum", "rigid_body")


def first_message_latency(repeats: int = 3, cold: tuple[str, ...] = COLD_SYSTEMS
                          ) -> dict[str, Any]:
    """Start-up to the first message in another process: ``mechsim run pendulum`` warm
    (``repeats`` times), and for each of ``cold`` its first run with the model not derived
    yet (a copy of the kernel cache without that system's modules and without the model
    summaries: the shared loops stay compiled, as set-up leaves them) against the next two
    (warm)."""
    import glob
    import shutil

    from mechsim.codegen import cache_dir
    from mechsim.environment import import_rclpy

    rclpy = import_rclpy()
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import qos_profile_sensor_data
    from rosgraph_msgs.msg import Clock

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    node = Node("startup_probe", context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    got: list[float] = []
    node.create_subscription(Clock, "/clock", lambda m: got.append(time.monotonic()),
                             qos_profile_sensor_data)
    warm: list[float] = []
    cold_rows = []
    try:
        for _ in range(repeats):
            x = _first_message(executor, got, "pendulum")
            if x is not None:
                warm.append(x)
        for system in cold:
            with tempfile.TemporaryDirectory() as tmp:
                cache = os.path.join(tmp, "cache")
                shutil.copytree(cache_dir(), cache, symlinks=True)
                # and every model summary (named by a hash, not by the system): the model is
                # declared from scratch, as the first time on a machine
                for pattern in (f"kernels/mechsim_{system}_*",
                                f"kernels/__pycache__/mechsim_{system}_*",
                                f"derived/{system}_*", "summaries/*.json"):
                    for f in glob.glob(os.path.join(cache, pattern)):
                        os.remove(f)
                env = dict(os.environ, MECHSIM_CACHE_DIR=cache)
                first = _first_message(executor, got, system, env)
                after = [_first_message(executor, got, system, env) for _ in range(2)]
            known = [x for x in after if x is not None]
            cold_rows.append({"system": system, "cold_s": first, "warm_s": known,
                              "ratio": first / min(known) if first and known else None})
    finally:
        executor.shutdown()
        node.destroy_node()
        ctx.try_shutdown()
    return {"warm_pendulum_s": warm, "cold": cold_rows}


#: Targets of the figures this benchmark measures (real-time factors; seconds).
TARGETS = {"batch_pendulum": 1000.0, "batch_every_system": 300.0, "recording": 1000.0,
           "startup_100": 3.0}


def run_streaming(out: Path, systems: list[str], duration: float = 1000.0,
                  realtime_duration: float = 10.0, batch_duration: float = 300.0,
                  pendulum_batch_duration: float = 2000.0) -> dict[str, Any]:
    """Every measurement of the module docstring and of ``live_batches`` and ``startup``, in
    one run; writes ``streaming.json`` and ``streaming.md``."""
    from mechsim.bench.live_batches import build_c_consumer, live_batches
    from mechsim.bench.startup import startup
    from mechsim.systems import load_system, system_ids

    out.mkdir(parents=True, exist_ok=True)
    ids = systems or system_ids()
    rows = recordings_in_rounds(list(ids), duration, RECORDING_REPEATS)
    for row in rows:
        print(f"  {row['system']:22s} RTF {row['rtf']:8.1f}  ({row['us_per_sample']:.1f} "
              f"µs/sample: {_split(row['split_us'])})", file=sys.stderr)
    ahead = [r["system"] for r in sorted(rows, key=lambda r: r["rtf"])
             if not load_system(r["system"]).events]  # (with events: one after the other)
    variants = recording_variants(ahead[:VARIANT_SYSTEMS], duration)
    batches = live_batches(ids, batch_duration, pendulum_batch_duration)
    live = []
    with tempfile.TemporaryDirectory() as tmp:
        c_exe, _ = build_c_consumer(Path(tmp))
        for s, live_duration, mode in LIVE_RUNS:
            if mode == "c" and c_exe is None:
                continue
            row = live_subscriber_rtf(s, live_duration, mode, c_exe)
            print(f"  {s:22s} per-sample topics ({mode}): RTF {row['rtf']:8.1f} (bare rclpy "
                  f"loop {row['bare_rtf']:.1f}), every message: {row['every_message']}",
                  file=sys.stderr)
            live.append(row)
    all_systems_realtime(1.0)  # warm: load every kernel once
    cpu = all_systems_realtime(realtime_duration)
    cpu_rec = all_systems_realtime(realtime_duration, record=True)
    starts = startup()
    latency = first_message_latency()
    result = {"schema": "mechsim-streaming/2", "recording": rows,
              "recording_variants": variants, "batches": batches,
              "live": live, "realtime_all": cpu, "realtime_all_recording": cpu_rec,
              "startup": starts, "first_message_s": latency, "targets": TARGETS,
              "host": {"cores": os.cpu_count(), "loadavg": os.getloadavg()}}
    (out / "streaming.json").write_text(json.dumps(result, indent=2))
    lines = report_lines(result, duration)
    (out / "streaming.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return result
