"""Recording to rosbag2 MCAP bags, checked with independent readers (``rosbags``, ``mcap`` +
``mcap_ros2``): counts, values, schema text, channel metadata, metadata.yaml, Ctrl-C, hard
kill + repair, write errors, bad inputs."""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path
from typing import Any

import pytest
import yaml

from mechsim.outputs.batch import recorded as recorded_topics  # noqa: E402
from mechsim.outputs.sink import Capabilities  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SHARE = Path(sys.prefix) / "share"
MECHSIM = [sys.executable, "-m", "mechsim.cli"]
# ROS_CONVENTIONS §4, values seen in this environment (independent of the writer).
HASHES = {
    "sensor_msgs/msg/JointState":
        "RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e",
    "tf2_msgs/msg/TFMessage":
        "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    "rosgraph_msgs/msg/Clock":
        "RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564",
    "diagnostic_msgs/msg/DiagnosticArray":
        "RIHS01_5a8a36efb05fb25070fa0fb3810290c0e6cd4862b54a8fb975a1ee8dc55a333e",
}


class Capture:
    """A second sink: what the nodes handed to the outlet, kept for comparison."""

    capabilities = Capabilities()

    def __init__(self) -> None:
        self.items: list[tuple[str, str, Any, int]] = []

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        self.items.append((topic, type_name, msg, ns))


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The default scene (three systems) recorded for 1 s, in process, plus a capture."""
    from mechsim.ros import launch, record
    from mechsim.scene import scene_from_target

    scene = scene_from_target(str(REPO / "scenes" / "default.yaml"), [])
    path = tmp_path_factory.mktemp("bags") / "rec"
    capture = Capture()
    real_run_scene = launch.run_scene

    def run_scene_with_capture(*args: Any, sinks: list[Any], **kw: Any) -> Any:
        return real_run_scene(*args, sinks=[*sinks, capture], **kw)

    launch.run_scene = run_scene_with_capture  # type: ignore[assignment]
    try:
        run, lines = record.run_with_outputs(scene, fast=True, duration=1.0, bag=str(path))
    finally:
        launch.run_scene = real_run_scene  # type: ignore[assignment]
    return {"path": path, "run": run, "capture": capture, "lines": lines}


def _rosbags_messages(path: Path) -> list[tuple[str, str, int, Any]]:
    from rosbags.highlevel import AnyReader

    out = []
    with AnyReader([path]) as reader:
        for con, ts, raw in reader.messages():
            out.append((con.topic, con.msgtype, ts, reader.deserialize(raw, con.msgtype)))
    return out


def _mcap_file(path: Path) -> Path:
    return path / f"{path.name}_0.mcap"


def test_counts_match_what_was_published(recorded: dict[str, Any]) -> None:
    path, run = recorded["path"], recorded["run"]
    assert run.messages and not run.interrupted
    meta = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    meta_counts = {t["topic_metadata"]["name"]: t["message_count"]
                   for t in meta["topics_with_message_count"]}
    file_counts = Counter(m[0] for m in _rosbags_messages(path))
    # channels never used: no topic; the batches are made for the capture, not recorded by a
    # bag of the default bag_topics ("samples")
    kept = recorded_topics("samples")
    published = {t: n for t, n in run.messages.items() if n and kept(t)}
    assert dict(file_counts) == published == meta_counts
    assert meta["message_count"] == sum(published.values())
    assert meta["files"][0]["message_count"] == meta["message_count"]
    for topic in ("/clock", "/tf_static", "/diagnostics", "/pendulum/system_info",
                  "/kepler/invariants", "/driven_oscillator/state"):
        assert file_counts[topic] > 0, topic
    assert file_counts["/pendulum/state"] == 101  # t = 0, 0.01, ..., 1.0
    from mcap.reader import make_reader

    with open(_mcap_file(path), "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    assert summary.statistics.message_count == meta["message_count"]
    by_channel = {summary.channels[c].topic: n
                  for c, n in summary.statistics.channel_message_counts.items()}
    assert by_channel == published
    assert {c.compression for c in summary.chunk_indexes} == {"zstd"}


def test_values_decode_to_what_the_nodes_published(recorded: dict[str, Any]) -> None:
    """rosbags and mcap_ros2 (two independent CDR decoders) give back the published values."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    kept = recorded_topics("samples")  # what a bag of the default bag_topics holds
    published = [(t, ty, m, ns) for t, ty, m, ns in recorded["capture"].items if kept(t)]
    decoded = _rosbags_messages(recorded["path"])
    assert len(decoded) == len(published)
    # Topics are handed over a chunk at a time: compare each topic's sequence in order.
    pairs = []
    for name in {t for t, *_ in published}:
        # /tf comes from several nodes: order by stamp, then by frame.
        mine = sorted((p for p in published if p[0] == name), key=lambda p: (
            p[3], p[2].transforms[0].child_frame_id if name == "/tf" else ""))
        theirs = sorted((d for d in decoded if d[0] == name), key=lambda d: (
            d[2], d[3].transforms[0].child_frame_id if name == "/tf" else ""))
        assert len(mine) == len(theirs), name
        pairs += list(zip(mine, theirs, strict=True))
    for (topic, ty, msg, ns), (btopic, bty, bts, bmsg) in pairs:
        assert (btopic, bty, bts) == (topic, ty, ns)
        if ty == "sensor_msgs/msg/JointState":
            assert list(bmsg.name) == list(msg.name)
            assert list(bmsg.position) == list(msg.position)
            assert list(bmsg.velocity) == list(msg.velocity)
            assert list(bmsg.effort) == []
        elif ty == "mechsim_msgs/msg/Energy":
            assert (bmsg.kinetic, bmsg.potential, bmsg.total) == (msg.kinetic, msg.potential,
                                                                  msg.total)
        elif ty == "tf2_msgs/msg/TFMessage":
            assert [t.child_frame_id for t in bmsg.transforms] == [
                t.child_frame_id for t in msg.transforms]
            assert [t.transform.rotation.w for t in bmsg.transforms] == [
                t.transform.rotation.w for t in msg.transforms]
    state = [(m, ns) for t, _, m, ns in published if t == "/kepler/state"]
    with open(_mcap_file(recorded["path"]), "rb") as f:
        got = [(dm, msg.log_time, msg.publish_time) for _, ch, msg, dm in
               make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
                   topics=["/kepler/state"])]
    assert len(got) == len(state)
    for (dm, log_time, pub_time), (m, ns) in zip(got, state, strict=True):
        assert list(dm.position) == list(m.position) and list(dm.velocity) == list(m.velocity)
        stamp = dm.header.stamp.sec * 1_000_000_000 + dm.header.stamp.nanosec
        assert log_time == pub_time == stamp == ns
    assert got[0][1] == 1_000_000_000  # sim time 0 + the 1 s offset


def _msg_text(name: str) -> str:
    pkg, typ = name.split("/")
    return (SHARE / pkg / "msg" / f"{typ}.msg").read_text()


def _expected(root: str, deps: list[str]) -> str:
    """rosbag2's concatenation, with the dependency order written out by hand."""
    text = _msg_text(root)
    for d in deps:
        text += "\n" + "=" * 80 + "\nMSG: " + d + "\n" + _msg_text(d)
    return text


def test_schemas_are_complete_ros2msg_definitions(recorded: dict[str, Any]) -> None:
    from mcap.reader import make_reader

    with open(_mcap_file(recorded["path"]), "rb") as f:
        reader = make_reader(f)
        header, summary = reader.get_header(), reader.get_summary()
    assert header.profile == "ros2"
    schemas = {s.name: s for s in summary.schemas.values()}
    assert {s.encoding for s in schemas.values()} == {"ros2msg"}
    assert len(schemas) == len(summary.schemas)  # one schema per type
    tf_deps = ["geometry_msgs/TransformStamped", "geometry_msgs/Transform",
               "geometry_msgs/Quaternion", "geometry_msgs/Vector3", "std_msgs/Header",
               "builtin_interfaces/Time"]
    assert schemas["tf2_msgs/msg/TFMessage"].data.decode() == _expected("tf2_msgs/TFMessage",
                                                                        tf_deps)
    assert schemas["sensor_msgs/msg/JointState"].data.decode() == _expected(
        "sensor_msgs/JointState", ["std_msgs/Header", "builtin_interfaces/Time"])
    assert schemas["rosgraph_msgs/msg/Clock"].data.decode() == _expected(
        "rosgraph_msgs/Clock", ["builtin_interfaces/Time"])
    assert schemas["diagnostic_msgs/msg/DiagnosticArray"].data.decode() == _expected(
        "diagnostic_msgs/DiagnosticArray",
        ["diagnostic_msgs/DiagnosticStatus", "diagnostic_msgs/KeyValue", "std_msgs/Header",
         "builtin_interfaces/Time"])
    assert schemas["mechsim_msgs/msg/Energy"].data.decode().startswith(
        _msg_text("mechsim_msgs/Energy"))
    for ch in summary.channels.values():
        assert ch.message_encoding == "cdr"
        name = summary.schemas[ch.schema_id].name
        if name in HASHES:
            assert ch.metadata["topic_type_hash"] == HASHES[name]
        assert ch.metadata["topic_type_hash"].startswith("RIHS01_")
        qos = yaml.safe_load(ch.metadata["offered_qos_profiles"])
        assert isinstance(qos, list) and len(qos) == 1
        want = {"/tf_static": ("reliable", "transient_local"),
                "/clock": ("best_effort", "volatile")}.get(
            ch.topic, ("reliable", "transient_local" if ch.topic.endswith(
                ("system_info", "markers_static", "markers_trails")) else "volatile"))
        assert (qos[0]["reliability"], qos[0]["durability"]) == want, ch.topic
        assert qos[0]["deadline"] == {"sec": 9223372036, "nsec": 854775807}


def test_metadata_yaml_is_rosbag2_version_9(recorded: dict[str, Any]) -> None:
    from rosbags.rosbag2 import Reader

    path = recorded["path"]
    text = (path / "metadata.yaml").read_text()
    assert "&id" not in text and "*id" not in text  # no YAML anchors
    meta = yaml.safe_load(text)["rosbag2_bagfile_information"]
    assert list(meta) == ["version", "storage_identifier", "duration", "starting_time",
                          "message_count", "topics_with_message_count", "compression_format",
                          "compression_mode", "relative_file_paths", "files", "custom_data",
                          "ros_distro"]
    assert (meta["version"], meta["storage_identifier"], meta["ros_distro"]) == (
        9, "mcap", "kilted")
    assert meta["relative_file_paths"] == ["rec_0.mcap"]
    assert meta["starting_time"]["nanoseconds_since_epoch"] == 1_000_000_000
    assert meta["duration"]["nanoseconds"] == 1_000_000_000
    tm = {t["topic_metadata"]["name"]: t["topic_metadata"]
          for t in meta["topics_with_message_count"]}
    assert tm["/tf"]["type_description_hash"] == HASHES["tf2_msgs/msg/TFMessage"]
    assert tm["/tf_static"]["offered_qos_profiles"][0]["durability"] == "transient_local"
    custom = meta["custom_data"]
    assert all(isinstance(v, str) for v in custom.values())
    assert custom["mechsim.instances"] == "pendulum,driven_oscillator,kepler"
    assert custom["mechsim.pendulum.system"] == "pendulum"
    assert yaml.safe_load(custom["mechsim.pendulum.parameters"])["initial.angle"] == 2.0
    assert custom["mechsim.kepler.integrator"] and custom["mechsim.kepler.tolerance"] == "1e-10"
    assert custom["mechsim.scene"] == "default" and custom["mechsim.version"]
    with Reader(path) as r:  # rosbags' own metadata parser
        assert r.message_count == meta["message_count"]
        assert r.ros_distro == "kilted"
        assert {c.topic: c.digest for c in r.connections}["/clock"] == HASHES[
            "rosgraph_msgs/msg/Clock"]
    from mcap.reader import make_reader

    with open(_mcap_file(path), "rb") as f:
        records = [m for m in make_reader(f).iter_metadata() if m.name == "rosbag2"]
    final = yaml.safe_load(records[-1].metadata["serialized_metadata"])
    assert final == meta  # the rosbag2 metadata record of the MCAP repeats metadata.yaml


def _cli(*args: str, env: dict[str, str] | None = None,
         timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*MECHSIM, *args], capture_output=True, text=True, timeout=timeout,
                          env=env, cwd=REPO)


def _wait_for_size(f: Path, size: int, proc: subprocess.Popen[str], timeout: float) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if f.exists() and f.stat().st_size >= size:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    raise AssertionError(f"{f} did not reach {size} bytes")


def _complete_chunks(f: Path) -> int:
    """How many MCAP Chunk records (opcode 0x06) the file holds whole so far: records are
    opcode (1 byte), length (8 bytes little-endian) and content, after the 8-byte magic."""
    data = f.read_bytes() if f.exists() else b""
    at, chunks = 8, 0
    while at + 9 <= len(data):
        opcode, length = data[at], int.from_bytes(data[at + 1:at + 9], "little")
        if at + 9 + length > len(data):
            break
        chunks += opcode == 0x06
        at += 9 + length
    return chunks


def _wait_for_chunks(f: Path, count: int, proc: subprocess.Popen[str], timeout: float) -> None:
    """Until ``f`` holds ``count`` whole chunks (a size alone can land inside the first
    chunk's write, which repair rightly drops)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if _complete_chunks(f) >= count:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    raise AssertionError(f"{f} did not reach {count} whole chunks")


def _counts_from_file(path: Path) -> Counter[str]:
    return Counter(m[0] for m in _rosbags_messages(path))


def test_sigint_mid_record_gives_a_complete_bag(tmp_path: Path,
                                                ros_env: dict[str, str]) -> None:
    bag = tmp_path / "stopped"
    proc = subprocess.Popen([*MECHSIM, "record", "pendulum", "--duration", "1000", "--bag",
                             str(bag)], env=ros_env, cwd=REPO, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        _wait_for_size(bag / "stopped_0.mcap", 20_000, proc, 60)  # chunks are flowing
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 130, err  # interrupted: the shell's code for SIGINT
    assert "interrupted" in err and "Traceback" not in err
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    counts = _counts_from_file(bag)
    assert {t["topic_metadata"]["name"]: t["message_count"]
            for t in meta["topics_with_message_count"]} == dict(counts)
    assert meta["message_count"] == sum(counts.values()) > 500
    states = [m for m in _rosbags_messages(bag) if m[0] == "/pendulum/state"]
    stamps = [ts for _, _, ts, _ in states]
    assert stamps == [1_000_000_000 + 10_000_000 * k for k in range(len(stamps))]  # no gaps


def test_sigkill_then_repair(tmp_path: Path, ros_env: dict[str, str]) -> None:
    from mechsim.outputs.bag import LOCK_FILE

    bag = tmp_path / "killed"
    f = bag / "killed_0.mcap"
    # 10 Hz: the recorder runs as fast as it can until the kill; fewer messages to read back.
    proc = subprocess.Popen([*MECHSIM, "record", "pendulum", "--duration", "1000", "--publish-rate",
                             "10", "--bag", str(bag)], env=ros_env, cwd=REPO, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        _wait_for_chunks(f, 2, proc, 120)
        proc.send_signal(signal.SIGKILL)
        proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert not (bag / "metadata.yaml").exists()
    assert (bag / LOCK_FILE).exists()  # the killed recorder's lock: stale (its PID is gone)
    info = _cli("bag", "info", str(bag), env=ros_env)
    assert info.returncode == 2 and info.stderr.count("\n") == 1
    assert "mechsim bag repair" in info.stderr
    rep = _cli("bag", "repair", str(bag), env=ros_env)
    assert rep.returncode == 0, rep.stderr
    assert "truncated" in rep.stdout and not (bag / LOCK_FILE).exists()
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    counts = _counts_from_file(bag)
    assert meta["message_count"] == sum(counts.values()) > 100
    assert {t["topic_metadata"]["name"]: t["message_count"]
            for t in meta["topics_with_message_count"]} == dict(counts)
    assert meta["custom_data"]["mechsim.scene"] == "pendulum"  # from the MCAP's first record
    assert meta["custom_data"]["mechsim.pendulum.system"] == "pendulum"  # from system_info
    stamps = [ts for t, _, ts, _ in _rosbags_messages(bag) if t == "/pendulum/state"]
    assert stamps == [1_000_000_000 + 100_000_000 * k for k in range(len(stamps))]
    again = _cli("bag", "repair", str(bag), env=ros_env)  # idempotent on a complete bag
    assert again.returncode == 0 and "was complete" in again.stdout
    assert sum(_counts_from_file(bag).values()) == meta["message_count"]


class _FullDisk:
    """A file whose writes fail with ENOSPC once ``limit`` bytes were written."""

    def __init__(self, real: Any, limit: int) -> None:
        self.real, self.limit, self.written = real, limit, 0

    def write(self, data: bytes) -> int:
        self.written += len(data)
        if self.written > self.limit:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return int(self.real.write(data))

    def __getattr__(self, name: str) -> Any:
        return getattr(self.real, name)


def test_disk_full_keeps_what_was_recorded(tmp_path: Path,
                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """ENOSPC in the middle of a recording: a one-line error naming the bag and the cause; the
    recorder completes the bag from the chunks written before (no lock left), and an
    independent reader decodes it without a gap."""
    from mechsim.errors import MechsimError
    from mechsim.outputs.bag import LOCK_FILE, read_metadata
    from mechsim.outputs.bag import writer as writer_module
    from mechsim.ros import record
    from mechsim.scene import single_system_scene

    real_open = writer_module.open_exclusive
    monkeypatch.setattr(writer_module, "open_exclusive",
                        lambda path: _FullDisk(real_open(path), 600_000))
    target = tmp_path / "full"
    with pytest.raises(MechsimError) as e:
        # (chunks of 512 KB, ~175 KB compressed: a few reach the disk before it is full)
        record.run_with_outputs(single_system_scene("pendulum"), fast=True, duration=300.0,
                                bag=str(target))
    msg = str(e.value)
    assert str(target) in msg and "No space left on device" in msg and "\n" not in msg
    assert sorted(p.name for p in target.iterdir()) == ["full_0.mcap", "metadata.yaml"]
    assert not (target / LOCK_FILE).exists()
    meta = read_metadata(target)
    stamps = [ts for t, _, ts, _ in _rosbags_messages(target) if t == "/pendulum/state"]
    assert meta["message_count"] == sum(_counts_from_file(target).values())
    assert len(stamps) > 10
    assert stamps == [1_000_000_000 + 10_000_000 * k for k in range(len(stamps))]


@pytest.mark.parametrize("case", ["nonempty", "file_parent", "unwritable"])
def test_record_bad_output_paths(tmp_path: Path, case: str, capsys: Any) -> None:
    from mechsim.cli import main

    if case == "nonempty":
        target = tmp_path / "full"
        target.mkdir()
        (target / "x").write_text("x")
    elif case == "file_parent":
        (tmp_path / "afile").write_text("x")
        target = tmp_path / "afile" / "bag"
    else:
        if os.geteuid() == 0:
            target = Path("/proc/mechsim_bag")  # even root cannot create directories here
        else:
            ro = tmp_path / "ro"
            ro.mkdir(mode=0o500)
            target = ro / "bag"
    rc = main(["record", "pendulum", "--duration", "1", "--bag", str(target)])
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("mechsim: error")]
    assert rc == 2 and len(lines) == 1 and str(target) in lines[0], err
    assert "Traceback" not in err
    if case == "nonempty":
        assert sorted(p.name for p in target.iterdir()) == ["x"]  # untouched


def test_bad_bags_are_one_line_errors(tmp_path: Path, capsys: Any) -> None:
    from mechsim.cli import main

    corrupt = tmp_path / "corrupt"
    corrupt.mkdir()
    (corrupt / "corrupt_0.mcap").write_bytes(b"\x89MCAP0\r\n" + os.urandom(3000))
    (corrupt / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": {
        "version": 9, "storage_identifier": "mcap", "relative_file_paths": ["corrupt_0.mcap"],
        "topics_with_message_count": [], "duration": {"nanoseconds": 0},
        "starting_time": {"nanoseconds_since_epoch": 0}, "message_count": 0}}))
    junk = tmp_path / "junk"
    junk.mkdir()
    junk_bytes = os.urandom(5000)
    (junk / "junk_0.mcap").write_bytes(junk_bytes)
    notyaml = tmp_path / "notyaml"
    notyaml.mkdir()
    (notyaml / "metadata.yaml").write_text("{{{")
    cases = [["bag", "info", str(tmp_path / "missing")],
             ["bag", "info", str(notyaml)],
             ["replay", str(tmp_path / "missing")],
             ["replay", str(notyaml)],
             ["bag", "repair", str(tmp_path / "missing")],
             ["replay", str(corrupt), "--delay", "0"],
             ["bag", "repair", str(junk)],
             ["replay", str(REPO / "bags" / "reference"), "--rate", "-1"],
             ["replay", str(REPO / "bags" / "reference"), "--topics", "/nope"],
             ["record", "pendulum", "--duration", "-1", "--bag", str(tmp_path / "neg")]]
    for argv in cases:
        rc = main(argv)
        err = capsys.readouterr().err
        assert rc == 2 and err.count("\n") == 1 and err.startswith("mechsim: error: "), (argv,
                                                                                          err)
    assert not (tmp_path / "neg").exists()
    assert (junk / "junk_0.mcap").read_bytes() == junk_bytes  # not "repaired" into nothing
    from mechsim.errors import MechsimError
    from mechsim.outputs.bag import read_messages

    with pytest.raises(MechsimError, match="corrupt"):
        list(read_messages(corrupt))


def test_a_multi_system_bag_reads_back_in_time_order(tmp_path: Path) -> None:
    """A recorder writes each node's samples in chunks (5 s of a fast run), so the file holds
    node A's 0–5 s, then B's 0–5 s, then A's 5–10 s: ``read_messages`` (what ``replay`` and
    ``convert`` read) gives them in log-time order, every message once, as ``ros2 bag play``
    does."""
    from mechsim.outputs.bag.reader import read_messages
    from mechsim.ros import record
    from mechsim.scene import scene_from_target

    scene = scene_from_target(str(REPO / "scenes" / "default.yaml"), [])
    path = tmp_path / "multi"
    record.run_with_outputs(scene, fast=True, duration=12.0, bag=str(path))
    times = [m.log_time for m in read_messages(path)]
    stored = [ts for _, _, ts, _ in _rosbags_messages(path)]
    assert sorted(times) == sorted(stored)  # every message, once
    assert times == sorted(times)
    # the file itself is not in time order (else this test would prove nothing)
    from mcap.reader import make_reader

    with open(next(path.glob("*.mcap")), "rb") as f:
        in_file = [m.log_time for _, _, m in make_reader(f).iter_messages(log_time_order=False)]
    assert in_file != sorted(in_file)
