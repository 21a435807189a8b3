"""An MCAP file written a batch of messages at a time (the bag writer's storage).

``mcap.writer.Writer`` takes one message per Python call (a record object, an index tuple and
statistics updates each: ~4 µs a message). Here a batch of fixed-size payloads (the rows of a
``mechsim.outputs.cdr`` layout, see ``Outlet.publish_chunk``) becomes its Message records in a
few numpy operations: one (N, record bytes) array per topic, the topics of one sample side by
side, so records in a chunk are in time order. Everything else (header, schemas, channels,
chunks, message indexes, the summary with its statistics, chunk, metadata index and summary
offsets, footer) is written with the record classes of ``mcap.records``, in the layout
``mcap.writer.Writer`` produces (MCAP specification, https://mcap.dev/spec: Message record op
0x05 = channel_id u16, sequence u32, log_time u64, publish_time u64, data; Message Index op
0x07 = channel_id u16, then (log_time u64, offset u64) pairs prefixed by their byte length;
Chunk op 0x06 = start and end time u64, uncompressed size u64, uncompressed CRC-32 u32,
compression (u32-prefixed string), then the compressed records prefixed by a u64 length).
"""

from __future__ import annotations

import struct
import zlib
from collections import defaultdict
from typing import IO, Any

import numpy as np

MAGIC = struct.pack("<8B", 137, 77, 67, 65, 80, 48, 13, 10)
#: Message record header: opcode, record length, channel id, sequence, log and publish time.
_MESSAGE_HEAD = np.dtype([("op", "u1"), ("length", "<u8"), ("channel", "<u2"),
                          ("sequence", "<u4"), ("log_time", "<u8"), ("publish_time", "<u8")])
_HEAD = _MESSAGE_HEAD.itemsize  # 31
_OP_MESSAGE = 0x05
_OP_MESSAGE_INDEX = 0x07
_OP_CHUNK = 0x06
_CHUNK_HEAD = struct.Struct("<BQQQQII4sQ")  # up to the compressed records ("zstd" only)


def message_records(ns: np.ndarray, topics: list[tuple[int, np.ndarray]]
                    ) -> tuple[np.ndarray, list[np.ndarray]]:
    """Message records of N samples: row i holds sample i's record of every (channel id,
    (N, size) payload rows) in ``topics``, side by side. Returns the (N, S) byte array and,
    per topic, the byte offset of each of its records from the start of the array."""
    n = int(ns.shape[0])
    widths = [_HEAD + rows.shape[1] for _, rows in topics]
    total = sum(widths)
    out = np.empty((n, total), dtype=np.uint8)
    head = np.empty(n, dtype=_MESSAGE_HEAD)
    head["op"] = _OP_MESSAGE
    head["sequence"] = 0
    head["log_time"] = ns
    head["publish_time"] = ns
    offsets = []
    col = 0
    row_start = np.arange(n, dtype=np.int64) * total
    for (channel, rows), width in zip(topics, widths, strict=True):
        head["length"] = width - 9
        head["channel"] = channel
        out[:, col:col + _HEAD] = head.view(np.uint8).reshape(n, _HEAD)
        out[:, col + _HEAD:col + width] = rows
        offsets.append(row_start + col)
        col += width
    return out, offsets


class McapFile:
    """Writes one MCAP file to ``stream`` (``start`` … ``finish``), messages in batches.
    Chunks are zstd-compressed (level 1)
    and closed by :meth:`flush`, or when they pass ``chunk_size`` uncompressed bytes."""

    def __init__(self, stream: IO[bytes], chunk_size: int) -> None:
        from mcap.records import Statistics

        self.stream = stream
        self.chunk_size = chunk_size
        self.schemas: dict[int, Any] = {}
        self.channels: dict[int, Any] = {}
        #: The Chunk Index records, already encoded (memory: ~100 bytes per chunk, not a
        #: Python object per chunk).
        self.chunk_indexes = bytearray()
        self.metadata_indexes: list[Any] = []
        self.stats = Statistics(attachment_count=0, channel_count=0,
                                channel_message_counts=defaultdict(int), chunk_count=0,
                                message_count=0, message_end_time=0, message_start_time=0,
                                metadata_count=0, schema_count=0)
        self._parts: list[bytes] = []  # uncompressed records of the chunk in progress
        self._size = 0
        self._index: dict[int, list[tuple[np.ndarray, np.ndarray]]] = defaultdict(list)
        self._start: int | None = None
        self._end = 0
        import zstandard

        # Level 1: the fastest standard level (chunks are small; readers need no setting).
        self._zstd = zstandard.ZstdCompressor(level=1)

    def _builder(self) -> Any:
        from mcap.data_stream import RecordBuilder

        return RecordBuilder()

    def _write_record(self, record: Any) -> None:
        b = self._builder()
        record.write(b)
        self.stream.write(b.end())

    def start(self, profile: str, library: str) -> None:
        from mcap.records import Header

        self.stream.write(MAGIC)
        self._write_record(Header(profile=profile, library=library))

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        from mcap.records import Metadata, MetadataIndex

        b = self._builder()
        Metadata(name=name, metadata=data).write(b)
        raw = b.end()
        self.metadata_indexes.append(MetadataIndex(offset=self.stream.tell(),
                                                   length=len(raw), name=name))
        self.stats.metadata_count += 1
        self.stream.write(raw)

    def _add_to_chunk(self, record: Any) -> None:
        b = self._builder()
        record.write(b)
        raw = b.end()
        self._parts.append(raw)
        self._size += len(raw)

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        from mcap.records import Schema

        sid = len(self.schemas) + 1
        self.schemas[sid] = s = Schema(id=sid, data=data, encoding=encoding, name=name)
        self.stats.schema_count += 1
        self._add_to_chunk(s)
        return sid

    def register_channel(self, topic: str, message_encoding: str, schema_id: int,
                         metadata: dict[str, str]) -> int:
        from mcap.records import Channel

        cid = len(self.channels) + 1
        self.channels[cid] = c = Channel(id=cid, topic=topic,
                                         message_encoding=message_encoding,
                                         schema_id=schema_id, metadata=metadata)
        self.stats.channel_count += 1
        self._add_to_chunk(c)
        return cid

    def add_batch(self, ns: np.ndarray, topics: list[tuple[int, np.ndarray]]) -> None:
        """N samples stamped ``ns`` (int64, nondecreasing), each with one message on every
        (channel id, (N, size) uint8 payload rows) of ``topics``."""
        n = int(ns.shape[0])
        if n == 0 or not topics:
            return
        records, offsets = message_records(ns, topics)
        ns = np.asarray(ns, dtype=np.int64)
        for (channel, _), off in zip(topics, offsets, strict=True):
            self._index[channel].append((ns, off + self._size))
            self.stats.channel_message_counts[channel] += n
        self._parts.append(records.tobytes())
        self._size += records.size
        self._times(int(ns[0]), int(ns[-1]), n * len(topics))
        if self._size > self.chunk_size:
            self.flush_chunk()

    def add_message(self, channel: int, ns: int, data: bytes) -> None:
        """One message of any size."""
        head = np.empty(1, dtype=_MESSAGE_HEAD)
        head["op"], head["length"], head["channel"] = _OP_MESSAGE, _HEAD - 9 + len(data), channel
        head["sequence"], head["log_time"], head["publish_time"] = 0, ns, ns
        self._index[channel].append((np.array([ns], dtype=np.int64),
                                     np.array([self._size], dtype=np.int64)))
        self.stats.channel_message_counts[channel] += 1
        raw = head.tobytes() + data
        self._parts.append(raw)
        self._size += len(raw)
        self._times(ns, ns, 1)
        if self._size > self.chunk_size:
            self.flush_chunk()

    def _times(self, first: int, last: int, count: int) -> None:
        s = self.stats
        s.message_start_time = first if s.message_count == 0 else min(s.message_start_time,
                                                                      first)
        s.message_end_time = max(s.message_end_time, last)
        s.message_count += count
        self._start = first if self._start is None else min(self._start, first)
        self._end = max(self._end, last)

    def flush_chunk(self) -> None:
        """Close the chunk in progress (if it holds a message): Chunk record, then one
        Message Index record per channel."""
        from mcap.records import ChunkIndex

        if self._start is None:
            return
        data = b"".join(self._parts)
        compressed = self._zstd.compress(data)
        # Chunk record (op 0x06): start, end, uncompressed size, uncompressed CRC, compression
        # (a prefixed string), records (a prefixed byte string); written as two pieces.
        head = _CHUNK_HEAD.pack(_OP_CHUNK, _CHUNK_HEAD.size - 9 + len(compressed),
                                self._start, self._end, len(data), zlib.crc32(data),
                                4, b"zstd", len(compressed))
        chunk_start = self.stream.tell()
        self.stream.write(head)
        self.stream.write(compressed)
        chunk_length = len(head) + len(compressed)
        index_start = chunk_start + chunk_length
        offsets: dict[int, int] = {}
        pieces = []
        pos = index_start
        for channel in sorted(self._index):
            parts = self._index[channel]
            pairs = np.empty((sum(p[0].size for p in parts), 2), dtype="<u8")
            pairs[:, 0] = np.concatenate([p[0] for p in parts])
            pairs[:, 1] = np.concatenate([p[1] for p in parts])
            body = pairs.tobytes()
            rec = struct.pack("<BQHI", _OP_MESSAGE_INDEX, 2 + 4 + len(body), channel,
                              len(body)) + body
            offsets[channel] = pos
            pos += len(rec)
            pieces.append(rec)
        self.stream.write(b"".join(pieces))
        b = self._builder()
        ChunkIndex(message_start_time=self._start, message_end_time=self._end,
                   chunk_start_offset=chunk_start, chunk_length=chunk_length,
                   message_index_offsets=offsets, message_index_length=pos - index_start,
                   compression="zstd", compressed_size=len(compressed),
                   uncompressed_size=len(data)).write(b)
        self.chunk_indexes += b.end()
        self.stats.chunk_count += 1
        self._parts, self._size, self._start, self._end = [], 0, None, 0
        self._index = defaultdict(list)

    def flush(self) -> None:
        """Close the chunk in progress and flush the stream."""
        self.flush_chunk()
        self.stream.flush()

    def finish(self) -> None:
        """Data end, the summary section (as ``mcap.writer.Writer`` writes it), footer."""
        from mcap.opcode import Opcode
        from mcap.records import DataEnd, Footer, SummaryOffset

        self.flush_chunk()  # (schemas and channels of no message are in the summary only)
        self._write_record(DataEnd(data_section_crc=0))
        summary_start = self.stream.tell()
        b = self._builder()
        groups: list[Any] = []
        for opcode, records in ((Opcode.SCHEMA, list(self.schemas.values())),
                                (Opcode.CHANNEL, list(self.channels.values())),
                                (Opcode.STATISTICS, [self.stats]),
                                (Opcode.CHUNK_INDEX, [bytes(self.chunk_indexes)]),
                                (Opcode.ATTACHMENT_INDEX, []),
                                (Opcode.METADATA_INDEX, self.metadata_indexes)):
            start = b.count
            for r in records:
                if isinstance(r, bytes):
                    b.write(r)
                else:
                    r.write(b)
            groups.append(SummaryOffset(group_opcode=opcode, group_start=summary_start + start,
                                        group_length=b.count - start))
        offset_start = summary_start + b.count
        for g in groups:
            g.write(b)
        summary = b.end()
        crc = zlib.crc32(summary)
        crc = zlib.crc32(struct.pack("<BQQQ", Opcode.FOOTER, 8 + 8 + 4, summary_start,
                                     offset_start), crc)
        self.stream.write(summary)
        self._write_record(Footer(summary_start=summary_start,
                                  summary_offset_start=offset_start, summary_crc=crc))
        self.stream.write(MAGIC)
