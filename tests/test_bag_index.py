"""The bag's indexes over long recordings: the chunk indexes the summary needs are kept out of
memory (an anonymous file in the bag directory), so memory stays flat however many chunks are
written, and the finished file's summary still lists every chunk, checked against a walk of
the file written from the MCAP specification, the ``mcap`` library and ``rosbags``."""

from __future__ import annotations

import os
import struct
import tracemalloc
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pytest

SECOND = 1_000_000_000


def _walk(data: bytes) -> list[tuple[int, int, bytes]]:
    """(offset, opcode, content) of every top-level record, from the MCAP framing (magic,
    then opcode u8, length u64, content; magic again at the end)."""
    assert data[:8] == data[-8:] == b"\x89MCAP0\r\n"
    out, pos = [], 8
    while pos < len(data) - 8:
        op, length = struct.unpack_from("<BQ", data, pos)
        out.append((pos, op, data[pos + 9:pos + 9 + length]))
        pos += 9 + length
    assert pos == len(data) - 8
    return out


def _check_file(path: Path) -> dict[int, int]:
    """Every chunk of the MCAP file at ``path`` is listed by the summary, in order, with its
    offset, length, time range, sizes and message indexes; each message index entry points at
    a Message record of that channel and stamp; the summary CRC holds. Returns the message
    count per channel found in the chunks."""
    import zstandard
    from mcap.reader import make_reader

    data = path.read_bytes()
    records = _walk(data)
    at = {pos: (op, body) for pos, op, body in records}
    chunks = [(pos, body) for pos, op, body in records if op == 0x06]
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and summary.statistics is not None
    indexes = summary.chunk_indexes
    assert [ci.chunk_start_offset for ci in indexes] == [pos for pos, _ in chunks]
    assert summary.statistics.chunk_count == len(chunks)
    counts: dict[int, int] = {}
    for ci, (_, body) in zip(indexes, chunks, strict=True):
        start, end, size, crc, n = struct.unpack_from("<QQQII", body)
        compression = body[32:32 + n].decode()
        (clen,) = struct.unpack_from("<Q", body, 32 + n)
        raw = body[40 + n:40 + n + clen]
        assert (ci.message_start_time, ci.message_end_time) == (start, end)
        assert (ci.chunk_length, ci.compression, ci.compressed_size, ci.uncompressed_size) \
            == (9 + len(body), compression, clen, size)
        plain = zstandard.ZstdDecompressor().decompress(raw, max_output_size=size)
        assert len(plain) == size and zlib.crc32(plain) == crc
        messages = {}
        for p, op, rec in _walk(b"\x89MCAP0\r\n" + plain + b"\x89MCAP0\r\n"):
            if op == 0x05:
                channel, _, log_time = struct.unpack_from("<HIQ", rec)
                messages[p - 8] = (channel, log_time)
        indexed = 0
        length = 0
        for channel, offset in ci.message_index_offsets.items():
            op, body_ = at[offset]
            assert op == 0x07
            ch, nbytes = struct.unpack_from("<HI", body_)
            assert ch == channel and nbytes == len(body_) - 6
            pairs = np.frombuffer(body_[6:], dtype="<u8").reshape(-1, 2)
            assert list(pairs[:, 1]) == sorted(pairs[:, 1])
            for log_time, off in pairs.tolist():
                assert messages[off] == (channel, log_time)
            indexed += len(pairs)
            length += 9 + len(body_)
            counts[channel] = counts.get(channel, 0) + len(pairs)
        assert indexed == len(messages) and ci.message_index_length == length
    # Summary CRC: from the summary start through the footer's offsets (MCAP specification).
    footer_pos = len(data) - 8 - 29
    assert data[footer_pos] == 0x02
    summary_start, _, summary_crc = struct.unpack_from("<QQI", data, footer_pos + 9)
    assert zlib.crc32(data[summary_start:footer_pos + 25]) == summary_crc
    assert dict(summary.statistics.channel_message_counts) == counts
    return counts


def _layout_inputs(k: int, n: int) -> tuple[np.ndarray, list[tuple[int, np.ndarray]]]:
    """Sample k*n … k*n+n-1, one simulated second apart, on channels 1 (8-byte payload) and
    2 (20-byte payload): every sample closes a chunk when flushed."""
    ns = (np.arange(k * n, k * n + n, dtype=np.int64)) * SECOND
    a = np.repeat(np.arange(k * n, k * n + n, dtype="<u8")[:, None], 1, 1).view(np.uint8)
    b = np.full((n, 20), k % 251, dtype=np.uint8)
    return ns, [(1, a), (2, b)]


def test_chunk_index_memory_is_bounded(tmp_path: Path) -> None:
    """Thousands of chunks: the memory Python holds (all allocations, traced) stays within
    the spill's small buffer while the encoded chunk indexes grow many times larger; the
    closed file's summary lists every chunk."""
    from mechsim.outputs.bag.mcapfile import McapFile

    f = tmp_path / "x.mcap"
    with open(f, "wb") as stream:
        w = McapFile(stream, chunk_size=1 << 20, scratch=tmp_path)
        w.start("ros2", "test")
        sid = w.register_schema("pkg/msg/T", "ros2msg", b"uint64 x")
        for topic in ("/a", "/b"):
            w.register_channel(topic, "cdr", sid, {})

        def chunks(first: int, count: int) -> None:
            for k in range(first, first + count):
                ns, topics = _layout_inputs(k, 1)
                w.add_batch(ns, topics)
                w.flush_chunk()

        chunks(0, 1000)
        tracemalloc.start()
        try:
            before = tracemalloc.get_traced_memory()[0]
            index_bytes = w.chunk_indexes.size
            chunks(1000, 8000)
            grown = tracemalloc.get_traced_memory()[0] - before
        finally:
            tracemalloc.stop()
        spilled = w.chunk_indexes.size - index_bytes
        assert w.chunk_count == 9000
        assert spilled > 8 * w.chunk_indexes.buffer_limit  # what the old writer kept
        assert grown < 2 * w.chunk_indexes.buffer_limit, (grown, spilled)
        w.finish()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.mcap"]  # no temporary left
    assert _check_file(f) == {1: 9000, 2: 9000}


@pytest.mark.parametrize("tmpfile", [True, False], ids=["O_TMPFILE", "named-then-unlinked"])
def test_long_recording_lists_every_chunk(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                          tmpfile: bool) -> None:
    """A recording of 3000 chunks (one per hand-off: a 1-byte chunk size) through the bag
    writer, its chunk indexes spilled to an anonymous file (O_TMPFILE, or the exclusive named
    file unlinked at once where O_TMPFILE is not available): the summary lists every chunk,
    ``rosbags`` reads every message with its stamp, and the bag directory holds only the
    bag's two files, during the recording and after."""
    from rclpy.qos import QoSProfile
    from rosbags.highlevel import AnyReader

    from mechsim import files
    from mechsim.outputs.bag import LOCK_FILE, mcapfile
    from mechsim.outputs.bag.writer import BagWriter

    if not tmpfile:
        monkeypatch.delattr(os, "O_TMPFILE", raising=False)
    spills: list[Any] = []

    def anonymous_file(directory: Any) -> Any:
        spills.append(f := files.anonymous_file(directory))
        assert sorted(p.name for p in Path(directory).iterdir()) == [
            LOCK_FILE, "bag_0.mcap"]  # the spill has no name
        return f

    monkeypatch.setattr(mcapfile, "anonymous_file", anonymous_file)
    path = tmp_path / "bag"
    qos = QoSProfile(depth=10)
    items, n = 3000, 1
    with BagWriter(path, chunk_size=1) as bag:
        for k in range(items):
            ns = np.arange(k * n, (k + 1) * n, dtype=np.int64) * SECOND
            a = np.full((n, 8), k % 256, dtype=np.uint8)
            b = np.repeat(np.arange(n, dtype=np.uint8)[:, None], 12, 1)
            bag.write_rows(ns, [("/a", "std_msgs/msg/UInt64", qos, a),
                                 ("/b", "std_msgs/msg/String", qos, b)])
    assert len(spills) == 1 and spills[0].closed
    assert sorted(p.name for p in path.iterdir()) == ["bag_0.mcap", "metadata.yaml"]
    counts = _check_file(path / "bag_0.mcap")
    assert sorted(counts.values()) == [items * n, items * n]
    with AnyReader([path]) as reader:
        got = [(con.topic, ts) for con, ts, _ in reader.messages()]
    expected = [(t, k * SECOND) for k in range(items * n) for t in ("/a", "/b")]
    assert sorted(got) == sorted(expected)


def test_chunks_mixing_batches_and_single_messages_are_indexed(tmp_path: Path) -> None:
    """Chunks holding batches and single messages on the same channels, in any order: every
    message index entry points at its message, the channels' entries in file order."""
    from mechsim.outputs.bag.mcapfile import McapFile

    f = tmp_path / "x.mcap"
    with open(f, "wb") as stream:
        w = McapFile(stream, chunk_size=1 << 20, scratch=tmp_path)
        w.start("ros2", "test")
        sid = w.register_schema("pkg/msg/T", "ros2msg", b"uint64 x")
        for topic in ("/a", "/b", "/c"):
            w.register_channel(topic, "cdr", sid, {})
        for k in range(6):
            w.add_message(3, k * 10 * SECOND, b"first" * k)
            ns, topics = _layout_inputs(k, 10)
            w.add_batch(ns, topics[::-1])  # channels given in descending order
            w.add_message(2, (k * 10 + 9) * SECOND, b"last")
            if k % 2:
                w.flush_chunk()
        w.finish()
    assert _check_file(f) == {1: 60, 2: 66, 3: 6}
