"""An MCAP file written a batch of messages at a time (the bag writer's storage).

``mcap.writer.Writer`` takes one message per Python call (a record object, an index tuple and
statistics updates each). Here a batch of fixed-size payloads (the rows of a
``mechsim.outputs.wire`` layout, see ``Outlet.publish_chunk``) becomes its Message records in a
few numpy operations (:meth:`McapFile.layout`): one (N, record bytes) array, the topics of one
sample side by side, so records in a chunk are in time order and any run of samples is one
contiguous slice, compressed and checksummed in place. A chunk costs a fixed handful of Python
operations, whatever it holds: its message indexes come from the batches' arrays, its records
are written in one call, and zstd and CRC-32 (ISA-L's) run without holding the interpreter
lock.

Memory stays flat however long the recording: the only thing that grows with the number of
chunks, their Chunk Index records (needed by the summary at the end), is kept in an anonymous
file in the output's directory beyond a small buffer (:class:`Spill`) and streamed into the
summary by :meth:`McapFile.finish`.

Everything else (header, schemas, channels, the summary's other records, footer) is written
with the record classes of ``mcap.records``, in the layout ``mcap.writer.Writer`` produces
(MCAP specification, https://mcap.dev/spec: Message record op 0x05 = channel_id u16, sequence
u32, log_time u64, publish_time u64, data; Message Index op 0x07 = channel_id u16, then
(log_time u64, offset u64) pairs prefixed by their byte length; Chunk op 0x06 = start and end
time u64, uncompressed size u64, uncompressed CRC-32 u32, compression (u32-prefixed string),
then the compressed records prefixed by a u64 length; Chunk Index op 0x08 = start and end time,
chunk offset and length u64, (channel u16, message index offset u64) pairs prefixed by their
byte length, message index length u64, compression, compressed and uncompressed size u64).
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any, NamedTuple

import numpy as np

from mechsim.files import anonymous_file

try:  # ISA-L's CRC-32: zlib's checksum, an order of magnitude faster on a chunk's records
    from isal.isal_zlib import crc32 as chunk_crc32
except ImportError:  # (isal is a dependency; zlib computes the same value)
    from zlib import crc32 as chunk_crc32  # noqa: F401 - the same name either way

MAGIC = struct.pack("<8B", 137, 77, 67, 65, 80, 48, 13, 10)
#: Message record header: opcode, record length, channel id, sequence, log and publish time.
_MESSAGE_HEAD = np.dtype([("op", "u1"), ("length", "<u8"), ("channel", "<u2"),
                          ("sequence", "<u4"), ("log_time", "<u8"), ("publish_time", "<u8")])
_HEAD = _MESSAGE_HEAD.itemsize  # 31
_OP_MESSAGE = 0x05
_OP_CHUNK = 0x06
_CHUNK_HEAD = struct.Struct("<BQQQQII4sQ")  # up to the compressed records ("zstd" only)
#: Message Index record up to its pairs: opcode, length, channel, pairs' byte length.
_MESSAGE_INDEX_HEAD = struct.Struct("<BQHI")
_OP_MESSAGE_INDEX = 0x07
_MESSAGE_INDEX_DTYPE = np.dtype([("op", "u1"), ("length", "<u8"), ("channel", "<u2"),
                                 ("bytes", "<u4")])
#: The Chunk Index's map from channel to the offset of its Message Index record.
_INDEX_MAP_DTYPE = np.dtype([("channel", "<u2"), ("offset", "<u8")])
_OP_CHUNK_INDEX = 0x08
_CHUNK_INDEX_HEAD = struct.Struct("<BQQQQQI")  # up to the message index offsets
_CHUNK_INDEX_TAIL = struct.Struct("<QI4sQQ")  # message index length ... uncompressed size
#: The level MCAP's own writers call "fast" (zstd level -3): a standard zstd frame that every
#: reader decodes with no setting. The writer thread shares the machine with the nodes, so its
#: time per sample bounds a fast recording; the samples' rows (byte columns that repeat from
#: row to row) still compress several-fold. Slower levels give smaller chunks at a cost the
#: benchmark's recording designs table shows (``mechsim bench --streaming``).
ZSTD_LEVEL = -3


class RecordBatch(NamedTuple):
    """The Message records of N samples, one on each of C channels per sample (see
    :meth:`McapFile.layout`)."""

    ns: np.ndarray  # (N,) int64 stamps, nondecreasing
    records: np.ndarray  # (N, S) uint8: row i = sample i's records, side by side
    channels: np.ndarray  # (C,) channel ids, ascending
    columns: np.ndarray  # (C,) byte offset of each channel's record within a row


class _RowLayout(NamedTuple):
    """The Message records of one sample on a set of topics (channel, payload size), side by
    side in a row of ``width`` bytes: each record's byte offset in the row (``columns``, in
    the topics' order) and its first 15 bytes (opcode, length, channel, sequence: the same in
    every row; the two stamps and the payload follow); the channels ascending, with their
    records' offsets in the row (``RecordBatch.channels``, ``RecordBatch.columns``)."""

    heads: np.ndarray  # (C, 15) uint8
    columns: np.ndarray  # (C,) offsets in the topics' order
    width: int
    channels: np.ndarray  # (C,) ascending
    offsets: np.ndarray  # (C,) the offsets in that order


class Spill:
    """Bytes appended during a run and read back once at its end, memory bounded: beyond
    ``buffer`` bytes they go to an anonymous file in ``directory`` (``files.anonymous_file``:
    no name, gone with the process), created at the first overflow."""

    def __init__(self, directory: str | Path, buffer: int = 64 * 1024) -> None:
        self.directory = directory
        self.buffer_limit = buffer
        self.buffer = bytearray()
        self.size = 0
        self._file: IO[bytes] | None = None

    def append(self, data: bytes) -> None:
        self.buffer += data
        self.size += len(data)
        if len(self.buffer) >= self.buffer_limit:
            if self._file is None:
                self._file = anonymous_file(self.directory)
            self._file.write(self.buffer)
            self.buffer = bytearray()

    def blocks(self, block: int = 1 << 20) -> Iterator[bytes]:
        """Everything appended, in order, ``block`` bytes at a time."""
        if self._file is not None:
            self._file.flush()
            self._file.seek(0)
            while data := self._file.read(block):
                yield data
        if self.buffer:
            yield bytes(self.buffer)

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None
        self.buffer = bytearray()


class McapFile:
    """Writes one MCAP file to ``stream`` (``start`` … ``finish``), messages in batches.
    Chunks are zstd-compressed (``ZSTD_LEVEL``) and closed by :meth:`flush`, or when they pass
    ``chunk_size`` uncompressed bytes. ``scratch`` is the output's own directory, where the
    chunk indexes wait for the summary (:class:`Spill`)."""

    def __init__(self, stream: IO[bytes], chunk_size: int, scratch: str | Path) -> None:
        import zstandard

        self.stream = stream
        self.chunk_size = chunk_size
        self.schemas: dict[int, Any] = {}
        self.channels: dict[int, Any] = {}
        #: The Chunk Index records, encoded, in order (the summary's largest part).
        self.chunk_indexes = Spill(scratch)
        self.metadata_indexes: list[Any] = []
        self.chunk_count = 0
        self.metadata_count = 0
        self.message_count = 0
        self.message_start_time = 0
        self.message_end_time = 0
        self._counts = np.zeros(1, dtype=np.int64)  # messages per channel id
        self._pos = stream.tell()
        self._layouts: dict[tuple[tuple[int, int], ...], _RowLayout] = {}
        # The chunk in progress: record bytes (buffers); what its message indexes hold, one
        # entry per batch (batch, first row, end row, the first row's offset in the chunk) or
        # message (channel, stamp, offset); its byte size and span.
        self._parts: list[Any] = []
        self._index: list[tuple[Any, ...]] = []
        self._size = 0
        self._start: int | None = None
        self._end = 0
        self._zstd = zstandard.ZstdCompressor(level=ZSTD_LEVEL)

    def _write(self, data: Any) -> None:
        self.stream.write(data)
        self._pos += memoryview(data).nbytes

    @staticmethod
    def _encode(record: Any) -> bytes:
        from mcap.data_stream import RecordBuilder

        b = RecordBuilder()
        record.write(b)
        return bytes(b.end())

    def start(self, profile: str, library: str) -> None:
        from mcap.records import Header

        self._write(MAGIC)
        self._write(self._encode(Header(profile=profile, library=library)))

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        from mcap.records import Metadata, MetadataIndex

        raw = self._encode(Metadata(name=name, metadata=data))
        self.metadata_indexes.append(MetadataIndex(offset=self._pos, length=len(raw),
                                                   name=name))
        self.metadata_count += 1
        self._write(raw)

    def _add_to_chunk(self, record: Any) -> None:
        raw = self._encode(record)
        self._parts.append(raw)
        self._size += len(raw)

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        from mcap.records import Schema

        sid = len(self.schemas) + 1
        self.schemas[sid] = s = Schema(id=sid, data=data, encoding=encoding, name=name)
        self._add_to_chunk(s)
        return sid

    def register_channel(self, topic: str, message_encoding: str, schema_id: int,
                         metadata: dict[str, str]) -> int:
        from mcap.records import Channel

        cid = len(self.channels) + 1
        self.channels[cid] = c = Channel(id=cid, topic=topic,
                                         message_encoding=message_encoding,
                                         schema_id=schema_id, metadata=metadata)
        self._counts = np.concatenate([self._counts, np.zeros(1, dtype=np.int64)])
        self._add_to_chunk(c)
        return cid

    def _row_layout(self, topics: list[tuple[int, np.ndarray]]) -> _RowLayout:
        """The row layout of ``topics`` (one entry per set of topics: a few)."""
        key = tuple((channel, rows.shape[1]) for channel, rows in topics)
        lay = self._layouts.get(key)
        if lay is None:
            if len(self._layouts) >= 64:
                self._layouts.clear()
            heads = np.array([np.frombuffer(struct.pack("<BQHI", _OP_MESSAGE,
                                                        _HEAD - 9 + size, channel, 0),
                                            dtype=np.uint8) for channel, size in key])
            sizes = np.array([_HEAD + size for _, size in key], dtype=np.int64)
            columns = np.concatenate(([0], np.cumsum(sizes)[:-1]))
            channels = np.array([channel for channel, _ in key], dtype=np.int64)
            order = np.argsort(channels, kind="stable")
            lay = self._layouts[key] = _RowLayout(heads, columns, int(sizes.sum()),
                                                  channels[order], columns[order])
        return lay

    @staticmethod
    def layout(ns: np.ndarray, topics: list[tuple[int, np.ndarray]],
               lay: _RowLayout) -> RecordBatch:
        """The records of N samples stamped ``ns`` (int64, nondecreasing), each with one
        message on every (channel id, (N, size) uint8 payload rows) of ``topics`` (distinct
        channels; their row layout ``lay``), in that order within a sample: each record's
        header, stamps and payload written as columns of one (N, row bytes) array (four
        copies per topic)."""
        ns = np.ascontiguousarray(ns, dtype="<i8")
        n, width = ns.shape[0], lay.width
        out = np.empty((n, width), dtype=np.uint8)
        for (_, rows), head, at in zip(topics, lay.heads, lay.columns.tolist(), strict=True):
            out[:, at:at + 15] = head
            # log time and publish time: one u64 a row, through a strided view
            np.ndarray((n,), "<i8", out, at + 15, (width,))[:] = ns
            np.ndarray((n,), "<i8", out, at + 23, (width,))[:] = ns
            out[:, at + _HEAD:at + _HEAD + rows.shape[1]] = rows
        return RecordBatch(ns, out, lay.channels, lay.offsets)

    def add_batch(self, ns: np.ndarray, topics: list[tuple[int, np.ndarray]]) -> None:
        """N samples stamped ``ns`` (int64, nondecreasing), each with one message on every
        (channel id, (N, size) uint8 payload rows) of ``topics``. Laid out a chunk's worth at
        a time: every chunk closes just past ``chunk_size``, and the rows being laid out,
        checksummed and compressed stay in the processor's cache."""
        n = len(ns)
        if not (n and topics):
            return
        lay = self._row_layout(topics)
        start = 0
        while start < n:
            end = min(n, start + max(1, (self.chunk_size - self._size) // lay.width + 1))
            self.add_rows(self.layout(ns[start:end],
                                      [(c, r[start:end]) for c, r in topics], lay),
                          0, end - start)
            start = end

    def add_rows(self, batch: RecordBatch, start: int, end: int) -> None:
        """Samples ``start`` to ``end`` (exclusive) of ``batch``, appended to the chunk in
        progress (closed once past ``chunk_size``)."""
        n = end - start
        if n <= 0:
            return
        self._index.append((batch, start, end, self._size))
        self._parts.append(batch.records[start:end].reshape(-1))
        self._size += n * batch.records.shape[1]
        self._counts[batch.channels] += n
        self._times(int(batch.ns[start]), int(batch.ns[end - 1]), n * batch.channels.shape[0])
        if self._size > self.chunk_size:
            self.flush_chunk()

    def add_message(self, channel: int, ns: int, data: bytes) -> None:
        """One message of any size."""
        head = struct.pack("<BQHIQQ", _OP_MESSAGE, _HEAD - 9 + len(data), channel, 0, ns, ns)
        self._index.append((channel, ns, self._size))
        self._counts[channel] += 1
        self._parts += (head, data)
        self._size += len(head) + len(data)
        self._times(ns, ns, 1)
        if self._size > self.chunk_size:
            self.flush_chunk()

    def _times(self, first: int, last: int, count: int) -> None:
        if self.message_count == 0 or first < self.message_start_time:
            self.message_start_time = first
        self.message_end_time = max(self.message_end_time, last)
        self.message_count += count
        self._start = first if self._start is None else min(self._start, first)
        self._end = max(self._end, last)

    def _message_indexes(self, at: int) -> tuple[Any, bytes, int]:
        """The chunk's Message Index records (one per channel, ascending; pairs in file
        order), to be written at file offset ``at``: (their bytes, the Chunk Index's map
        of (channel u16, offset u64), the number of channels)."""
        batches = [e for e in self._index if len(e) == 4]
        if len(batches) == 1:
            # A fast run's chunk: one batch (C records of n pairs, one (C, bytes) array),
            # and maybe a few single messages on other channels (/diagnostics).
            batch, start, end, base = batches[0]
            records = self._batch_indexes(batch, start, end, base)
            channels = batch.channels
            singles: dict[int, list[tuple[int, int]]] = {}
            for e in self._index:
                if len(e) == 3:
                    singles.setdefault(e[0], []).append((e[1], e[2]))
            if not singles:
                c = channels.shape[0]
                index_map = np.empty(c, dtype=_INDEX_MAP_DTYPE)
                index_map["channel"] = channels
                index_map["offset"] = at + np.arange(c, dtype=np.int64) * records.shape[1]
                return records.reshape(-1), index_map.tobytes(), c
            batch_channels = channels.tolist()
            if not singles.keys() & set(batch_channels):
                by_channel = dict(zip(batch_channels, records, strict=True))
                made: list[Any] = []
                placed: list[int] = []
                for channel in sorted((*batch_channels, *singles)):
                    row = by_channel.get(channel)
                    if row is None:
                        kept = singles[channel]
                        body = 16 * len(kept)
                        row = _MESSAGE_INDEX_HEAD.pack(
                            _OP_MESSAGE_INDEX, 2 + 4 + body, channel, body) + struct.pack(
                            f"<{2 * len(kept)}Q", *(v for pair in kept for v in pair))
                    made.append(row)
                    placed += (channel, at)
                    at += len(row)
                return (b"".join(made), struct.pack("<" + "HQ" * len(made), *placed),
                        len(made))
        entries: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        for e in self._index:
            if len(e) == 4:
                batch, start, end, base = e
                n = end - start
                rows = np.arange(n, dtype=np.int64) * batch.records.shape[1] + base
                entries.append((np.repeat(batch.channels, n),
                                np.tile(batch.ns[start:end], batch.channels.shape[0]),
                                (batch.columns[:, None] + rows[None, :]).reshape(-1)))
            else:
                entries.append((np.array([e[0]], dtype=np.int64), np.array([e[1]], dtype=np.int64),
                                np.array([e[2]], dtype=np.int64)))
        channels, stamps, offsets = (np.concatenate(a) for a in zip(*entries, strict=True))
        order = np.lexsort((offsets, channels))
        pairs = np.empty((channels.shape[0], 2), dtype="<u8")
        pairs[:, 0] = stamps[order]
        pairs[:, 1] = offsets[order]
        channels = channels[order]
        bounds = np.flatnonzero(np.diff(channels)) + 1
        starts = [0, *bounds.tolist()]
        ends = [*bounds.tolist(), channels.shape[0]]
        indexes: list[Any] = []
        where: list[int] = []
        for channel, lo, hi in zip(channels[starts].tolist(), starts, ends, strict=True):
            body = 16 * (hi - lo)
            indexes += (_MESSAGE_INDEX_HEAD.pack(_OP_MESSAGE_INDEX, 2 + 4 + body, channel,
                                                 body), pairs[lo:hi])
            where += (channel, at)
            at += _MESSAGE_INDEX_HEAD.size + body
        return (b"".join(indexes), struct.pack("<" + "HQ" * len(starts), *where),
                len(starts))

    @staticmethod
    def _batch_indexes(batch: RecordBatch, start: int, end: int, base: int) -> np.ndarray:
        """The Message Index records of rows ``start`` to ``end`` of ``batch`` (the first
        at byte ``base`` of the chunk): a (C, bytes) array, one record per channel, in the
        batch's (ascending) channel order."""
        n, channels = end - start, batch.channels
        c = channels.shape[0]
        head = np.empty(c, dtype=_MESSAGE_INDEX_DTYPE)
        head["op"], head["length"], head["channel"], head["bytes"] = \
            _OP_MESSAGE_INDEX, 6 + 16 * n, channels, 16 * n
        records = np.empty((c, _MESSAGE_INDEX_HEAD.size + 16 * n), dtype=np.uint8)
        records[:, :_MESSAGE_INDEX_HEAD.size] = head.view(np.uint8).reshape(c, -1)
        pairs = records[:, _MESSAGE_INDEX_HEAD.size:].view("<u8").reshape(c, n, 2)
        pairs[:, :, 0] = batch.ns[start:end]
        pairs[:, :, 1] = batch.columns[:, None] + (
            np.arange(n, dtype=np.int64) * batch.records.shape[1] + base)
        return records

    def flush_chunk(self) -> None:
        """Close the chunk in progress (if it holds a message): Chunk record, then one
        Message Index record per channel, in one write (a chunk reaches the file whole or
        not at all: a full disk keeps every chunk before); its Chunk Index to the spill."""
        if self._start is None:
            return
        data = self._parts[0] if len(self._parts) == 1 else b"".join(self._parts)
        compressed = self._zstd.compress(data)
        head = _CHUNK_HEAD.pack(_OP_CHUNK, _CHUNK_HEAD.size - 9 + len(compressed),
                                self._start, self._end, self._size, chunk_crc32(data),
                                4, b"zstd", len(compressed))
        chunk_start = self._pos
        chunk_length = len(head) + len(compressed)
        indexes, index_map, channels = self._message_indexes(chunk_start + chunk_length)
        self._write(b"".join((head, compressed, indexes)))
        chunk_index = (
            _CHUNK_INDEX_HEAD.pack(_OP_CHUNK_INDEX, 8 * 4 + 4 + 10 * channels
                                   + _CHUNK_INDEX_TAIL.size, self._start, self._end,
                                   chunk_start, chunk_length, 10 * channels)
            + index_map
            + _CHUNK_INDEX_TAIL.pack(memoryview(indexes).nbytes, 4, b"zstd",
                                     len(compressed), self._size))
        self.chunk_indexes.append(chunk_index)
        self.chunk_count += 1
        self._parts, self._index, self._size, self._start, self._end = [], [], 0, None, 0

    def flush(self) -> None:
        """Close the chunk in progress and flush the stream."""
        self.flush_chunk()
        self.stream.flush()

    def finish(self) -> None:
        """Data end, the summary section (as ``mcap.writer.Writer`` writes it, the chunk
        indexes streamed from the spill), footer."""
        from mcap.opcode import Opcode
        from mcap.records import DataEnd, Footer, Statistics, SummaryOffset

        self.flush_chunk()  # (schemas and channels of no message are in the summary only)
        self._write(self._encode(DataEnd(data_section_crc=0)))
        stats = Statistics(
            attachment_count=0, channel_count=len(self.channels),
            channel_message_counts={c: int(k) for c, k in enumerate(self._counts.tolist())
                                    if k},
            chunk_count=self.chunk_count, message_count=self.message_count,
            message_end_time=self.message_end_time,
            message_start_time=self.message_start_time, metadata_count=self.metadata_count,
            schema_count=len(self.schemas))
        summary_start = self._pos
        crc = 0
        groups: list[Any] = []

        def group(opcode: int, pieces: Any) -> None:
            nonlocal crc
            start = self._pos
            for data in pieces:
                crc = zlib.crc32(data, crc)
                self._write(data)
            groups.append(SummaryOffset(group_opcode=opcode, group_start=start,
                                        group_length=self._pos - start))

        group(Opcode.SCHEMA, [self._encode(s) for s in self.schemas.values()])
        group(Opcode.CHANNEL, [self._encode(c) for c in self.channels.values()])
        group(Opcode.STATISTICS, [self._encode(stats)])
        group(Opcode.CHUNK_INDEX, self.chunk_indexes.blocks())
        group(Opcode.ATTACHMENT_INDEX, [])
        group(Opcode.METADATA_INDEX, [self._encode(m) for m in self.metadata_indexes])
        self.chunk_indexes.close()
        offset_start = self._pos
        offsets = b"".join(self._encode(g) for g in groups)
        crc = zlib.crc32(offsets, crc)
        self._write(offsets)
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 8 + 8 + 4, summary_start,
                                     offset_start), crc)
        self._write(self._encode(Footer(summary_start=summary_start,
                                        summary_offset_start=offset_start, summary_crc=crc)))
        self._write(MAGIC)
