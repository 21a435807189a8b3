"""``<ns>/sample_batch``: one ``mechsim_msgs/SampleBatch`` per block of samples, its values
those of the per-sample topics bit for bit; its consumer helpers (numpy decoding, from a bag
and from a live subscription in another process); what a bag records of it; and lossless
delivery to another process with several slices in flight.

The per-sample messages and the batches are decoded by rclpy's own deserializer (the C type
support of the generated interfaces), independent of mechsim's encoder and decoder."""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mechsim.outputs.sink import Capabilities, Takes
from mechsim.testing import wait_until

DEADLINE = 300.0


class _Capture:
    """Every message of a run as CDR bytes, per topic, in publication order."""

    capabilities = Capabilities(Takes.BYTES)

    def __init__(self) -> None:
        self.data: dict[str, list[bytes]] = {}

    def write_rows(self, ns: Any, topics: list[tuple[str, str, Any, Any]]) -> None:
        for topic, _, _, rows in topics:
            self.data.setdefault(topic, []).extend(r.tobytes() for r in rows)

    def write_bytes(self, topic: str, type_name: str, qos: Any, ns: int, data: bytes) -> None:
        self.data.setdefault(topic, []).append(data)

    def messages(self, topic: str, cls: type) -> list[Any]:
        from rclpy.serialization import deserialize_message

        return [deserialize_message(d, cls) for d in self.data.get(topic, [])]


def _run(system: str, context: Any, duration: float, *, paced: bool = False,
         sinks: list[Any] | None = None) -> Any:
    from mechsim.ros.launch import run_scene
    from mechsim.scene import parse_scene

    scene = parse_scene({"name": system, "publish_rate": 100.0, "real_time_factor": 40.0,
                         "systems": [{"system": system}]})
    return run_scene(scene, fast=not paced, duration=duration, context=context, sinks=sinks)


def _bits(values: Any) -> bytes:
    return np.asarray(values, dtype="<f8").tobytes()


def _stamp(header: Any) -> int:
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def _columns(batches: list[Any], group: str) -> tuple[list[str], list[str], np.ndarray]:
    """Names, units and (samples, columns) values of one group of rclpy SampleBatch
    messages, joined."""
    first = getattr(batches[0], group)
    names = [s.name for s in first]
    units = [s.unit for s in first]
    columns = [np.concatenate([np.asarray(getattr(b, group)[j].values) for b in batches])
               for j in range(len(names))]
    samples = sum(len(b.stamps) for b in batches)
    return names, units, np.array(columns).T if columns else np.empty((samples, 0))


SYSTEMS = ("pendulum", "double_pendulum", "kepler", "rigid_body", "driven_oscillator")


@pytest.mark.parametrize("system,paced", [*((s, False) for s in SYSTEMS),
                                          ("pendulum", True)])
def test_the_batch_columns_equal_the_per_sample_messages_bit_for_bit(
        ros_context: Any, system: str, paced: bool) -> None:
    """Every sample of the run is in exactly one batch, in order, and each column holds the
    per-sample topics' values of those samples bit for bit (stamps, coordinates and rates,
    the six energy terms, each invariant and observable by name); a paced run releases its
    samples in small groups, each a batch."""
    from geometry_msgs.msg import PoseStamped, TwistStamped
    from sensor_msgs.msg import JointState

    from mechsim.outputs.messages import DEFAULT_TIME_OFFSET, stamps_ns
    from mechsim.systems import system_class
    from mechsim_msgs.msg import Energy, NamedScalars, SampleBatch

    cap = _Capture()
    run = _run(system, ros_context, 3.0 if paced else 15.0, paced=paced, sinks=[cap])
    assert not run.failures
    ns = f"/{system}"
    batches = cap.messages(f"{ns}/sample_batch", SampleBatch)
    energy = cap.messages(f"{ns}/energy", Energy)
    samples = run.samples[system]
    assert len(energy) == samples and sum(len(b.stamps) for b in batches) == samples
    assert len(batches) > (10 if paced else 2)  # one per released block
    stamps = np.array([s.sec * 1_000_000_000 + s.nanosec for b in batches for s in b.stamps])
    assert stamps.tolist() == [_stamp(m.header) for m in energy]
    assert [_stamp(b.header) for b in batches] == [
        s.sec * 1_000_000_000 + s.nanosec for s in (b.stamps[0] for b in batches)]
    time = np.concatenate([np.asarray(b.time) for b in batches])
    assert stamps_ns(time, DEFAULT_TIME_OFFSET).tolist() == stamps.tolist()

    names, units, terms = _columns(batches, "energy")
    assert names == ["kinetic", "potential", "total", "energy_function", "work_external",
                     "work_dissipated"] and set(units) == {"J"}
    for j, field in enumerate(names):
        assert _bits(terms[:, j]) == _bits([getattr(m, field) for m in energy]), field

    model = system_class(system)()
    coords, coord_units, q = _columns(batches, "positions")
    rate_names, rate_units, v = _columns(batches, "velocities")
    assert coords == rate_names == [c.name for c in model.coordinates]
    assert coord_units == [c.unit for c in model.coordinates]
    assert rate_units == [f"{u}/s" if u else "1/s" for u in coord_units]
    state = cap.messages(f"{ns}/state", JointState)
    if state:
        joints = [coords.index(n) for n in state[0].name]
        assert _bits(q[:, joints]) == _bits([m.position for m in state])
        assert _bits(v[:, joints]) == _bits([m.velocity for m in state])
    if model.attitude is not None:
        pose = cap.messages(f"{ns}/pose", PoseStamped)
        twist = cap.messages(f"{ns}/twist", TwistStamped)
        o = [m.pose.orientation for m in pose]
        assert _bits(model.attitude.orientation(q)) == _bits([[x.x, x.y, x.z, x.w] for x in o])
        w = [m.twist.angular for m in twist]
        assert _bits(model.attitude.angular_velocity(q, v)) == _bits([[x.x, x.y, x.z]
                                                                      for x in w])
    for group in ("invariants", "observables"):
        named = cap.messages(f"{ns}/{group}", NamedScalars)
        names, units, values = _columns(batches, group)
        assert len(named) == (samples if names else 0)
        for m in named[:1]:
            assert names == [s.name for s in m.scalars]
            assert units == [s.unit for s in m.scalars]
        if names:
            assert _bits(values) == _bits([[s.value for s in m.scalars] for m in named])


def test_the_numpy_decoder_gives_the_batch_rclpy_deserializes(ros_context: Any) -> None:
    """``batch.decode`` (numpy, no message objects) against rclpy's deserializer, column by
    column; ``joined`` keeps the order."""
    from mechsim.outputs.batch import GROUPS, decode, joined
    from mechsim_msgs.msg import SampleBatch

    cap = _Capture()
    _run("rigid_body", ros_context, 12.0, sinks=[cap])
    data = cap.data["/rigid_body/sample_batch"]
    msgs = cap.messages("/rigid_body/sample_batch", SampleBatch)
    mine = joined(decode(d) for d in data)
    assert mine.stamps.dtype == np.int64
    assert mine.stamps.tolist() == [s.sec * 1_000_000_000 + s.nanosec
                                    for m in msgs for s in m.stamps]
    assert _bits(mine.time) == _bits(np.concatenate([m.time for m in msgs]))
    for group in GROUPS:
        names, units, values = _columns(msgs, group)
        series = getattr(mine, group)
        assert list(series.names) == names and list(series.units) == units, group
        assert _bits(series.values) == _bits(values), group
        for j, name in enumerate(names):
            assert _bits(series[name]) == _bits(values[:, j])


def test_a_malformed_batch_is_one_error_in_bounded_time() -> None:
    """Cut short, a count larger than the bytes, a string without its NUL, columns of
    different lengths: each a MechsimError naming the problem, never a huge allocation."""
    from mechsim.errors import MechsimError
    from mechsim.outputs.batch import decode
    from mechsim.outputs.wire import encode

    good = encode("mechsim_msgs/msg/SampleBatch", {
        "header": {"stamp": (1, 0), "frame_id": "world"},
        "stamps": [(1, 0), (1, 10_000_000)], "time": [0.0, 0.01],
        "positions": [("theta", "rad", [0.1, 0.2])], "velocities": [("theta", "rad/s",
                                                                   [0.0, 0.5])],
        "energy": [], "invariants": [], "observables": []})
    assert decode(good).positions["theta"].tolist() == [0.1, 0.2]
    huge = bytearray(good)
    huge[24:28] = (2**32 - 1).to_bytes(4, "little")  # the stamps' count
    bad = {"cut short": good[:-3], "a huge count": bytes(huge), "big endian": b"\x00\x00"
           + good[2:], "uneven columns": encode("mechsim_msgs/msg/SampleBatch", {
               "header": {"stamp": (1, 0), "frame_id": ""}, "stamps": [(1, 0)],
               "time": [0.0], "positions": [("x", "m", [1.0, 2.0])], "velocities": [],
               "energy": [], "invariants": [], "observables": []})}
    for what, data in bad.items():
        with pytest.raises(MechsimError, match="sample batch"):
            decode(data)
            pytest.fail(what)


def test_a_time_sequence_given_as_a_record_array_is_encoded_as_its_messages() -> None:
    """The wire encoder copies a numpy record array into a sequence of a flat type
    (builtin_interfaces/Time[]): the same bytes as rclpy's serializer of the messages."""
    from builtin_interfaces.msg import Time
    from rclpy.serialization import deserialize_message, serialize_message

    from mechsim.outputs.batch import TIME_RECORD
    from mechsim.outputs.wire import encode
    from mechsim_msgs.msg import SampleBatch

    stamps = np.zeros(5, TIME_RECORD)
    stamps["sec"] = [1, 2, -3, 2**31 - 1, 0]
    stamps["nanosec"] = [0, 999_999_999, 5, 7, 2**32 - 1]
    msg = SampleBatch(stamps=[Time(sec=int(s), nanosec=int(n)) for s, n in stamps.tolist()],
                      time=[0.5] * 5)
    msg.header.frame_id = "w"
    data = encode("mechsim_msgs/msg/SampleBatch", {
        "header": {"stamp": (0, 0), "frame_id": "w"}, "stamps": stamps,
        "time": np.full(5, 0.5), "positions": [], "velocities": [], "energy": [],
        "invariants": [], "observables": []})
    assert data == encode("mechsim_msgs/msg/SampleBatch", msg)  # the messages one by one
    assert deserialize_message(data, SampleBatch) == msg  # rclpy's reading of the bytes
    assert len(serialize_message(msg)) >= len(data)


def test_a_bag_records_what_the_scene_asks_and_the_helper_reads_its_batches(
        tmp_path: Path) -> None:
    """bag_topics samples (the default): no batches; batches: the batches instead of the
    per-sample topics (system_info, /tf_static, /diagnostics kept); both: all. The batches
    read from the bag (``read_batches``) hold the per-sample messages' values of the other
    bag."""
    from rclpy.serialization import deserialize_message

    from mechsim.outputs.bag import read_messages
    from mechsim.outputs.batch import joined, read_batches
    from mechsim.ros.record import run_with_outputs
    from mechsim.scene import parse_scene
    from mechsim_msgs.msg import Energy

    topics = {}
    for what in ("samples", "batches", "both"):
        scene = parse_scene({"name": "k", "outputs": {"bag_topics": what},
                             "systems": [{"system": "kepler"}]})
        run_with_outputs(scene, fast=True, duration=12.0, bag=str(tmp_path / what))
        topics[what] = {m.topic for m in read_messages(tmp_path / what)}
    assert "/kepler/sample_batch" not in topics["samples"]
    assert {"/kepler/state", "/kepler/energy", "/clock", "/tf"} <= topics["samples"]
    # (the latched look, as system_info and /tf_static: recorded whatever the choice)
    assert topics["batches"] == {"/kepler/sample_batch", "/kepler/system_info",
                                 "/kepler/markers_static", "/diagnostics"} | (
        {"/tf_static"} & topics["samples"])
    assert topics["both"] == topics["samples"] | {"/kepler/sample_batch"}
    batch = joined(b for _, b in read_batches(tmp_path / "batches"))
    assert list(read_batches(tmp_path / "samples")) == []
    energy = [deserialize_message(m.data, Energy)
              for m in read_messages(tmp_path / "samples", ["/kepler/energy"])]
    assert batch.stamps.tolist() == [_stamp(m.header) for m in energy]
    assert _bits(batch.energy["total"]) == _bits([m.total for m in energy])
    assert _bits(batch.energy["work_dissipated"]) == _bits([m.work_dissipated
                                                            for m in energy])


def test_the_helper_names_an_instance_s_batch_topic_or_takes_one_as_given() -> None:
    from mechsim.ros.batches import batch_topic

    assert batch_topic("pendulum") == "/pendulum/sample_batch"
    assert batch_topic("/lab/swing/") == "/lab/swing/sample_batch"
    assert batch_topic("/swing/sample_batch") == "/swing/sample_batch"
    assert batch_topic("sample_batch") == "sample_batch"  # relative, as ROS resolves it


def test_a_bad_bag_topics_is_refused_in_one_line() -> None:
    from mechsim.errors import ParameterError
    from mechsim.scene import parse_scene

    with pytest.raises(ParameterError, match=r"outputs.bag_topics: got 'batch': did you "
                                             r"mean 'batches'\?"):
        parse_scene({"outputs": {"bag_topics": "batch"}, "systems": [{"system": "kepler"}]})
    out = subprocess.run([sys.executable, "-m", "mechsim.cli", "record", "kepler",
                          "--duration", "1", "--bag-topics", "every"],
                         capture_output=True, text=True, timeout=DEADLINE)
    assert out.returncode == 2
    assert out.stderr.strip().splitlines() == [
        "mechsim: error: --bag-topics: got 'every' (choices: batches, both, samples)"]


#: A consumer in another process: the per-sample topics it is given and the batch topic,
#: counted (distinct stamps) and, for the batches, decoded with the helper and saved. It
#: stops once the batches and every topic hold the samples expected, or at the deadline.
_CONSUMER = """
import json, sys, time
import numpy as np
from mechsim.outputs.batch import joined
from mechsim.ros.batches import subscribe_batches
from mechsim.environment import import_rclpy
rclpy = import_rclpy()
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from mechsim.outputs.wire import message_class
topics, out = json.loads(sys.argv[1]), sys.argv[2]
expected, deadline = int(sys.argv[3]), time.monotonic() + float(sys.argv[4])
with subscribe_batches("swing") as sub:
    qos = QoSProfile(depth=1, history=HistoryPolicy.KEEP_ALL,
                     reliability=ReliabilityPolicy.RELIABLE)
    stamps = {t: [] for t in topics}
    def keep(t, cls):
        def got(data):
            h = deserialize_message(data, cls).header.stamp
            stamps[t].append(h.sec * 1_000_000_000 + h.nanosec)
        return got
    for t, type_name in topics.items():
        sub.node.create_subscription(message_class(type_name), t,
                                     keep(t, message_class(type_name)), qos, raw=True)
    print("ready", flush=True)
    got = []
    def short():
        return (sum(len(b) for b in got) < expected
                or any(len(s) < expected for s in stamps.values()))
    while short() and time.monotonic() < deadline:
        got += [b for _, b in sub.take(timeout=0.1)]
b = joined(got)
np.savez(out, stamps=b.stamps, time=b.time, theta=b.positions["angle"],
         omega=b.velocities["angle"], total=b.energy["total"], tension=b.observables["tension"])
print(json.dumps({"batches": len(got), "per_sample": {t: [len(s), len(set(s))]
                                                       for t, s in stamps.items()}}),
      flush=True)
"""


def _line(proc: subprocess.Popen[str], timeout: float = DEADLINE) -> str:
    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], timeout)
    assert ready, f"no line from the consumer within {timeout:g} s"
    return proc.stdout.readline().strip()


def test_lossless_delivers_every_sample_of_every_topic_with_several_slices_in_flight(
        ros_context: Any, ros_env: dict[str, str], tmp_path: Path) -> None:
    """A consumer in another process subscribes to the per-sample topics and, through the
    helper, to the batches of a fast lossless run. It is stopped (SIGSTOP) until the node
    has published more than one slice without an acknowledgment (so they are in flight
    together), then continues: every sample arrives once on every topic, and the helper's
    arrays equal the values the node published sample by sample."""
    from sensor_msgs.msg import JointState

    from mechsim.outputs.messages import DEFAULT_TIME_OFFSET, stamps_ns
    from mechsim.ros.launch import run_scene
    from mechsim.ros.outlet import LOSSLESS_DEPTH
    from mechsim.scene import parse_scene
    from mechsim_msgs.msg import Energy, NamedScalars

    per_sample = {"/swing/state": "sensor_msgs/msg/JointState",
                  "/swing/energy": "mechsim_msgs/msg/Energy",
                  "/swing/observables": "mechsim_msgs/msg/NamedScalars"}
    out = tmp_path / "batches.npz"
    samples = 6001  # 60 s at 100 Hz, both ends
    consumer = subprocess.Popen([sys.executable, "-c", _CONSUMER, json.dumps(per_sample),
                                 str(out), str(samples), str(DEADLINE)], env=ros_env,
                                stdout=subprocess.PIPE, text=True)
    stopped = [False]
    peak = [0]
    nodes: list[Any] = []
    try:
        assert _line(consumer) == "ready"
        scene = parse_scene({"name": "lossless", "pacing": "fast", "publish_rate": 100.0,
                             "systems": [{"system": "pendulum", "name": "swing"}]})

        def matched(node: Any) -> None:
            """Before the first sample: every topic matched, then the consumer stopped."""
            from rclpy.executors import SingleThreadedExecutor

            nodes.append(node)
            pubs = [node.outlet.channels[t].publisher
                    for t in [*per_sample, "/swing/sample_batch"]]
            ex = SingleThreadedExecutor(context=ros_context)
            try:
                assert wait_until(ex, lambda: all(p.get_subscription_count() for p in pubs),
                                  DEADLINE), "the consumer never matched"
            finally:
                ex.shutdown()
            os.kill(consumer.pid, signal.SIGSTOP)
            stopped[0] = True

        def progress(t: float, duration: float) -> None:
            outlet = nodes[0].outlet
            peak[0] = max(peak[0], outlet.in_flight)
            if stopped[0] and outlet.in_flight > 2 * LOSSLESS_DEPTH:
                os.kill(consumer.pid, signal.SIGCONT)
                stopped[0] = False

        cap = _Capture()
        run = run_scene(scene, fast=True, duration=60.0, context=ros_context, lossless=True,
                        before_first_message=matched, progress=progress, sinks=[cap])
        if stopped[0]:
            os.kill(consumer.pid, signal.SIGCONT)
        assert not run.failures
        assert peak[0] > 2 * LOSSLESS_DEPTH  # three slices out, none acknowledged
        report = json.loads(_line(consumer))
    finally:
        if consumer.poll() is None:
            os.kill(consumer.pid, signal.SIGCONT)
            consumer.kill()
        consumer.wait()
    assert run.samples["swing"] == samples
    assert report["per_sample"] == {t: [samples, samples] for t in per_sample}
    assert report["batches"] == run.messages["/swing/sample_batch"]
    got = np.load(out)
    assert got["stamps"].tolist() == sorted(set(got["stamps"].tolist()))
    state = cap.messages("/swing/state", JointState)
    energy = cap.messages("/swing/energy", Energy)
    observables = cap.messages("/swing/observables", NamedScalars)
    assert got["stamps"].tolist() == [_stamp(m.header) for m in state]
    assert stamps_ns(got["time"], DEFAULT_TIME_OFFSET).tolist() == got["stamps"].tolist()
    assert _bits(got["theta"]) == _bits([m.position[0] for m in state])
    assert _bits(got["omega"]) == _bits([m.velocity[0] for m in state])
    assert _bits(got["total"]) == _bits([m.total for m in energy])
    tension = [next(s.value for s in m.scalars if s.name == "tension") for m in observables]
    assert _bits(got["tension"]) == _bits(tension)
