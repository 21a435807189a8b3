"""CDR payloads of a whole chunk of samples at once, from layouts derived from the message
definitions (no rclpy message objects in the loop, no per-type code).

A :class:`Layout` is made once per topic from a *prototype*: any message of the type (an rclpy
message, or nested dicts and lists), which fixes every string and every sequence length. The
definition (the environment's ``.msg`` files, parsed by rosbags; see ``bag.typeinfo``) is
walked field by field: the prototype is serialized as little-endian CDR (XCDR1, the
encapsulation rmw uses: a 4-byte header, primitives aligned to their size counted from the end
of the header, strings and sequences with a uint32 length, strings NUL-terminated), with every
padding byte zero, and the offset of each numeric leaf is kept under its dotted path
(``header.stamp.sec``, ``position.1``, ``transforms.0.transform.rotation.w``).

A chunk of N messages is then an (N, size) byte array: the template copied N times, each
:class:`Block` (numeric leaves of one type filled from the columns of one matrix; adjacent
leaves are written in one numpy operation) and every ``builtin_interfaces/Time`` field filled
from the stamps. A new ``.msg`` needs no code here: only its prototype.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from mechsim.errors import MechsimError
from mechsim.outputs.bag.typeinfo import (
    DEPTH_LIMIT,
    DTYPES,
    HEADER,
    PRIMITIVES,
    STRUCTS,
    TIME_TYPE,
    U32,
    split_type,
    typestore_with,
)

_TIME = struct.Struct("<iI")  # builtin_interfaces/Time: int32 sec, uint32 nanosec
#: struct codes of the numpy types a block can have.
_CODES = {np.dtype(v).str: st.format[-1] for v, st in
          ((PRIMITIVES[k], STRUCTS[k]) for k in PRIMITIVES)}


def _field(obj: Any, name: str) -> Any:
    return obj[name] if isinstance(obj, dict) else getattr(obj, name)


class _Writer:
    """Serializes a prototype, recording where each numeric leaf and Time field lands."""

    def __init__(self, store: Any) -> None:
        self.store = store
        self.buf = bytearray(HEADER)
        self.slots: dict[str, tuple[int, np.dtype[Any]]] = {}
        self.times: list[int] = []  # offsets of Time fields (sec, then nanosec)

    def align(self, n: int) -> None:
        pad = -(len(self.buf) - 4) % n
        self.buf += b"\x00" * pad

    def base(self, typ: str, value: Any, path: str) -> None:
        if typ in ("string", "wstring"):
            if typ == "wstring":
                raise MechsimError(f"{path}: wstring fields are not supported")
            data = str(value).encode()
            self.align(4)
            self.buf += U32.pack(len(data) + 1) + data + b"\x00"
            return
        if typ not in PRIMITIVES:
            raise MechsimError(f"{path}: unknown primitive type {typ}")
        dt = DTYPES[typ]
        self.align(dt.itemsize)
        self.slots[path] = (len(self.buf), dt)
        if isinstance(value, (bytes, bytearray)):
            value = value[0]
        try:
            self.buf += STRUCTS[typ].pack(value)
        except (struct.error, TypeError):  # a numpy scalar or an out-of-range value
            self.buf += np.array(value).astype(dt).tobytes()

    def node(self, kind: Any, arg: Any, value: Any, path: str, depth: int) -> None:
        from rosbags.interfaces import Nodetype

        if depth > DEPTH_LIMIT:
            raise MechsimError(f"{path}: message nested too deep")
        if kind == Nodetype.BASE:
            self.base(arg[0], value, path)
        elif kind == Nodetype.NAME:
            self.message(str(arg), value, path, depth + 1)
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            (sub_kind, sub_arg), length = arg
            items = list(value)
            if kind == Nodetype.ARRAY and len(items) != length:
                raise MechsimError(f"{path}: {len(items)} elements, the array has {length}")
            if kind == Nodetype.SEQUENCE:
                self.align(4)
                self.buf += U32.pack(len(items))
            for k, item in enumerate(items):
                self.node(sub_kind, sub_arg, item, f"{path}.{k}" if path else str(k), depth)
        else:
            raise MechsimError(f"{path}: unsupported field kind {kind}")

    def message(self, type_name: str, value: Any, path: str, depth: int = 0) -> None:
        if type_name == TIME_TYPE:
            self.align(4)
            self.times.append(len(self.buf))
        _, fields = self.store.fielddefs[type_name]
        for name, (kind, arg) in fields:
            self.node(kind, arg, _field(value, name), f"{path}.{name}" if path else name, depth)


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
        pkg, typ = split_type(type_name)
        self.type_name = f"{pkg}/msg/{typ}"
        store = typestore_with(self.type_name)
        w = _Writer(store)
        w.message(self.type_name, prototype, "")
        self._template_bytes = bytes(w.buf)
        self.template = np.frombuffer(self._template_bytes, dtype=np.uint8)
        self.size = self.template.size
        self.slots = w.slots
        self.time_offsets = tuple(w.times)

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
        if self.time_offsets:
            tb = time_rows(ns) if times is None else times
            for off in self.time_offsets:
                out[:, off:off + 8] = tb
        for block, values in blocks:
            m = np.asarray(values, dtype=block.dtype).reshape(n, block.width)
            size = block.dtype.itemsize
            for a, b, off in block.runs:
                out[:, off:off + size * (b - a)] = \
                    np.ascontiguousarray(m[:, a:b]).view(np.uint8)
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
            code = block.dtype.str
            for a, b, off in block.runs:
                struct.pack_into(f"<{b - a}{_CODES[code]}", buf, off, *row[a:b])
        return np.frombuffer(bytes(buf), dtype=np.uint8).reshape(1, self.size)

    def payloads(self, rows: np.ndarray) -> list[bytes]:
        """The rows of :meth:`encode` as ``bytes`` (what rclpy publishes and MCAP records)."""
        return [r.tobytes() for r in rows]
