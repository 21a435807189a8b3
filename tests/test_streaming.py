"""The batched sample pipeline: reproducible bytes, lossless counts, the paced clock, services
served during a fast run, and the diagnostics node's chunk feed."""

from __future__ import annotations

import math
import threading
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from mechsim.outputs.sink import Capabilities, Takes  # noqa: E402
from mechsim.testing import wait_until

REPO = Path(__file__).resolve().parents[1]
DEADLINE = 120.0


def _mcap_messages(path: Path) -> list[tuple[str, int, bytes]]:
    """(topic, log time, payload) of every message, in file order, read with the mcap
    library's reader (independent of the writer)."""
    from mcap.reader import make_reader

    with open(path / f"{path.name}_0.mcap", "rb") as f:
        return [(ch.topic, m.log_time, bytes(m.data))
                for _, ch, m in make_reader(f).iter_messages(log_time_order=True)]


def _record(path: Path, duration: float) -> Any:
    from mechsim.ros import record
    from mechsim.scene import scene_from_target

    scene = scene_from_target(str(REPO / "scenes" / "default.yaml"), [])
    run, _ = record.run_with_outputs(scene, fast=True, duration=duration, bag=str(path))
    return run


def test_identical_runs_give_identical_bytes_and_lossless_counts(tmp_path: Path) -> None:
    """Two fast recordings of the same scene hold byte-identical payloads on every topic
    (/diagnostics included: a fast run's reports have no wall-clock content), and the counts
    agree: published (SceneRun.messages) == metadata.yaml == an independent reader."""
    from rosbags.highlevel import AnyReader

    # 12 s: several fast chunks, several diagnostics reports inside one chunk.
    runs = [_record(tmp_path / f"run{i}", 12.0) for i in range(2)]
    bags = [_mcap_messages(tmp_path / f"run{i}") for i in range(2)]
    assert len(bags[0]) == len(bags[1]) > 0
    topics = {t for t, _, _ in bags[0]}
    for topic in ("/diagnostics", "/tf_static", "/pendulum/system_info", "/clock",
                  "/pendulum/state", "/kepler/energy", "/tf"):
        assert topic in topics, topic
    for topic in sorted(topics):
        a = [(ts, d) for t, ts, d in bags[0] if t == topic]
        b = [(ts, d) for t, ts, d in bags[1] if t == topic]
        assert a == b, f"{topic}: the two runs differ"
    for i, run in enumerate(runs):
        path = tmp_path / f"run{i}"
        published = {t: n for t, n in run.messages.items() if n}
        meta = yaml.safe_load((path / "metadata.yaml").read_text())[
            "rosbag2_bagfile_information"]
        meta_counts = {t["topic_metadata"]["name"]: t["message_count"]
                       for t in meta["topics_with_message_count"]}
        with AnyReader([path]) as reader:
            read = Counter(con.topic for con, _, _ in reader.messages())
        assert published == meta_counts == dict(read) == dict(Counter(t for t, _, _ in bags[i]))
        # Every sample of the 12 s, once: t = 0, 0.01, ..., 12.0.
        assert published["/pendulum/state"] == 1201
        assert published["/diagnostics"] >= 12


class _Capture:
    """A sink keeping (topic, stamp) of every message handed to it."""

    capabilities = Capabilities()

    def __init__(self) -> None:
        self.items: list[tuple[str, int]] = []

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        self.items.append((topic, ns))


def test_paced_run_keeps_clock_monotone_and_stamps_on_the_sample_grid(ros_context: Any
                                                                       ) -> None:
    from mechsim.outputs.messages import DEFAULT_TIME_OFFSET
    from mechsim.ros.launch import run_scene
    from mechsim.scene import parse_scene

    scene = parse_scene({"name": "paced", "pacing": "realtime", "real_time_factor": 2.0,
                         "publish_rate": 100.0,
                         "systems": [{"system": "pendulum"},
                                     {"system": "rigid_body", "origin": [2.0, 0.0, 0.0]}]})
    capture = _Capture()
    run = run_scene(scene, duration=1.0, sinks=[capture], context=ros_context)
    assert not run.failures and not run.interrupted
    offset = int(DEFAULT_TIME_OFFSET * 1e9)
    period = 10_000_000
    clock = [ns for t, ns in capture.items if t == "/clock"]
    # Every sample of the second, in order, each once: monotone, nothing skipped.
    assert clock == [offset + k * period for k in range(101)]
    sampled = [(t, ns) for t, ns in capture.items
               if t.rpartition("/")[2] in ("state", "energy", "invariants", "observables",
                                           "pose", "twist", "tf")]
    assert {t for t, _ in sampled} >= {"/pendulum/state", "/rigid_body/pose", "/tf"}
    for topic, ns in sampled:
        assert (ns - offset) % period == 0 and 0 <= ns - offset <= 100 * period, (topic, ns)
    grid = [offset + k * period for k in range(101)]
    for topic in {t for t, _ in sampled} - {"/tf"}:
        stamps = [ns for t, ns in sampled if t == topic]
        assert stamps == grid, topic  # one node's topic: every sample once, in order
    tf = Counter(ns for t, ns in sampled if t == "/tf")  # both systems publish /tf
    assert sorted(tf) == grid and set(tf.values()) == {2}


def test_reset_pause_and_parameters_answered_during_a_fast_run(ros_context: Any) -> None:
    """Services and a parameter set are served between the chunks of a fast run (no wall-clock
    target: a generous deadline)."""
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_srvs.srv import SetBool, Trigger

    from mechsim.ros.launch import run_scene
    from mechsim.scene import parse_scene

    scene = parse_scene({"name": "busy", "pacing": "fast", "publish_rate": 100.0,
                         "systems": [{"system": "pendulum", "name": "busy"}]})
    stop = threading.Event()
    reached: list[float] = []
    result: dict[str, Any] = {}

    def progress(t: float, duration: float) -> None:
        reached.append(t)
        if stop.is_set():
            raise KeyboardInterrupt  # the run's own stop path

    def body() -> None:
        result["run"] = run_scene(scene, fast=True, duration=1e7, context=ros_context,
                                  progress=progress)

    runner = threading.Thread(target=body, daemon=True)
    runner.start()
    probe = Node("busy_probe", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(probe)
    try:
        def wait(done: Any, what: str) -> None:
            def answered() -> bool:
                assert runner.is_alive(), "the run ended"
                return bool(done())

            assert wait_until(ex, answered, DEADLINE), f"no answer: {what}"

        pause = probe.create_client(SetBool, "/busy/simulator/pause")
        reset = probe.create_client(Trigger, "/busy/simulator/reset")
        params = probe.create_client(SetParameters, "/busy/simulator/set_parameters")
        wait(lambda: pause.service_is_ready() and reset.service_is_ready()
             and params.service_is_ready() and len(reached) > 2, "services")
        fut = reset.call_async(Trigger.Request())
        wait(fut.done, "~/reset")
        assert fut.result().success
        req = SetParameters.Request(parameters=[Parameter(name="gravity", value=ParameterValue(
            type=ParameterType.PARAMETER_DOUBLE, double_value=3.0))])
        fut = params.call_async(req)
        wait(fut.done, "set_parameters")
        assert fut.result().results[0].successful
        fut = pause.call_async(SetBool.Request(data=True))
        wait(fut.done, "~/pause")
        assert fut.result().success
        assert runner.is_alive()  # answered while the fast run went on
    finally:
        stop.set()
        runner.join(DEADLINE)
        ex.shutdown()
        probe.destroy_node()
    assert not runner.is_alive() and result["run"].interrupted


def test_every_node_of_a_scene_serves_its_parameters(ros_context: Any) -> None:
    """A scene of more nodes than get their parameter services per chunk: every node comes to
    serve all six parameter services (made once the samples flow), and answers with its own
    values."""
    from rcl_interfaces.srv import GetParameters
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from mechsim.ros.launch import PARAMETER_SERVICES_PER_CHUNK, run_scene
    from mechsim.scene import parse_scene

    n = 2 * PARAMETER_SERVICES_PER_CHUNK + 3
    scene = parse_scene({"name": "many", "pacing": "fast", "publish_rate": 100.0,
                         "systems": [{"system": "pendulum", "name": f"m{i}",
                                      "parameters": {"length": 1.0 + i / 8}}
                                     for i in range(n)]})
    stop = threading.Event()
    result: dict[str, Any] = {}

    def progress(t: float, duration: float) -> None:
        if stop.is_set():
            raise KeyboardInterrupt  # the run's own stop path

    def body() -> None:
        result["run"] = run_scene(scene, fast=True, duration=1e7, context=ros_context,
                                  progress=progress, graph_wait=0)

    runner = threading.Thread(target=body, daemon=True)
    runner.start()
    probe = Node("many_probe", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(probe)
    services = ("describe_parameters", "get_parameter_types", "get_parameters",
                "list_parameters", "set_parameters", "set_parameters_atomically")
    try:
        def served() -> bool:
            assert runner.is_alive(), "the run ended"
            names = {s for s, _ in probe.get_service_names_and_types()}
            return all(f"/m{i}/simulator/{s}" in names for i in range(n) for s in services)

        assert wait_until(ex, served, DEADLINE), "parameter services missing"
        for i in (0, n - 1):
            client = probe.create_client(GetParameters, f"/m{i}/simulator/get_parameters")
            assert wait_until(ex, client.service_is_ready, DEADLINE)
            fut = client.call_async(GetParameters.Request(names=["length"]))
            assert wait_until(ex, fut.done, DEADLINE), f"/m{i}: no answer"
            assert fut.result().values[0].double_value == 1.0 + i / 8
    finally:
        stop.set()
        runner.join(DEADLINE)
        ex.shutdown()
        probe.destroy_node()
    run = result["run"]
    assert not runner.is_alive() and run.interrupted
    # (a fast scene makes every node's after its first chunk, and says when)
    assert run.parameters_served_time is not None
    assert run.parameters_served_time >= run.startup_time


def test_chunk_feed_tracks_drift_and_epochs(ros_context: Any) -> None:
    """A chunk of energy samples whose stamps go back in the middle (a reset): the law
    re-bases there; drifts are |E - E0| / scale of the new epoch; a non-finite sample counts
    and makes the level ERROR until a finite one follows."""
    from mechsim.outputs.messages import EnergyColumns
    from mechsim.ros.diagnostics import DiagnosticsNode
    from mechsim_msgs.msg import SystemInfo

    diag = DiagnosticsNode(context=ros_context, period=3600.0, stale_timeout=3600.0,
                           discover=False)
    try:
        diag.feed("/s", "system_info", SystemInfo(instance="s", system="x",
                                                  laws=["energy"], law_scales=[2.0]))
        total = np.array([1.0, 1.1, 0.9, 5.0, 5.2, math.nan])
        zero = np.zeros_like(total)
        stamps = np.array([10, 20, 30, 10, 20, 30], dtype=np.int64)
        diag.feed_chunk("/s", "energy", stamps,
                        EnergyColumns(total, zero, total, total, zero, zero))
        st = diag.systems["/s"]
        law = st.laws["energy"]
        assert st.epoch == 1 and law.samples == 6 and law.nonfinite == 1
        assert law.initial == 5.0 and law.max_drift == pytest.approx(0.2 / 2.0)
        assert law.worst == math.inf and diag.level(law, False) == 2
        diag.feed_chunk("/s", "energy", np.array([40], dtype=np.int64),
                        EnergyColumns(*(np.array([v]) for v in (5.1, 0.0, 5.1, 5.1, 0, 0))))
        assert law.drift == pytest.approx(0.05) and diag.level(law, False) == 2  # 0.1 ≥ 1e-3
        assert st.epoch == 1 and law.nonfinite == 1
    finally:
        diag.destroy_node()


def test_mcap_batches_read_back_by_the_mcap_library(tmp_path: Path) -> None:
    """Messages written a batch at a time (and one at a time) come back from the mcap
    library's reader, through the chunk indexes and message indexes and by a plain scan, with
    their stamps, payloads and the summary statistics."""
    from mcap.reader import make_reader
    from mcap.stream_reader import StreamReader

    from mechsim.outputs.bag.mcapfile import McapFile

    rng = np.random.default_rng(1)
    f = tmp_path / "x.mcap"
    expected: list[tuple[str, int, bytes]] = []
    with open(f, "wb") as stream:
        w = McapFile(stream, chunk_size=4000, scratch=tmp_path)
        w.start("ros2", "test")
        sid = w.register_schema("pkg/msg/T", "ros2msg", b"float64 x")
        a = w.register_channel("/a", "cdr", sid, {})
        b = w.register_channel("/b", "cdr", sid, {"k": "v"})
        for k in range(5):
            ns = np.arange(k * 30, k * 30 + 30, dtype=np.int64) * 1000 + 7
            ra = rng.integers(0, 256, (30, 12), dtype=np.uint8)
            rb = rng.integers(0, 256, (30, 37), dtype=np.uint8)
            w.add_batch(ns, [(a, ra), (b, rb)])
            for i in range(30):
                expected += [("/a", int(ns[i]), ra[i].tobytes()), ("/b", int(ns[i]),
                                                                     rb[i].tobytes())]
            w.add_message(b, int(ns[-1]) + 1, b"single")
            expected.append(("/b", int(ns[-1]) + 1, b"single"))
            if k == 2:
                w.flush()
        w.add_metadata("m", {"x": "y"})
        w.finish()
    with open(f, "rb") as stream:
        reader = make_reader(stream)
        got = [(ch.topic, m.log_time, bytes(m.data)) for _, ch, m in reader.iter_messages()]
        summary = reader.get_summary()
    assert got == expected  # file order is time order here
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count == len(expected)
    assert dict(summary.statistics.channel_message_counts) == {a: 150, b: 155}
    assert len(summary.chunk_indexes) >= 3 and summary.channels[b].metadata == {"k": "v"}
    with open(f, "rb") as stream:  # a scan of every record (chunks opened), CRCs checked
        records = list(StreamReader(stream, validate_crcs=True).records)
    assert [(r.log_time, bytes(r.data)) for r in records if type(r).__name__ == "Message"] \
        == [(ts, d) for _, ts, d in expected]


class _Messages:
    """A sink keeping (topic, stamp, message) of the state and energy messages."""

    capabilities = Capabilities()

    def __init__(self) -> None:
        self.items: list[tuple[str, int, Any]] = []

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        if topic.rpartition("/")[2] in ("state", "energy"):
            self.items.append((topic, ns, msg))


def test_paced_parameter_set_applies_from_the_next_sample(ros_context: Any) -> None:
    """A paced node computes samples ahead of the wall clock; a parameter set arriving
    meanwhile drops them: every energy published after the change is the new gravity's
    V = m g R (1 − cos φ) of its own state, every one before it the old one's, and the
    samples stay on the grid (the current one published again: the new epoch)."""
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from mechsim.ros.launch import run_scene
    from mechsim.scene import parse_scene

    scene = parse_scene({"name": "paced_change", "pacing": "realtime",
                         "real_time_factor": 1.0, "publish_rate": 100.0,
                         "systems": [{"system": "pendulum", "name": "swing"}]})
    sink = _Messages()
    result: dict[str, Any] = {}
    runner = threading.Thread(target=lambda: result.update(run=run_scene(
        scene, duration=4.0, sinks=[sink], context=ros_context)), daemon=True)
    runner.start()
    probe = Node("paced_probe", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(probe)
    try:
        params = probe.create_client(SetParameters, "/swing/simulator/set_parameters")
        assert wait_until(ex, lambda: params.service_is_ready() and len(sink.items) > 40
                          and runner.is_alive(), DEADLINE)
        fut = params.call_async(SetParameters.Request(parameters=[Parameter(
            name="gravity", value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                                 double_value=3.0))]))
        assert wait_until(ex, fut.done, DEADLINE)
        assert fut.result().results[0].successful
    finally:
        runner.join(DEADLINE)
        ex.shutdown()
        probe.destroy_node()
    run = result["run"]
    assert not run.failures and not run.interrupted
    states = [(ns, m) for t, ns, m in sink.items if t == "/swing/state"]
    energies = [(ns, m) for t, ns, m in sink.items if t == "/swing/energy"]
    stamps = [ns for ns, _ in states]
    assert stamps == [ns for ns, _ in energies]
    again = [i for i in range(1, len(stamps)) if stamps[i] <= stamps[i - 1]]
    assert len(again) == 1, "one new epoch: the current sample published again"
    change = again[0]
    assert stamps[change] == stamps[change - 1]
    assert states[change][1].position[0] == states[change - 1][1].position[0]
    period = 10_000_000
    grid = sorted(set(stamps))
    assert grid == [grid[0] + k * period for k in range(len(grid))] and len(grid) == 401
    m, R = 1.0, 1.0
    for i, ((_, state), (_, energy)) in enumerate(zip(states, energies, strict=True)):
        g = 9.81 if i < change else 3.0
        phi = state.position[0]
        assert energy.potential == pytest.approx(m * g * R * (1 - math.cos(phi)),
                                                 rel=1e-12, abs=1e-12), (i, change)
    assert change < len(states) - 50, "the change came early enough to test what follows"


class _Chunks:
    """A sink taking chunks of CDR rows (as the recorder does): the stamps of each hand-off
    per topic, and the number of hand-offs."""

    capabilities = Capabilities(Takes.BYTES)

    def __init__(self) -> None:
        self.handoffs = 0
        self.stamps: dict[str, list[int]] = {}

    def write_rows(self, ns: Any, topics: list[tuple[str, str, Any, Any]]) -> None:
        self.handoffs += 1
        for topic, _, _, rows in topics:
            assert len(rows) == len(ns), topic
            self.stamps.setdefault(topic, []).extend(int(x) for x in ns)

    def write_bytes(self, topic: str, type_name: str, qos: Any, ns: int, data: bytes) -> None:
        pass


def test_paced_run_hands_sinks_whole_blocks_of_every_sample(ros_context: Any) -> None:
    """A paced run publishes a sample or two per node and tick, but a chunk sink gets them a
    block at a time (the samples computed ahead), every one once and in order: the hand-offs
    are far fewer than the samples, and the stamps of each node's topics are the whole grid."""
    from mechsim.outputs.messages import DEFAULT_TIME_OFFSET
    from mechsim.ros.launch import run_scene
    from mechsim.scene import parse_scene

    scene = parse_scene({"name": "blocks", "pacing": "realtime", "real_time_factor": 2.0,
                         "publish_rate": 100.0,
                         "systems": [{"system": "pendulum"},
                                     {"system": "kepler", "origin": [2.0, 0.0, 0.0]}]})
    sink = _Chunks()
    run = run_scene(scene, duration=2.0, sinks=[sink], context=ros_context)
    assert not run.failures and not run.interrupted
    offset = int(DEFAULT_TIME_OFFSET * 1e9)
    grid = [offset + k * 10_000_000 for k in range(201)]
    for topic in ("/clock", "/pendulum/state", "/pendulum/energy", "/kepler/state",
                  "/kepler/invariants"):
        assert sink.stamps[topic] == grid, topic
    assert sorted(sink.stamps["/tf"]) == sorted(grid * 2)
    published = {t: n for t, n in run.messages.items() if n}
    assert {t: len(s) for t, s in sink.stamps.items()} == {
        t: n for t, n in published.items() if t in sink.stamps}
    samples = sum(run.samples.values())
    assert samples == 2 * 201
    # One hand-off per block of samples computed ahead (``LOOKAHEAD`` wall seconds: 200), plus
    # the ones a diagnostics report or the end of the run makes: not one per tick.
    assert sink.handoffs <= samples / 10, sink.handoffs


def test_paced_recording_holds_every_sample_as_a_fast_one(tmp_path: Path) -> None:
    """A paced recording and a fast one of the same scene: the same messages on every topic
    (counts: published == metadata.yaml == read back), each node's topics in time order on
    the sample grid with the same stamps, the same states and energies (the integration
    runs in blocks of another length: equal to round-off)."""
    from rosbags.highlevel import AnyReader

    from mechsim.ros import record
    from mechsim.scene import parse_scene

    scene = parse_scene({"name": "paced_bag", "pacing": "realtime", "real_time_factor": 2.0,
                         "publish_rate": 100.0,
                         "systems": [{"system": "pendulum"},
                                     {"system": "rigid_body", "origin": [2.0, 0.0, 0.0]},
                                     {"system": "kepler", "origin": [4.0, 0.0, 0.0]}]})
    read: dict[str, dict[str, list[tuple[int, list[float]]]]] = {}
    for mode in ("paced", "fast"):
        path = tmp_path / mode
        run, _ = record.run_with_outputs(scene, fast=mode == "fast", duration=2.0,
                                         bag=str(path))
        assert not run.failures and not run.interrupted
        published = {t: n for t, n in run.messages.items() if n}
        meta = yaml.safe_load((path / "metadata.yaml").read_text())[
            "rosbag2_bagfile_information"]
        assert published == {t["topic_metadata"]["name"]: t["message_count"]
                             for t in meta["topics_with_message_count"]}, mode
        got: dict[str, list[tuple[int, list[float]]]] = {}
        with AnyReader([path]) as reader:  # file order
            for con, ns, raw in reader.messages():
                values: list[float] = []
                leaf = con.topic.rpartition("/")[2]
                if leaf in ("state", "energy", "pose"):
                    m = reader.deserialize(raw, con.msgtype)
                    values = (list(m.position) + list(m.velocity) if leaf == "state" else
                              [m.kinetic, m.potential, m.total] if leaf == "energy" else
                              [m.pose.orientation.x, m.pose.orientation.y,
                               m.pose.orientation.z, m.pose.orientation.w])
                got.setdefault(con.topic, []).append((ns, values))
        assert {t: len(v) for t, v in got.items()} == published, mode
        read[mode] = got
    paced, fast = read["paced"], read["fast"]
    assert set(paced) == set(fast)
    grid = [s for s, _ in fast["/clock"]]
    assert len(grid) == 201 and grid == sorted(grid)
    for topic in paced:
        stamps = [s for s, _ in paced[topic]]
        if topic == "/tf":  # every system's frames, each node's in order
            assert sorted(stamps) == sorted(s for s, _ in fast[topic])
        elif topic.rpartition("/")[2] in ("system_info", "tf_static", "diagnostics",
                                          "markers_static"):
            assert len(stamps) == len(fast[topic]), topic
        elif topic.endswith("/markers_trails"):  # where a trail's body changes
            assert stamps == [s for s, _ in fast[topic]] and set(stamps) <= set(grid), topic
        else:
            assert stamps == grid, topic  # every sample once, in time order
        for (_, a), (_, b) in zip(paced[topic], fast[topic], strict=True):
            assert a == pytest.approx(b, rel=1e-9, abs=1e-9), topic
