"""Every reader of bags is bounded by what it accepts, not by what a file declares.

Hostile storage files, made here byte by byte (MCAP specification, https://mcap.dev/spec): a
decompression bomb (one zstd chunk that declares 1.5 GiB and inflates to it), a chunk that
declares 1 MiB and inflates to 1.5 GiB, a chunk record whose length is 2⁴⁰ bytes and one whose
uncompressed size is 2⁴⁰ bytes. Each verb that reads a bag (``bag info``, ``bag repair``,
``replay``, ``convert``) runs in a child process under a 512 MiB address-space limit
(RLIMIT_AS): a one-line answer naming the file and the byte offset, never a traceback or a
MemoryError. Also: a bag with one corrupted zstd chunk is one line before ``replay`` starts
(no ZstdError), metadata with only the keys a reader once checked is refused, and a damaged
chunk of a real bag is found at its offset.
"""

from __future__ import annotations

import os
import resource
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import pytest
import yaml

from mechsim.environment import import_rclpy

import_rclpy()

from rclpy.qos import QoSProfile  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402

from mechsim.cli import main  # noqa: E402
from mechsim.outputs.bag import BagWriter  # noqa: E402
from mechsim.outputs.bag.mcapread import MAX_CHUNK  # noqa: E402
from mechsim.outputs.wire import cdr_bytes  # noqa: E402

MAGIC = b"\x89MCAP0\r\n"
LIMIT_AS = 512 * 1024 * 1024
GIB = 1 << 30


def record(opcode: int, body: bytes, length: int | None = None) -> bytes:
    """One MCAP record: opcode u8, content length u64 (``length`` if given: a lie), content."""
    return struct.pack("<BQ", opcode, len(body) if length is None else length) + body


def text(s: str) -> bytes:
    return struct.pack("<I", len(s)) + s.encode()


def zstd_rle(size: int, byte: int = 0) -> bytes:
    """A zstd frame (RFC 8878) of ``size`` copies of ``byte`` in RLE blocks of 128 KiB: about
    4 bytes per 128 KiB, so 1.5 GiB take 48 KiB. The frame header declares the content size
    and a 128 KiB window (the decoder needs no more)."""
    block = 128 * 1024
    out = bytearray(struct.pack("<I", 0xFD2FB528))
    out += bytes([0xC0, 7 << 3]) + struct.pack("<Q", size)  # 8-byte content size, window
    left = size
    while left > 0:
        n = min(block, left)
        left -= n
        out += ((n << 3) | (1 << 1) | (left == 0)).to_bytes(3, "little") + bytes([byte])
    return bytes(out)


def chunk(data: bytes, declared: int, compression: str = "zstd", crc: int = 0,
          length: int | None = None) -> bytes:
    body = (struct.pack("<QQQI", 1_000_000_000, 1_000_000_000, declared, crc)
            + text(compression) + struct.pack("<Q", len(data)) + data)
    return record(0x06, body, length)


def mcap_file(*records: bytes) -> bytes:
    header = record(0x01, text("ros2") + text("hostile"))
    footer = record(0x02, struct.pack("<QQI", 0, 0, 0))
    return MAGIC + header + b"".join(records) + record(0x0F, struct.pack("<I", 0)) + footer \
        + MAGIC


def hostile_bag(d: Path, data: bytes) -> Path:
    """A bag directory whose metadata is complete and valid, and whose storage file is
    ``data``."""
    d.mkdir(parents=True)
    (d / f"{d.name}_0.mcap").write_bytes(data)
    (d / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": {
        "version": 9, "storage_identifier": "mcap", "relative_file_paths": [f"{d.name}_0.mcap"],
        "duration": {"nanoseconds": 0}, "starting_time": {"nanoseconds_since_epoch": 0},
        "message_count": 1, "topics_with_message_count": [{
            "topic_metadata": {"name": "/p/state", "type": "sensor_msgs/msg/JointState",
                               "serialization_format": "cdr", "offered_qos_profiles": ""},
            "message_count": 1}]}}))
    return d


BOMBS = {
    # declares 1.5 GiB and inflates to it (the decompression bomb)
    "declares_1.5GiB": lambda: chunk(zstd_rle(3 * GIB // 2), 3 * GIB // 2),
    # declares 1 MiB and inflates to 1.5 GiB
    "inflates_past": lambda: chunk(zstd_rle(3 * GIB // 2), 1 << 20),
    # a chunk record 2^40 bytes long
    "record_2^40": lambda: chunk(zstd_rle(1 << 20), 1 << 20, length=1 << 40),
    # a chunk declaring 2^40 bytes uncompressed
    "declares_2^40": lambda: chunk(zstd_rle(1 << 20), 1 << 40),
}


def _limit() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (LIMIT_AS, LIMIT_AS))


def run_limited(argv: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    """``mechsim ARGV`` in a child process whose address space is limited to 512 MiB."""
    return subprocess.run([sys.executable, "-m", "mechsim.cli", *argv], env=env,
                          capture_output=True, text=True, timeout=600, preexec_fn=_limit)


@pytest.mark.parametrize("bomb", sorted(BOMBS))
def test_bombs_are_refused_in_one_line_by_every_reader(bomb: str, tmp_path: Path,
                                                       ros_env: dict[str, str]) -> None:
    bag = hostile_bag(tmp_path / "bomb", mcap_file(BOMBS[bomb]()))
    storage = bag / "bomb_0.mcap"
    verbs = [["replay", str(bag), "--rate", "0", "--delay", "0"],
             ["convert", str(bag), "--rrd", str(tmp_path / "out.rrd")],
             ["bag", "repair", str(bag)]]
    if bomb != "inflates_past":  # (info reads no chunk's data: it checks declared sizes)
        verbs.insert(0, ["bag", "info", str(bag)])
    for argv in verbs:
        r = run_limited(argv, ros_env)
        assert "Traceback" not in r.stderr and "MemoryError" not in r.stderr, (argv, r.stderr)
        if argv[:2] == ["bag", "repair"]:
            # Repair salvages what is readable: the chunk is skipped, said in one line.
            lines = r.stdout.splitlines()
            assert r.returncode == 0 and len(lines) == 1, (argv, r.stdout, r.stderr)
            assert "at byte" in lines[0] and ("limit" in lines[0] or "declares" in lines[0]
                                               or "past the end" in lines[0]), lines
        else:
            errors = [ln for ln in r.stderr.splitlines() if ln.startswith("mechsim:")]
            assert r.returncode == 2 and len(errors) == 1, (argv, r.stderr)
            assert errors[0].startswith("mechsim: error: ") and storage.name in errors[0] \
                and "at byte" in errors[0], (argv, errors)
    assert not (tmp_path / "out.rrd").exists()


def _states(w: BagWriter, n: int) -> None:
    qos = QoSProfile(depth=10)
    for k in range(n):
        m = JointState(name=["q"], position=[float(k)], velocity=[0.5 * k])
        ns = 1_000_000_000 + 10_000_000 * k
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(ns, 1_000_000_000)
        w.write_bytes("/p/state", "sensor_msgs/msg/JointState", qos, ns, cdr_bytes(m))


def _chunk_offsets(path: Path) -> list[int]:
    """File offsets of the chunk records (from mcap's own summary: independent of the
    reader under test)."""
    from mcap.reader import make_reader

    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return sorted(ci.chunk_start_offset for ci in summary.chunk_indexes)


def test_a_corrupted_zstd_chunk_is_one_line_before_replay_starts(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = tmp_path / "b"
    w = BagWriter(bag, chunk_size=4096)
    _states(w, 400)
    w.close()
    storage = bag / "b_0.mcap"
    data = bytearray(storage.read_bytes())
    offsets = _chunk_offsets(storage)
    assert len(offsets) > 3
    at = offsets[2]
    # The third chunk's zstd frame loses its magic: "Unknown frame descriptor".
    name_len = struct.unpack_from("<I", data, at + 9 + 28)[0]
    frame = at + 9 + 28 + 4 + name_len + 8
    assert bytes(data[frame:frame + 4]) == struct.pack("<I", 0xFD2FB528)
    data[frame:frame + 4] = b"JUNK"
    storage.write_bytes(bytes(data))
    for argv in (["replay", str(bag), "--rate", "0", "--delay", "0"],
                 ["convert", str(bag), "--rrd", str(tmp_path / "x.rrd")]):
        rc = main(argv)
        err = capsys.readouterr().err
        assert rc == 2 and err.count("\n") == 1, (argv, err)
        assert err.startswith("mechsim: error: ") and f"at byte {at}:" in err \
            and "does not decompress" in err and "b_0.mcap" in err, err
    assert not (tmp_path / "x.rrd").exists()
    # Repair keeps the other chunks and says which one it skipped.
    assert main(["bag", "repair", str(bag)]) == 0
    out = capsys.readouterr().out
    assert "1 damaged chunk skipped" in out and f"at byte {at}:" in out, out


def test_metadata_with_only_the_keys_once_checked_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = tmp_path / "b"
    w = BagWriter(bag)
    _states(w, 3)
    w.close()
    (bag / "metadata.yaml").write_text(yaml.safe_dump({"rosbag2_bagfile_information": {
        "storage_identifier": "mcap", "relative_file_paths": ["b_0.mcap"],
        "topics_with_message_count": []}}))
    assert main(["bag", "info", str(bag)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("mechsim: error: ") \
        and "version: missing" in err, err


def test_declared_sizes_are_checked_before_anything_is_read(tmp_path: Path) -> None:
    """In-process, the reader's own answer for each bomb: the offset of the chunk record
    (after the magic and the header) and the limit it broke."""
    from mechsim.outputs.bag.mcapread import BadMcap, McapFile, verify

    header = len(MAGIC) + 9 + 4 + 4 + 4 + 7
    for name, expect in (("declares_1.5GiB", "above the reader's limit"),
                         ("inflates_past", "decompresses to more than the 1 MiB it declares"),
                         ("record_2^40", "runs past the end of the file"),
                         ("declares_2^40", "above the reader's limit")):
        path = tmp_path / f"{name}.mcap"
        path.write_bytes(mcap_file(BOMBS[name]()))
        with open(path, "rb") as stream:
            with pytest.raises(BadMcap) as e:
                verify(McapFile(stream, os.path.getsize(path)))
        assert e.value.offset == header and expect in e.value.reason, (name, e.value)
    assert MAX_CHUNK < 3 * GIB // 2


def test_a_chunk_failing_its_crc_is_never_read_as_messages(tmp_path: Path) -> None:
    from mechsim.outputs.bag.mcapread import BadMcap, McapFile, iter_messages

    body = b"\x05" + struct.pack("<Q", 22) + struct.pack("<HIQQ", 1, 0, 5, 5)
    path = tmp_path / "crc.mcap"
    path.write_bytes(mcap_file(chunk(body, len(body), "", crc=zlib.crc32(body) ^ 1)))
    with open(path, "rb") as stream:
        with pytest.raises(BadMcap, match="fails its CRC"):
            list(iter_messages(McapFile(stream, os.path.getsize(path))))


def test_lz4_chunks_are_read_and_bounded(tmp_path: Path) -> None:
    import lz4.frame

    from mechsim.outputs.bag.mcapread import BadMcap, McapFile, iter_messages

    schema = record(0x03, struct.pack("<H", 1) + text("std_msgs/msg/Empty") + text("ros2msg")
                    + text(""))
    channel = record(0x04, struct.pack("<HH", 1, 1) + text("/e") + text("cdr")
                     + struct.pack("<I", 0))
    messages = b"".join(record(0x05, struct.pack("<HIQQ", 1, k, 10 - k, 10 - k) + bytes([k]))
                        for k in range(5))
    plain = schema + channel + messages
    good = tmp_path / "good.mcap"
    good.write_bytes(mcap_file(chunk(lz4.frame.compress(plain), len(plain), "lz4")))
    with open(good, "rb") as stream:
        got = [(c.topic, m.log_time, m.data) for _, c, m in
               iter_messages(McapFile(stream, os.path.getsize(good)))]
    assert got == [("/e", 10 - k, bytes([k])) for k in reversed(range(5))]
    bomb = tmp_path / "bomb.mcap"
    bomb.write_bytes(mcap_file(chunk(lz4.frame.compress(bytes(64 << 20)), 1 << 20, "lz4")))
    with open(bomb, "rb") as stream:
        with pytest.raises(BadMcap, match="decompresses to more than"):
            list(iter_messages(McapFile(stream, os.path.getsize(bomb))))

