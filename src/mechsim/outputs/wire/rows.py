"""A chunk of samples as CDR rows: columns of numbers and stamps in, one message per row out.

A :class:`Layout` is made once per topic from a *prototype*: any message of the type (an rclpy
message, or nested dicts and lists), which fixes every string and every sequence length. The
prototype is encoded by the type's traced encoder (``encoder.tracer``: the one generated
encoder, recording as it goes), which keeps the offset of each numeric leaf under its dotted
path (``header.stamp.sec``, ``position.1``, ``transforms.0.transform.rotation.w``) and of each
``builtin_interfaces/Time``.

A chunk of N messages is then an (N, size) byte array: the prototype's bytes copied N times,
each :class:`Block` (numeric leaves of one type filled from the columns of one matrix;
adjacent leaves are written in one numpy operation) and every Time field filled from the
stamps. A new ``.msg`` needs no code here: only its prototype.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mechsim.errors import MechsimError
from mechsim.outputs.wire.definitions import full_name
from mechsim.outputs.wire.encoder import DTYPES, ENCODING_ERRORS, FORMATS, HEADER, tracer

_TIME = struct.Struct("<iI")  # builtin_interfaces/Time: int32 sec, uint32 nanosec
#: struct codes of the numpy types a block can have.
_CODES = {DTYPES[k].str: FORMATS[k] for k in FORMATS}


@dataclass(frozen=True)
class Block:
    """Numeric leaves of one type, filled from the columns of one (N, k) matrix: runs of
    adjacent leaves as (first column, last column + 1, byte offset)."""

    dtype: np.dtype[Any]
    width: int
    runs: tuple[tuple[int, int, int], ...]


def time_rows(ns: np.ndarray) -> np.ndarray:
    """(N, 8) uint8: the builtin_interfaces/Time fields (int32 sec, uint32 nanosec) of the
    stamps ``ns`` (int64 nanoseconds), as :meth:`Layout.encode` writes them."""
    ns = np.asarray(ns, dtype=np.int64)
    t = np.empty((ns.shape[0], 2), dtype="<u4")
    t[:, 0] = (ns // 1_000_000_000).astype("<i4").view("<u4")
    t[:, 1] = (ns % 1_000_000_000).astype("<u4")
    return t.view(np.uint8)


class Layout:
    """The CDR bytes of ``type_name`` with the shape of ``prototype`` (see the module
    docstring). ``size`` includes the 4-byte encapsulation header."""

    def __init__(self, type_name: str, prototype: Any) -> None:
        self.type_name = full_name(type_name)
        buf = bytearray(HEADER)
        slots: dict[str, tuple[int, np.dtype[Any]]] = {}
        times: list[int] = []
        try:
            tracer(self.type_name)(buf, prototype, slots, times)
        except ENCODING_ERRORS as e:
            raise MechsimError(f"message type {self.type_name}: cannot encode the prototype "
                               f"({type(e).__name__}: {e})") from None
        self._template_bytes = bytes(buf)
        self.template = np.frombuffer(self._template_bytes, dtype=np.uint8)
        self.size = self.template.size
        self.slots = slots
        self.time_offsets = tuple(times)

    def block(self, paths: Sequence[str]) -> Block:
        """A :class:`Block` for the leaves ``paths`` (all of one type), in column order."""
        if not paths:
            return Block(np.dtype("<f8"), 0, ())
        try:
            slots = [self.slots[p] for p in paths]
        except KeyError as e:
            raise MechsimError(f"{self.type_name}: no numeric field {e.args[0]!r} in the "
                               "layout") from None
        dt = slots[0][1]
        if any(s[1] != dt for s in slots):
            raise MechsimError(f"{self.type_name}: a block mixes types ({', '.join(paths)})")
        runs: list[tuple[int, int, int]] = []
        start = 0
        for j in range(1, len(slots) + 1):
            if j == len(slots) or slots[j][0] != slots[j - 1][0] + dt.itemsize:
                runs.append((start, j, slots[start][0]))
                start = j
        return Block(dt, len(paths), tuple(runs))

    def encode(self, ns: np.ndarray, blocks: Sequence[tuple[Block, np.ndarray]] = (),
               times: np.ndarray | None = None) -> np.ndarray:
        """(N, size) uint8: one message per row, Time fields from ``ns`` (int64 nanoseconds;
        ``times``: ``time_rows(ns)`` if already made) and each block from its (N, k) matrix
        (a 1-D array for k = 1)."""
        n = int(np.shape(ns)[0])
        if n == 1:
            return self._encode_one(int(np.asarray(ns).reshape(-1)[0]), blocks)
        out = np.empty((n, self.size), dtype=np.uint8)
        out[:] = self.template
        # Each field is written through a typed view of ``out`` (one element a row, strided
        # by the row size, unaligned as CDR places it), not as a column of bytes.
        if self.time_offsets:
            tb = (time_rows(ns) if times is None else times).view("<u8").reshape(n)
            for off in self.time_offsets:
                np.ndarray((n,), "<u8", out, off, (self.size,))[:] = tb
        for block, values in blocks:
            m = np.asarray(values, dtype=block.dtype).reshape(n, block.width)
            size = block.dtype.itemsize
            for a, b, off in block.runs:
                np.ndarray((n, b - a), block.dtype, out, off, (self.size, size))[:] = m[:, a:b]
        return out

    def _encode_one(self, ns: int, blocks: Sequence[tuple[Block, np.ndarray]]) -> np.ndarray:
        """:meth:`encode` of one message, with ``struct`` (a paced run encodes one sample at
        a time, where numpy's per-call cost would dominate)."""
        buf = bytearray(self._template_bytes)
        sec, nanosec = divmod(ns, 1_000_000_000)
        for off in self.time_offsets:
            _TIME.pack_into(buf, off, sec, nanosec)
        for block, values in blocks:
            row = np.asarray(values, dtype=block.dtype).reshape(-1).tolist()
            code = _CODES[block.dtype.str]
            for a, b, off in block.runs:
                struct.pack_into(f"<{b - a}{code}", buf, off, *row[a:b])
        return np.frombuffer(bytes(buf), dtype=np.uint8).reshape(1, self.size)

    def payloads(self, rows: np.ndarray) -> list[bytes]:
        """The rows of :meth:`encode` as ``bytes`` (what rclpy publishes and MCAP records)."""
        return [r.tobytes() for r in rows]
