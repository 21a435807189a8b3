"""Live consumers of ``<ns>/sample_batch`` in another process (part of ``mechsim bench
--streaming``).

A fast ``--lossless`` run (no recording) with one consumer of the system's batch topic in a
new process: the real-time factor from the first sample to the last sample taken by the
consumer (whichever ends later: the run, every message acknowledged, or the consumer's last
take), and whether every sample arrived. Consumers:

- ``python``: ``mechsim.ros.batches.subscribe_batches`` (rclpy, every message decoded into
  numpy columns);
- ``c``: a subscriber written against rcl alone (``rcl_subscriber.c``: serialized messages
  taken in a loop, samples counted from the bytes), compiled here with the C compiler and the
  ROS headers and libraries of this environment, where they are.

And the ceiling of each: a bare rclpy loop that simulates nothing publishes a full batch
message (one recorded from the system) as often as the run's samples need, with the same
slices in flight as ``--lossless``, to a new consumer of the same kind.
"""

from __future__ import annotations

import json
import math
import os
import select
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
from pathlib import Path
from typing import Any

#: Seconds any one consumer may take in all (a condition ends every wait long before).
DEADLINE = 600.0

#: The Python consumer: ``mechsim.ros.batches.subscribe_batches`` on one topic; prints
#: "ready", stops once it holds the number of messages a line on stdin gives (or at the
#: deadline), prints
#: {"messages", "samples", "last"} ("last": time.monotonic() of the last take, the
#: CLOCK_MONOTONIC seconds the C consumer and this process read too).
_PYTHON_CONSUMER = """
import json, select, sys, time
from mechsim.ros.batches import subscribe_batches
topic, deadline = sys.argv[1], time.monotonic() + float(sys.argv[2])
messages = samples = 0
last, expected = 0.0, None
with subscribe_batches(topic) as sub:
    print("ready", flush=True)
    while (expected is None or messages < expected) and time.monotonic() < deadline:
        if expected is None and select.select([sys.stdin], [], [], 0)[0]:
            expected = int(sys.stdin.readline())
        for _, batch in sub.take(timeout=0.05):
            messages += 1
            samples += len(batch)
            last = time.monotonic()
print(json.dumps({"messages": messages, "samples": samples, "last": last}), flush=True)
"""


def build_c_consumer(directory: Path) -> tuple[Path | None, str]:
    """The rcl subscriber compiled into ``directory``: (executable, "") or (None, why not)."""
    compiler = shutil.which(os.environ.get("CC", "cc")) or shutil.which("gcc")
    if compiler is None:
        return None, "no C compiler on PATH"
    prefix = Path(sys.prefix)
    include, lib = prefix / "include", prefix / "lib"
    if not (include / "rcl" / "rcl" / "rcl.h").is_file() or not (lib / "librcl.so").is_file():
        return None, f"no rcl headers and library under {prefix} (include/rcl, lib/librcl.so)"
    source = Path(__file__).with_name("rcl_subscriber.c")
    exe = directory / "rcl_subscriber"
    # The ROS libraries of the environment resolve some of their own dependencies at run time
    # (LD_LIBRARY_PATH as rclpy sets it), hence --allow-shlib-undefined; among them, rcl
    # loads a message package's Python glue, whose symbols libpython provides (loaded, never
    # run: no interpreter starts).
    python_lib = sysconfig.get_config_var("LIBDIR")
    if not sysconfig.get_config_var("Py_ENABLE_SHARED") or not python_lib:
        return None, "this Python has no shared libpython (the ROS libraries load its symbols)"
    version = sysconfig.get_config_var("LDVERSION") or sysconfig.get_python_version()
    cmd = [compiler, "-O2", "-o", str(exe), str(source),
           *[f"-I{d}" for d in sorted(include.iterdir()) if d.is_dir()],
           f"-L{lib}", f"-Wl,-rpath,{lib}", f"-L{python_lib}", f"-Wl,-rpath,{python_lib}",
           "-Wl,--allow-shlib-undefined", "-Wl,--no-as-needed", f"-lpython{version}",
           "-lrcl", "-lrcutils", "-lrmw", "-ldl"]
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        last = (out.stderr.strip().splitlines() or ["(no message)"])[-1]
        return None, f"the rcl subscriber did not compile: {last}"
    return exe, ""


def stop(proc: subprocess.Popen[str]) -> None:
    """End a consumer that is still running (a failed measurement) and reap it."""
    if proc.poll() is None:
        proc.kill()
    proc.wait()


def _line(proc: subprocess.Popen[str], timeout: float) -> str:
    assert proc.stdout is not None
    if not select.select([proc.stdout], [], [], timeout)[0]:
        raise RuntimeError(f"no answer from the consumer within {timeout:g} s")
    return proc.stdout.readline().strip()


def start_consumer(kind: str, topic: str, c_exe: Path | None,
                   others: tuple[tuple[str, str], ...] = ()) -> subprocess.Popen[str]:
    """A consumer of ``kind`` (python, c) subscribed to ``topic`` and ready (the C one also
    to ``others``: (topic, type) pairs)."""
    from mechsim.environment import import_rclpy

    import_rclpy()  # the environment (DDS profile, library path) the child inherits
    if kind == "python":
        cmd = [sys.executable, "-c", _PYTHON_CONSUMER, topic, str(DEADLINE)]
    else:
        assert c_exe is not None
        pairs = ([(topic, "mechsim_msgs/msg/SampleBatch")] if topic else []) + [*others]
        cmd = [str(c_exe), str(DEADLINE), *[x for pair in pairs for x in pair]]
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        if _line(proc, 120.0) != "ready":
            raise RuntimeError(f"the {kind} consumer did not start")
    except BaseException:
        stop(proc)
        raise
    return proc


def finish_consumer(proc: subprocess.Popen[str], messages: int) -> dict[str, Any]:
    """Tell the consumer how many messages were sent; what it took, once it has them."""
    assert proc.stdin is not None
    try:
        proc.stdin.write(f"{messages}\n")
        proc.stdin.flush()
        return dict(json.loads(_line(proc, DEADLINE)))
    finally:
        stop(proc)


def _wait_matched(publisher: Any) -> None:
    end = time.monotonic() + 120
    while not publisher.get_subscription_count():
        if time.monotonic() > end:
            raise RuntimeError("the consumer never matched")
        time.sleep(0.01)


class _FullBatch:
    """A sink keeping the longest batch message of a run (the bare loop's payload)."""

    def __init__(self) -> None:
        from mechsim.outputs.batch import is_batch_topic
        from mechsim.outputs.sink import Capabilities, Takes

        self.capabilities = Capabilities(Takes.BYTES, wants=is_batch_topic)
        self.data = b""

    def write_rows(self, ns: Any, topics: list[tuple[str, str, Any, Any]]) -> None:
        pass

    def write_bytes(self, topic: str, type_name: str, qos: Any, ns: int, data: bytes) -> None:
        if len(data) > len(self.data):
            self.data = bytes(data)


def batch_consumer_rtf(system: str, duration: float, kind: str,
                       c_exe: Path | None = None) -> dict[str, Any]:
    """One system run fast and lossless for ``duration`` simulated seconds with one consumer
    of ``kind`` of its batch topic in another process (see the module docstring)."""
    from mechsim.ros.launch import run_scene
    from mechsim.scene import single_system_scene

    scene = single_system_scene(system)
    topic = f"/{system}/sample_batch"
    run_scene(scene, fast=True, duration=0.2)  # warm-up: kernels loaded
    proc = start_consumer(kind, topic, c_exe)
    try:
        t0 = time.monotonic()
        run = run_scene(scene, fast=True, duration=duration, lossless=True,
                        before_first_message=lambda node: _wait_matched(
                            node.outlet.channels[topic].publisher))
        ended = time.monotonic()
    except BaseException:
        stop(proc)
        raise
    sent = run.messages.get(topic, 0)
    got = finish_consumer(proc, sent)
    wall = max(ended, got["last"]) - (t0 + run.startup_time)
    samples = run.samples[system]
    return {"system": system, "consumer": kind, "sim_s": run.sim_time, "wall_s": wall,
            "rtf": run.sim_time / wall, "samples": samples, "messages": sent,
            "received_samples": got["samples"], "received_messages": got["messages"],
            "every_sample": got["samples"] == samples and got["messages"] == sent}


def full_batch(system: str) -> tuple[bytes, int]:
    """A full batch message of ``system`` (as many samples as one message holds) and its
    sample count."""
    from mechsim.outputs.batch import MAX_SAMPLES, decode
    from mechsim.ros.launch import run_scene
    from mechsim.scene import single_system_scene

    keep = _FullBatch()
    scene = single_system_scene(system)
    rate = scene.publish_rate
    run_scene(scene, fast=True, duration=1.5 * MAX_SAMPLES / rate, sinks=[keep])
    return keep.data, len(decode(keep.data))


def bare_batch_rtf(system: str, sim_s: float, samples: int, kind: str,
                   c_exe: Path | None = None) -> dict[str, Any]:
    """The ceiling: a bare rclpy loop sends ``samples`` samples as full batch messages of
    ``system`` (8 in flight at most, as ``--lossless`` keeps them) to a new consumer of
    ``kind``; real-time factor = ``sim_s`` / its wall time to the last take."""
    from mechsim.environment import import_rclpy

    rclpy = import_rclpy()
    from rclpy.duration import Duration

    from mechsim.ros.batches import batch_qos
    from mechsim.ros.outlet import LOSSLESS_SLICES
    from mechsim_msgs.msg import SampleBatch

    data, per_message = full_batch(system)
    messages = math.ceil(samples / per_message)
    topic = f"/bare_{system}/sample_batch"
    context = rclpy.context.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("bare_batch_publisher", context=context)
    try:
        pub = node.create_publisher(SampleBatch, topic, batch_qos())
        proc = start_consumer(kind, topic, c_exe)
        try:
            _wait_matched(pub)
            t0 = time.monotonic()
            for k in range(messages):
                pub.publish(data)
                if (k + 1) % LOSSLESS_SLICES == 0:
                    pub.wait_for_all_acked(Duration(seconds=60))
            pub.wait_for_all_acked(Duration(seconds=60))
            ended = time.monotonic()
        except BaseException:
            stop(proc)
            raise
        got = finish_consumer(proc, messages)
    finally:
        node.destroy_node()
        rclpy.shutdown(context=context)
    wall = max(ended, got["last"]) - t0
    return {"system": system, "consumer": kind, "sim_s": sim_s, "wall_s": wall,
            "rtf": sim_s / wall, "messages": messages, "samples_per_message": per_message,
            "every_message": got["messages"] == messages}


def live_batches(systems: list[str], duration: float, pendulum_duration: float
                 ) -> dict[str, Any]:
    """The batch consumers: pendulum with the Python and C consumers and their ceilings;
    every system of ``systems`` with the Python consumer."""
    with tempfile.TemporaryDirectory() as tmp:
        c_exe, c_missing = build_c_consumer(Path(tmp))
        kinds = ["python"] + (["c"] if c_exe else [])
        pendulum = []
        for kind in kinds:
            row = batch_consumer_rtf("pendulum", pendulum_duration, kind, c_exe)
            row["bare"] = bare_batch_rtf("pendulum", row["sim_s"], row["samples"], kind, c_exe)
            _say(row, f"batch topic, {kind} consumer (bare rclpy loop "
                      f"{row['bare']['rtf']:.0f})")
            pendulum.append(row)
        every = []
        for s in systems:
            row = batch_consumer_rtf(s, duration, "python")
            _say(row, "batch topic, python consumer")
            every.append(row)
    return {"pendulum": pendulum, "systems": every, "c_consumer": c_missing or "built"}


def _say(row: dict[str, Any], what: str) -> None:
    print(f"  {row['system']:22s} {what}: RTF {row['rtf']:8.1f}, every sample: "
          f"{row['every_sample']}", file=sys.stderr)
