"""File safety of recordings, one test per guard, each checked against something independent
(rosbags' and PyYAML's parsers, mcap's summary, the bytes of files outside the bag):

- temporaries never follow a symlink planted at their name, and nothing outside the bag changes;
- ``custom_data`` from outside stays data in metadata.yaml (no added lines or keys);
- YAML aliases (alias bombs) are refused, malformed or non-UTF-8 metadata is one line naming
  the field, ``bag info`` escapes terminal control characters;
- one damaged chunk in the middle: repair keeps every message of the other chunks;
- a bag being recorded (live lock) is refused by repair, info, convert and replay; a lock of a
  dead process or of a reused PID is stale;
- bag directories are claimed exclusively;
- ``convert`` never overwrites an existing .rrd without ``--force``, never before the bag is
  known readable, and a full disk leaves no half-written .rrd.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from mechsim.environment import import_rclpy

import_rclpy()

from rclpy.qos import QoSProfile  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from mechsim.cli import main  # noqa: E402
from mechsim.errors import MechsimError  # noqa: E402
from mechsim.outputs.bag import (  # noqa: E402
    LOCK_FILE,
    BagWriter,
    read_messages,
    read_metadata,
    repair_bag,
)
from mechsim.outputs.wire import cdr_bytes  # noqa: E402

JOINT_STATE = "sensor_msgs/msg/JointState"
OFFSET_NS = 1_000_000_000
PAYLOAD = "x\nrosbag2_bagfile_information: {}\n#!/bin/sh\necho pwned > /tmp/pwned\n"
BOMB = ('a: &a ["x","x","x","x","x","x","x","x","x"]\n'
        + "".join(f"{c}: &{c} [*{p},*{p},*{p},*{p},*{p},*{p},*{p},*{p},*{p}]\n"
                  for p, c in zip("abcdefgh", "bcdefghi", strict=True)))


def _write_states(w: BagWriter, n: int, first: int = 0) -> None:
    qos = QoSProfile(depth=10)
    for k in range(first, first + n):
        m = JointState()
        m.name = ["q"]
        m.position = [float(k)]
        m.velocity = [0.5 * k]
        ns = OFFSET_NS + 10_000_000 * k
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(ns, 1_000_000_000)
        w.write_bytes("/p/state", JOINT_STATE, qos, ns, cdr_bytes(m))


def _make_bag(path: Path, n: int = 400, chunk_size: int = 4096,
              custom: dict[str, str] | None = None) -> Path:
    w = BagWriter(path, custom, chunk_size=chunk_size)
    _write_states(w, n)
    w.close()
    return path


def _rosbags(path: Path) -> list[tuple[str, int, bytes]]:
    from rosbags.highlevel import AnyReader

    with AnyReader([path]) as r:
        return [(c.topic, ts, bytes(raw)) for c, ts, raw in r.messages()]


def _one_line_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and err.startswith("mechsim: error: "), (argv, err)
    return err


@pytest.fixture
def candidate_names(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Make temporary names predictable, as an attacker would like them: each mkstemp first
    tries ``planted``, then fresh names."""
    def names() -> Iterator[str]:
        yield "planted"
        k = 0
        while True:
            k += 1
            yield f"fresh{k}"

    monkeypatch.setattr(tempfile, "_get_candidate_names", names)
    yield


# --- temporaries and symlinks -------------------------------------------------------------------
def test_repair_never_follows_planted_symlinks(tmp_path: Path, candidate_names: None) -> None:
    bag = _make_bag(tmp_path / "b")
    (bag / "metadata.yaml").unlink()  # an interrupted recording
    victim = tmp_path / "victim.sh"
    victim.write_text("original\n")
    planted = ["metadata.yaml", ".metadata.yaml.tmp", ".b_0.mcap.repair",
               ".metadata.yaml.planted.tmp", ".b_0.mcap.planted.tmp",
               f".{LOCK_FILE}.planted.tmp"]
    for name in planted:
        (bag / name).symlink_to(victim)
    r = repair_bag(bag)
    assert victim.read_text() == "original\n"
    for name in planted[1:]:
        assert (bag / name).is_symlink() and (bag / name).resolve() == victim
    assert not (bag / "metadata.yaml").is_symlink()  # replaced by the rename, not written into
    assert r.messages == 400 and len(_rosbags(bag)) == 400


def test_atomic_write_leaves_the_target_on_failure(tmp_path: Path) -> None:
    from mechsim.files import atomic_file, write_atomic

    target = tmp_path / "out.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError), atomic_file(target) as f:
        f.write(b"partial")
        raise RuntimeError("disk gone")
    assert target.read_text() == "old" and sorted(os.listdir(tmp_path)) == ["out.txt"]
    with pytest.raises(FileExistsError):
        write_atomic(target, "new", replace=False)
    assert target.read_text() == "old" and sorted(os.listdir(tmp_path)) == ["out.txt"]


# --- YAML from outside --------------------------------------------------------------------------
def test_crafted_custom_data_stays_data(tmp_path: Path) -> None:
    from rosbags.rosbag2 import Reader
    from ruamel.yaml import YAML

    crafted = {"mechsim.scene": PAYLOAD, "key\nwith: newline": "v", "quotes": "'\"&a *a !!x",
               "esc": "\x1b[2J\u2028\x85end"}
    bag = _make_bag(tmp_path / "b", n=5, custom=crafted)
    text = (bag / "metadata.yaml").read_text()
    lines = [ln.strip() for ln in text.splitlines()]
    assert not [ln for ln in lines if ln.startswith(("#!", "echo", "rosbag2_bagfile_information:"
                                                     " {}"))]
    assert sum(ln.startswith("rosbag2_bagfile_information") for ln in lines) == 1
    assert yaml.safe_load(text)["rosbag2_bagfile_information"]["custom_data"] == crafted
    other = YAML(typ="safe").load(text)  # a second, independent YAML parser
    assert other["rosbag2_bagfile_information"]["custom_data"] == crafted
    with Reader(bag) as r:  # and rosbags still opens the bag
        assert r.message_count == 5


def _hand_made_mcap(path: Path, serialized_metadata: str, n: int = 20) -> None:
    """An MCAP written with mcap's own writer whose rosbag2 record carries ``serialized_metadata``
    as given (an attacker's file)."""
    from mcap.writer import Writer

    from mechsim.outputs.wire import message_definition

    path.mkdir()
    with open(path / f"{path.name}_0.mcap", "wb") as f:
        w = Writer(f)
        w.start(profile="ros2", library="hand made")
        w.add_metadata("rosbag2", {"serialized_metadata": serialized_metadata})
        sid = w.register_schema(JOINT_STATE, "ros2msg", message_definition(JOINT_STATE).encode())
        cid = w.register_channel("/p/state", "cdr", sid, {"offered_qos_profiles": "[]"})
        for k in range(n):
            m = JointState()
            m.position = [float(k)]
            w.add_message(cid, log_time=OFFSET_NS + k, data=cdr_bytes(m),
                          publish_time=OFFSET_NS + k)
        w.finish()


def test_repair_writes_crafted_custom_data_back_quoted(tmp_path: Path) -> None:
    """The attack of the hardening issue: custom_data in the MCAP's rosbag2 record as a literal
    block; written back, it must stay one quoted value."""
    bag = tmp_path / "evil"
    evil = "custom_data:\n  mechsim.scene: |\n" + "".join(
        f"    {ln}\n" for ln in PAYLOAD.splitlines())
    _hand_made_mcap(bag, evil)
    r = repair_bag(bag)
    text = (bag / "metadata.yaml").read_text()
    assert not [ln for ln in text.splitlines() if ln.strip().startswith(("#!", "echo"))]
    meta = yaml.safe_load(text)["rosbag2_bagfile_information"]
    assert meta["custom_data"] == {"mechsim.scene": PAYLOAD} and r.messages == 20


def test_alias_bombs_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = _make_bag(tmp_path / "b", n=5)
    meta = (bag / "metadata.yaml").read_text()
    (bag / "metadata.yaml").write_text(meta.replace("custom_data: null",
                                                    "custom_data:\n  k: *i").replace(
        "rosbag2_bagfile_information:", BOMB + "rosbag2_bagfile_information:"))
    assert "aliases are not allowed" in _one_line_error(["bag", "info", str(bag)], capsys)
    # In the MCAP's own rosbag2 record (read by repair): ignored, the repair completes.
    evil = tmp_path / "evil"
    _hand_made_mcap(evil, BOMB + "custom_data:\n  k: *i\n")
    assert repair_bag(evil).messages == 20
    assert read_metadata(evil)["custom_data"] is None


def _metadata(bag: Path) -> dict[str, Any]:
    return yaml.safe_load((bag / "metadata.yaml").read_text())


@pytest.mark.parametrize("case", ["missing", "wrong_type", "custom_list", "negative", "not_map",
                                  "not_utf8", "huge_int", "deep", "fifo", "outside"])
def test_malformed_metadata_is_one_line_naming_the_field(
        tmp_path: Path, case: str, capsys: pytest.CaptureFixture[str]) -> None:
    bag = _make_bag(tmp_path / "b", n=3)
    doc = _metadata(bag)
    m = doc["rosbag2_bagfile_information"]
    f = bag / "metadata.yaml"
    expect = {"missing": "topics_with_message_count: missing",
              "wrong_type": "topics_with_message_count[0].topic_metadata.name: expected a "
                            "string (got int)",
              "custom_list": "custom_data.k: expected a string (got list)",
              "negative": "message_count: must be >= 0",
              "not_map": "expected a mapping (got list)", "not_utf8": "not UTF-8",
              "huge_int": "not valid YAML", "deep": "not valid YAML",
              "fifo": "cannot read", "outside": "storage file secret_0.mcap missing"}[case]
    if case == "missing":
        del m["topics_with_message_count"]
    elif case == "wrong_type":
        m["topics_with_message_count"][0]["topic_metadata"]["name"] = 7
    elif case == "custom_list":
        m["custom_data"] = {"k": ["a"]}
    elif case == "negative":
        m["message_count"] = -1
    elif case == "not_map":
        doc = [1, 2]
    elif case == "outside":  # a file beside the bag must not be read as its storage
        (tmp_path / "secret_0.mcap").write_bytes((bag / "b_0.mcap").read_bytes())
        m["relative_file_paths"] = ["../secret_0.mcap"]
    f.write_text(yaml.safe_dump(doc))
    if case == "not_utf8":
        f.write_bytes(f.read_bytes().replace(b"mcap", b"mc\xff\xfe", 1))
    elif case == "huge_int":
        f.write_text(f.read_text().replace("message_count: 3", "message_count: " + "9" * 5000, 1))
    elif case == "deep":
        f.write_text("[" * 50_000)
    elif case == "fifo":
        f.unlink()
        os.mkfifo(f)
    err = _one_line_error(["bag", "info", str(bag)], capsys)
    assert f"bag {bag}" in err and expect in err, err


def test_bag_info_escapes_control_characters(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    bag = _make_bag(tmp_path / "b", n=3, custom={"title": "\x1b]0;owned\x07", "k\x1b[31m": "v"})
    doc = _metadata(bag)
    doc["rosbag2_bagfile_information"]["topics_with_message_count"][0]["topic_metadata"][
        "name"] = "/p\x1b[2J/state"
    (bag / "metadata.yaml").write_text(yaml.safe_dump(doc))
    assert main(["bag", "info", str(bag)]) == 0
    out = capsys.readouterr().out
    assert not any(ord(c) < 32 and c != "\n" or 0x7F <= ord(c) < 0xA0 for c in out)
    assert "/p\\x1b[2J/state" in out and "\\x1b]0;owned\\x07" in out and "k\\x1b[31m" in out


# --- repair salvages around a damaged chunk -----------------------------------------------------
def _chunk_data_offset(index: Any) -> int:
    """File offset of a chunk's compressed records (MCAP spec: opcode, record length, start,
    end, uncompressed size, CRC, compression string, records length, records)."""
    return index.chunk_start_offset + 1 + 8 + 8 + 8 + 8 + 4 + 4 + len(index.compression) + 8


def test_repair_keeps_the_chunks_around_a_damaged_one(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    bag = _make_bag(tmp_path / "b", n=2000, chunk_size=4096)
    original = _rosbags(bag)
    f = bag / "b_0.mcap"
    with open(f, "rb") as stream:
        chunks = make_reader(stream).get_summary().chunk_indexes
    chunks.sort(key=lambda c: c.chunk_start_offset)
    assert len(chunks) >= 5
    bad = chunks[len(chunks) // 2]
    data = bytearray(f.read_bytes())
    at = _chunk_data_offset(bad) + bad.compressed_size // 2
    data[at:at + 32] = bytes(b ^ 0xFF for b in data[at:at + 32])
    f.write_bytes(bytes(data))
    with pytest.raises(MechsimError, match="corrupt"):  # readers see the damage (CRC)
        list(read_messages(bag))
    r = repair_bag(bag)
    lost = [m for m in original if bad.message_start_time <= m[1] <= bad.message_end_time]
    kept = [m for m in original if m not in lost]
    assert 0 < len(lost) < len(original) // 4
    assert [m[1] for m in kept if m[1] > bad.message_end_time]  # chunks after it are kept
    assert _rosbags(bag) == kept
    assert (r.lost_chunks, r.messages, r.complete) == (1, len(kept), False)
    assert r.damaged is not None and r.damaged.read_bytes() == bytes(data)  # original kept


# --- the lock of a bag being recorded -----------------------------------------------------------
def test_a_live_recording_is_left_alone(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "live"
    w = BagWriter(path)
    try:
        _write_states(w, 50)
        with pytest.raises(MechsimError, match=f"being recorded by process {os.getpid()}"):
            repair_bag(path)
        for argv in (["bag", "repair", str(path)], ["bag", "info", str(path)],
                     ["convert", str(path), "--rrd", str(tmp_path / "x.rrd")],
                     ["replay", str(path), "--delay", "0"]):
            err = _one_line_error(argv, capsys)
            assert f"being recorded by process {os.getpid()}" in err, (argv, err)
        _write_states(w, 50, first=50)
    finally:
        w.close()
    assert not (path / LOCK_FILE).exists() and not (tmp_path / "x.rrd").exists()
    assert [ts for _, ts, _ in _rosbags(path)] == [OFFSET_NS + 10_000_000 * k for k in range(100)]
    assert sorted(p.name for p in path.iterdir()) == ["live_0.mcap", "metadata.yaml"]


def _dead_process_lock(bag: Path) -> None:
    """A lock left by a recorder process that died without removing it."""
    code = ("import os, sys\nfrom pathlib import Path\nfrom mechsim.outputs.bag.lock import "
            "BagLock\nBagLock.acquire(Path(sys.argv[1]), 'recording', break_stale=False)\n"
            "os._exit(0)\n")
    subprocess.run([sys.executable, "-c", code, str(bag)], check=True, timeout=120)
    assert (bag / LOCK_FILE).exists()


def test_stale_locks_are_detected(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = _make_bag(tmp_path / "b", n=30)
    (bag / "metadata.yaml").unlink()
    _dead_process_lock(bag)
    err = _one_line_error(["bag", "info", str(bag)], capsys)
    assert "interrupted recording" in err and "mechsim bag repair" in err
    assert repair_bag(bag).messages == 30 and not (bag / LOCK_FILE).exists()
    # A live PID that started at another time than the lock's holder: the PID was reused.
    _dead_process_lock(bag)
    info = json.loads((bag / LOCK_FILE).read_text())
    info["pid"] = os.getpid()
    info["started"] = (info["started"] or 0) + 12345
    (bag / LOCK_FILE).write_text(json.dumps(info))
    assert read_metadata(bag)["message_count"] == 30
    assert repair_bag(bag).messages == 30 and not (bag / LOCK_FILE).exists()


# --- bag directories ----------------------------------------------------------------------------
def test_bag_directories_are_claimed_exclusively(tmp_path: Path,
                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """A second recorder reaching the same new path between the first one's decision and its
    directory creation (the window of a check-then-create) is refused; the first records."""
    from mechsim.outputs.bag import writer as writer_module

    path = tmp_path / "race"
    real_make_dir = writer_module.make_dir
    others: list[BagWriter] = []

    def make_dir_with_competitor(d: Path) -> bool:
        if not others:
            monkeypatch.setattr(writer_module, "make_dir", real_make_dir)
            others.append(BagWriter(path))  # wins the race
        return real_make_dir(d)

    monkeypatch.setattr(writer_module, "make_dir", make_dir_with_competitor)
    try:
        with pytest.raises(MechsimError, match="not empty"):
            BagWriter(path)
        _write_states(others[0], 10)
    finally:
        for w in others:
            w.close()
    assert len(_rosbags(path)) == 10
    # An existing empty directory is claimed; a symlink to one is refused, its target untouched.
    empty = tmp_path / "empty"
    empty.mkdir()
    link = tmp_path / "link"
    link.symlink_to(empty)
    with pytest.raises(MechsimError, match="symbolic link"):
        BagWriter(link)
    assert list(empty.iterdir()) == []
    _make_bag(empty, n=3)
    assert len(_rosbags(empty)) == 3


# --- convert ------------------------------------------------------------------------------------
def test_convert_never_overwrites_unasked(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    from rerun.chunk import RrdReader

    bag = _make_bag(tmp_path / "b", n=50)
    rrd = tmp_path / "out.rrd"
    rrd.write_text("precious")
    assert "--force" in _one_line_error(["convert", str(bag), "--rrd", str(rrd)], capsys)
    corrupt = tmp_path / "c"
    corrupt.mkdir()
    (corrupt / "c_0.mcap").write_bytes(b"\x89MCAP0\r\n" + b"\0" * 100)
    (corrupt / "metadata.yaml").write_text(
        (bag / "metadata.yaml").read_text().replace("b_0.mcap", "c_0.mcap"))
    _one_line_error(["convert", str(corrupt), "--rrd", str(rrd), "--force"], capsys)
    assert rrd.read_text() == "precious"
    assert main(["convert", str(bag), "--rrd", str(rrd), "--force"]) == 0
    assert len(RrdReader(rrd).recordings()) == 1
    monkeypatch.chdir(bag)  # `convert .`: the default .rrd is beside the bag
    assert main(["convert", "."]) == 0
    assert len(RrdReader(tmp_path / "b.rrd").recordings()) == 1
    assert sorted(os.listdir(tmp_path)) == ["b", "b.rrd", "c", "out.rrd"]


def test_rrd_on_a_full_disk_is_not_left_half_written(tmp_path: Path,
                                                     ros_env: dict[str, str]) -> None:
    """The file-size limit (RLIMIT_FSIZE: writes past it fail like a full disk) stops Rerun's
    writer: one error line naming the .rrd, and neither it nor a temporary is left. The limit
    (64 KiB) lies past the recording's opening (an empty recording with its blueprint is ~17 KB;
    Rerun hangs when its very first write fails, which a real disk full at that instant would
    also do) and well before its end (~130 KB)."""
    bag = _make_bag(tmp_path / "b", n=3000)
    rrd = tmp_path / "out.rrd"

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (65_536, 65_536))

    r = subprocess.run([sys.executable, "-m", "mechsim.cli", "convert", str(bag), "--rrd",
                        str(rrd)], env=ros_env, capture_output=True, text=True, timeout=300,
                       preexec_fn=limit)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1, r.stderr  # Rerun's own lines silenced
    assert lines[0].startswith("mechsim: error: rrd ") and str(rrd) in lines[0], r.stderr
    assert sorted(os.listdir(tmp_path)) == ["b"]


def test_a_live_run_with_rrd_on_a_full_disk_ends_in_one_line(tmp_path: Path,
                                                             ros_env: dict[str, str]) -> None:
    """``run --fast --rrd`` under the same 64 KiB file-size limit: the run's one error line
    names the .rrd (exit 2), nothing is left in the output's directory, no traceback."""
    out = tmp_path / "out"
    out.mkdir()

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (65_536, 65_536))

    r = subprocess.run([sys.executable, "-m", "mechsim.cli", "run", "pendulum", "--fast",
                        "--duration", "30", "--rrd", "out.rrd"], env=ros_env, cwd=out,
                       capture_output=True, text=True, timeout=600, preexec_fn=limit)
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("mechsim: error:")]
    assert r.returncode == 2 and len(errors) == 1 and "out.rrd" in errors[0], r.stderr
    assert "Traceback" not in r.stderr and "re_log_encoding" not in r.stderr
    assert os.listdir(out) == []
