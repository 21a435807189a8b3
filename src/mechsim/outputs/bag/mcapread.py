"""Reading MCAP files within bounds this reader sets, whatever a file declares.

Every length in an MCAP file is a claim of the file. Here each is checked before anything is
allocated for it: a record must fit in what is left of the file (or of its chunk) and below
:data:`MAX_RECORD`; a chunk's uncompressed size must be below :data:`MAX_CHUNK`, and its data
is decompressed as a stream, a block at a time, into at most that many bytes (zstd, lz4 or
none): a chunk that inflates past what it declares is refused when it passes it. Fields inside
a record (strings, maps, byte arrays) are read against the record's own length. Messages wait
in memory for their turn (log-time order) only up to :data:`MAX_PENDING`. Anything that breaks
a bound or does not parse is a :class:`BadMcap`: the byte offset of the record and one line of
reason, which the bag reader turns into one line naming the file.

The file is walked record by record (opcode, length, content: MCAP specification,
https://mcap.dev/spec), without trusting its summary: :func:`scan` reads the framing and the
headers of the chunks (no decompression), :func:`verify` also decompresses and parses every
chunk (one at a time), :func:`iter_messages` yields the messages in log-time order (ties in
file order, as ``mcap``'s reader orders them), loading a chunk only when its first message may
be next, and :func:`walk` gives every readable record in file order for a repair, a damaged
chunk reported and skipped.
"""

from __future__ import annotations

import heapq
import struct
import zlib
from array import array
from collections.abc import Iterator
from dataclasses import dataclass
from typing import IO, Any, NamedTuple

MAGIC = b"\x89MCAP0\r\n"
#: Largest uncompressed chunk accepted (mechsim writes 512 KiB chunks, rosbag2 and other
#: writers a few MiB).
MAX_CHUNK = 64 * 1024 * 1024
#: Largest record other than a chunk that is read into memory (a schema, channel, metadata
#: record, a message outside chunks, a summary record).
MAX_RECORD = 64 * 1024 * 1024
#: Most bytes of messages held in memory while ordering them by log time (chunks whose time
#: ranges overlap are loaded together).
MAX_PENDING = 256 * 1024 * 1024
#: Decompression output per step.
_BLOCK = 1 << 20
#: Longest compression name accepted ("zstd", "lz4", "").
_MAX_NAME = 64
#: Messages outside chunks are loaded in runs of at most this many bytes.
_RUN_BYTES = 4 * 1024 * 1024

OP_HEADER, OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK = 0x01, 0x02, 0x03, 0x04, \
    0x05, 0x06
OP_METADATA, OP_DATA_END = 0x0C, 0x0F
_FOOTER_SIZE = 9 + 20
_CHUNK_FIXED = struct.Struct("<QQQI")  # start, end, uncompressed size, uncompressed crc
_MESSAGE_FIXED = struct.Struct("<HIQQ")  # channel, sequence, log time, publish time


class BadMcap(ValueError):
    """A record that breaks a bound or does not parse: its byte ``offset`` and the reason."""

    def __init__(self, offset: int, reason: str) -> None:
        super().__init__(f"at byte {offset}: {reason}")
        self.offset = offset
        self.reason = reason


def size_text(n: int) -> str:
    """``n`` bytes as a short text (``1.5 GiB``)."""
    value = float(n)
    for unit in ("bytes", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if value < 1024 or unit == "PiB":
            return f"{n} bytes" if unit == "bytes" else f"{value:.3g} {unit}"
        value /= 1024
    return f"{n} bytes"  # (not reached)


class Header(NamedTuple):
    profile: str
    library: str


class Schema(NamedTuple):
    id: int
    name: str
    encoding: str
    data: bytes


class Channel(NamedTuple):
    id: int
    schema_id: int
    topic: str
    message_encoding: str
    metadata: dict[str, str]


class Message(NamedTuple):
    channel_id: int
    sequence: int
    log_time: int
    publish_time: int
    data: bytes


class Metadata(NamedTuple):
    name: str
    metadata: dict[str, str]


class _Fields:
    """The fields of one record's content, each read against the content's length."""

    def __init__(self, data: memoryview, offset: int, kind: str) -> None:
        self.data, self.pos, self.offset, self.kind = data, 0, offset, kind

    def _take(self, n: int) -> memoryview:
        if n > len(self.data) - self.pos:
            raise BadMcap(self.offset, f"{self.kind} record: a field runs past its end")
        piece = self.data[self.pos:self.pos + n]
        self.pos += n
        return piece

    def uint(self, size: int) -> int:
        return int.from_bytes(self._take(size), "little")

    def text(self) -> str:
        try:
            return str(self._take(self.uint(4)), "utf-8")
        except UnicodeDecodeError:
            raise BadMcap(self.offset, f"{self.kind} record: a string is not UTF-8") from None

    def blob(self, size_bytes: int = 4) -> bytes:
        return bytes(self._take(self.uint(size_bytes)))

    def mapping(self) -> dict[str, str]:
        end = self.uint(4)
        inner = _Fields(self._take(end), self.offset, self.kind)
        out = {}
        while inner.pos < len(inner.data):
            key = inner.text()
            out[key] = inner.text()
        return out

    def rest(self) -> bytes:
        return bytes(self._take(len(self.data) - self.pos))


def parse_record(opcode: int, body: memoryview, offset: int) -> Any:
    """The record of ``opcode`` with content ``body`` (at byte ``offset``): a Header,
    Schema, Channel, Message or Metadata; None for any other opcode (not needed here)."""
    if opcode == OP_MESSAGE:
        if len(body) < _MESSAGE_FIXED.size:
            raise BadMcap(offset, "message record: shorter than its fixed fields")
        channel, sequence, log_time, publish_time = _MESSAGE_FIXED.unpack_from(body)
        return Message(channel, sequence, log_time, publish_time,
                       bytes(body[_MESSAGE_FIXED.size:]))
    if opcode == OP_CHANNEL:
        f = _Fields(body, offset, "channel")
        return Channel(f.uint(2), f.uint(2), f.text(), f.text(), f.mapping())
    if opcode == OP_SCHEMA:
        f = _Fields(body, offset, "schema")
        return Schema(f.uint(2), f.text(), f.text(), f.blob())
    if opcode == OP_HEADER:
        f = _Fields(body, offset, "header")
        return Header(f.text(), f.text())
    if opcode == OP_METADATA:
        f = _Fields(body, offset, "metadata")
        return Metadata(f.text(), f.mapping())
    return None


@dataclass(frozen=True)
class ChunkHead:
    """A chunk record's header: where it is and what it declares (its data not read)."""

    offset: int  # of the record (its opcode)
    length: int  # of the record's content
    start: int  # message log times
    end: int
    size: int  # uncompressed bytes
    crc: int
    compression: str
    data_at: int  # file offset of the compressed data
    data_size: int


class Scan:
    """What :func:`scan` found: the segments of messages (chunks, and runs of messages outside
    chunks) as compact arrays, the schemas and channels outside chunks (the summary's among
    them), and whether the file ends with a footer (and a summary). A file of many tiny
    chunks costs a few bytes per chunk here."""

    def __init__(self) -> None:
        self.kinds = array("b")  # 0: a chunk, 1: a run of messages outside chunks
        self.offsets = array("q")  # of the chunk record, of the run's first record
        self.extents = array("q")  # the chunk record's content length, the run's end offset
        self.starts = array("Q")  # earliest log time declared (chunk) or seen (run)
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.footer = False
        self.summary = False
        self.records = 0

    def add(self, kind: int, offset: int, extent: int, start: int) -> None:
        self.kinds.append(kind)
        self.offsets.append(offset)
        self.extents.append(extent)
        self.starts.append(start)

    @property
    def chunks(self) -> int:
        return self.kinds.count(0)


class McapFile:
    """One MCAP file opened for reading (``stream`` seekable, ``size`` its length)."""

    def __init__(self, stream: IO[bytes], size: int) -> None:
        self.stream, self.size = stream, size

    def read_at(self, offset: int, n: int) -> bytes:
        """Exactly ``n`` bytes at ``offset`` (``n`` checked by the caller against its bound
        and against the file's length)."""
        self.stream.seek(offset)
        data = self.stream.read(n)
        if len(data) != n:
            raise BadMcap(offset, f"the file ends {size_text(n - len(data))} early")
        return data

    def check_magic(self) -> None:
        if self.size < len(MAGIC) or self.read_at(0, len(MAGIC)) != MAGIC:
            raise BadMcap(0, "not an MCAP file (no magic)")

    def records(self, start: int = len(MAGIC)) -> Iterator[tuple[int, int, int]]:
        """(offset, opcode, content length) of each top-level record from ``start`` up to
        the footer (included) or the end of the file; a length past the end of the file is
        a BadMcap."""
        pos = start
        while pos < self.size:
            if self.size - pos < 9:
                raise BadMcap(pos, f"a record is cut short ({self.size - pos} bytes left)")
            head = self.read_at(pos, 9)
            opcode, length = head[0], int.from_bytes(head[1:], "little")
            if length > self.size - pos - 9:
                raise BadMcap(pos, f"record of {size_text(length)} runs past the end of "
                              f"the file ({size_text(self.size - pos - 9)} left)")
            yield pos, opcode, length
            if opcode == OP_FOOTER:
                return
            pos += 9 + length

    def content(self, offset: int, length: int, what: str = "record",
                limit: int = MAX_RECORD) -> memoryview:
        """The content of the record at ``offset`` (at most ``limit`` bytes)."""
        if length > limit:
            raise BadMcap(offset, f"{what} of {size_text(length)} is above the reader's "
                          f"limit of {size_text(limit)}")
        return memoryview(self.read_at(offset + 9, length))

    def chunk_head(self, offset: int, length: int) -> ChunkHead:
        """The header of the chunk record at ``offset``, its sizes checked against the
        reader's limits and the record's length (nothing allocated for its data)."""
        fixed = _CHUNK_FIXED.size
        if length < fixed + 4 + 8:
            raise BadMcap(offset, "chunk record shorter than its header")
        start, end, size, crc = _CHUNK_FIXED.unpack(self.read_at(offset + 9, fixed))
        name_len = int.from_bytes(self.read_at(offset + 9 + fixed, 4), "little")
        if name_len > min(_MAX_NAME, length - fixed - 12):
            raise BadMcap(offset, f"chunk compression name of {size_text(name_len)}")
        raw = self.read_at(offset + 9 + fixed + 4, name_len)
        data_size = int.from_bytes(self.read_at(offset + 9 + fixed + 4 + name_len, 8), "little")
        data_at = offset + 9 + fixed + 4 + name_len + 8
        if data_size > offset + 9 + length - data_at:
            raise BadMcap(offset, f"chunk data of {size_text(data_size)} runs past the chunk "
                          "record")
        if size > MAX_CHUNK:
            raise BadMcap(offset, f"chunk declares {size_text(size)} uncompressed, above the "
                          f"reader's limit of {size_text(MAX_CHUNK)}")
        compression = raw.decode("ascii", "replace")
        if data_size > MAX_CHUNK + MAX_CHUNK // 64 or (not compression and data_size != size):
            raise BadMcap(offset, f"chunk holds {size_text(data_size)} of data for "
                          f"{size_text(size)} uncompressed")
        return ChunkHead(offset, length, start, end, size, crc, compression, data_at,
                         data_size)

    def chunk_data(self, head: ChunkHead) -> memoryview:
        """The chunk's records, decompressed (at most the size it declares) and checked
        against its CRC."""
        data = inflate(head.compression, self.read_at(head.data_at, head.data_size), head.size,
                       head.offset)
        if head.crc and zlib.crc32(data) != head.crc:
            raise BadMcap(head.offset, "chunk fails its CRC (damaged)")
        return memoryview(data)

    def chunk_records(self, head: ChunkHead) -> Iterator[tuple[int, int, memoryview]]:
        """(index, opcode, content) of each record in the chunk, in order."""
        data = self.chunk_data(head)
        pos, index, n = 0, 0, len(data)
        while pos < n:
            if n - pos < 9:
                raise BadMcap(head.offset, "chunk: its last record is cut short")
            opcode, length = data[pos], int.from_bytes(data[pos + 1:pos + 9], "little")
            if length > n - pos - 9:
                raise BadMcap(head.offset, f"chunk: a record of {size_text(length)} runs past "
                              "the chunk's end")
            yield index, opcode, data[pos + 9:pos + 9 + length]
            pos += 9 + length
            index += 1


def inflate(compression: str, data: bytes, size: int, offset: int) -> bytearray | bytes:
    """``data`` decompressed into exactly ``size`` bytes, as a stream: never more than
    ``size`` + one block is produced, whatever the compressed data would inflate to."""
    if compression == "":
        return data
    if compression == "zstd":
        import zstandard

        out = bytearray()
        try:
            reader = zstandard.ZstdDecompressor(max_window_size=MAX_CHUNK).stream_reader(
                data, read_across_frames=True)
            while len(out) <= size:
                piece = reader.read(min(_BLOCK, size + 1 - len(out)))
                if not piece:
                    break
                out += piece
        except zstandard.ZstdError as e:
            raise BadMcap(offset, f"chunk does not decompress (zstd: {str(e)[:200]})") \
                from None
    elif compression == "lz4":
        try:
            import lz4.frame
        except ImportError:
            raise BadMcap(offset, "lz4 chunk, and no lz4 module to read it (pip install "
                          "lz4)") from None
        try:
            out = bytearray(lz4.frame.LZ4FrameDecompressor().decompress(data,
                                                                        max_length=size + 1))
        except RuntimeError as e:
            raise BadMcap(offset, f"chunk does not decompress (lz4: {str(e)[:200]})") \
                from None
    else:
        shown = compression.encode("ascii", "backslashreplace").decode()[:_MAX_NAME]
        raise BadMcap(offset, f"chunk compression {shown!r} is not supported (zstd, lz4)")
    if len(out) != size:
        more = "more than" if len(out) > size else f"{size_text(len(out))}, not"
        raise BadMcap(offset, f"chunk decompresses to {more} the {size_text(size)} it "
                      "declares")
    return out


def scan(f: McapFile) -> Scan:
    """One pass over the file's framing: chunk headers, runs of messages outside chunks,
    schemas and channels outside chunks (the summary's among them), the footer. Nothing is
    decompressed; every declared size is checked against the limits."""
    f.check_magic()
    s = Scan()
    run: list[int] | None = None  # first offset, end offset, earliest log time, bytes
    for pos, opcode, length in f.records():
        s.records += 1
        if opcode == OP_MESSAGE:
            if length < _MESSAGE_FIXED.size:
                raise BadMcap(pos, "message record shorter than its fixed fields")
            if length > MAX_RECORD:
                f.content(pos, length, "message")  # (raises)
            log_time = _MESSAGE_FIXED.unpack(f.read_at(pos + 9, _MESSAGE_FIXED.size))[2]
            if run is None or run[3] + length > _RUN_BYTES:
                if run is not None:
                    s.add(1, run[0], run[1], run[2])
                run = [pos, pos, log_time, 0]
            run[1], run[2], run[3] = pos + 9 + length, min(run[2], log_time), run[3] + length
            continue
        if run is not None:
            s.add(1, run[0], run[1], run[2])
            run = None
        if opcode == OP_CHUNK:
            head = f.chunk_head(pos, length)
            s.add(0, pos, length, head.start)
        elif opcode in (OP_SCHEMA, OP_CHANNEL):
            rec = parse_record(opcode, f.content(pos, length), pos)
            (s.schemas if opcode == OP_SCHEMA else s.channels).setdefault(rec.id, rec)
        elif opcode == OP_FOOTER:
            if length < 20:
                raise BadMcap(pos, "footer record shorter than its fields")
            s.footer = True
            s.summary = int.from_bytes(f.read_at(pos + 9, 8), "little") != 0
    if run is not None:
        s.add(1, run[0], run[1], run[2])
    if s.footer and f.read_at(f.size - len(MAGIC), len(MAGIC)) != MAGIC:
        raise BadMcap(f.size - len(MAGIC), "no MCAP magic after the footer")
    return s


def _segment_records(f: McapFile, s: Scan, i: int) -> Iterator[tuple[int, Any]]:
    """(position, record) of every record of segment ``i`` (a chunk: its records, by index;
    a run: its messages, by file offset), parsed; None for records not needed here."""
    offset, extent = s.offsets[i], s.extents[i]
    if s.kinds[i] == 0:
        head = f.chunk_head(offset, extent)
        for index, opcode, body in f.chunk_records(head):
            yield index, parse_record(opcode, body, offset)
        return
    for pos, opcode, length in f.records(offset):
        if pos >= extent:
            return
        yield pos, parse_record(opcode, f.content(pos, length, "message"), pos)


def verify(f: McapFile) -> Scan:
    """:func:`scan`, then every chunk decompressed (one at a time, bounded) and checked
    against its CRC, and every record in it parsed."""
    s = scan(f)
    for i in range(len(s.kinds)):
        for _ in _segment_records(f, s, i):
            pass
    return s


#: What a message waiting to be ordered costs beyond its data (its objects), counted against
#: :data:`MAX_PENDING`.
_MESSAGE_COST = 256


def iter_messages(f: McapFile, topics: set[str] | None = None
                  ) -> Iterator[tuple[Schema | None, Channel, Message]]:
    """Every message of the file (of ``topics`` only, if given) in log-time order; equal
    times in file order (segment, then position in it). A segment is decompressed only once
    its earliest message may be next; at most :data:`MAX_PENDING` bytes of messages wait."""
    import numpy as np

    s = scan(f)
    starts = np.frombuffer(s.starts, dtype=np.uint64) if len(s.starts) else np.zeros(0, "u8")
    offsets = np.frombuffer(s.offsets, dtype=np.int64) if len(s.offsets) else np.zeros(0, "i8")
    order = np.lexsort((offsets, starts))
    heap: list[tuple[int, int, int, Message]] = []  # (log time, segment offset, position)
    pending = 0
    k = 0
    while True:
        while k < len(order) and (not heap or (int(starts[order[k]]), int(offsets[order[k]]))
                                  < (heap[0][0], heap[0][1])):
            i = int(order[k])
            k += 1
            for pos, rec in _segment_records(f, s, i):
                if isinstance(rec, Schema):
                    s.schemas.setdefault(rec.id, rec)
                elif isinstance(rec, Channel):
                    s.channels.setdefault(rec.id, rec)
                elif isinstance(rec, Message):
                    known = s.channels.get(rec.channel_id)
                    if topics is not None and known is not None and known.topic not in topics:
                        continue
                    heapq.heappush(heap, (rec.log_time, s.offsets[i], pos, rec))
                    pending += len(rec.data) + _MESSAGE_COST
                    if pending > MAX_PENDING:
                        raise BadMcap(s.offsets[i], f"more than {size_text(MAX_PENDING)} of "
                                      "messages overlap in time: too many to order by log time")
        if not heap:
            return
        _, where, _, message = heapq.heappop(heap)
        pending -= len(message.data) + _MESSAGE_COST
        channel = s.channels.get(message.channel_id)
        if channel is None:
            raise BadMcap(where, f"a message on channel {message.channel_id}, which no "
                          "channel record defines")
        if topics is None or channel.topic in topics:
            yield s.schemas.get(channel.schema_id), channel, message


@dataclass
class Salvage:
    """What :func:`walk` could not read: chunks skipped (the first one's reason) and where
    the framing ended early, if it did."""

    lost_chunks: int = 0
    lost_reason: str = ""
    cut: str = ""
    footer: bool = False


_WANTED = (OP_HEADER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_METADATA)


def walk(f: McapFile, salvage: Salvage) -> Iterator[Any]:
    """Every readable Header, Schema, Channel, Message and Metadata record in file order (a
    chunk's records in place of the chunk). A chunk that breaks a bound, does not decompress
    or fails its CRC is skipped (counted in ``salvage``; one with a bad record inside keeps
    the records before it); the walk ends where the framing does (a file cut short, a length
    past its end)."""
    f.check_magic()
    records = f.records()
    while True:
        try:
            pos, opcode, length = next(records)
        except StopIteration:
            return
        except BadMcap as e:
            salvage.cut = str(e)
            return
        if opcode == OP_FOOTER:
            salvage.footer = True
            return
        if opcode not in _WANTED and opcode != OP_CHUNK:
            continue
        try:
            if opcode == OP_CHUNK:
                for _, op, body in f.chunk_records(f.chunk_head(pos, length)):
                    rec = parse_record(op, body, pos)
                    if rec is not None:
                        yield rec
            else:
                yield parse_record(opcode, f.content(pos, length), pos)
        except BadMcap as e:
            if opcode == OP_CHUNK:
                salvage.lost_chunks += 1
                salvage.lost_reason = salvage.lost_reason or str(e)
