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
from functools import cache
from typing import Any

import numpy as np

from mechsim.errors import MechsimError
from mechsim.outputs.bag.typeinfo import split_type, typestore_with

HEADER = b"\x00\x01\x00\x00"  # CDR little-endian, no options
TIME_TYPE = "builtin_interfaces/msg/Time"
_PRIMITIVES: dict[str, str] = {
    "bool": "u1", "byte": "u1", "char": "u1", "octet": "u1", "int8": "i1", "uint8": "u1",
    "int16": "<i2", "uint16": "<u2", "int32": "<i4", "uint32": "<u4", "int64": "<i8",
    "uint64": "<u8", "float32": "<f4", "float64": "<f8",
}
_DTYPES = {k: np.dtype(v) for k, v in _PRIMITIVES.items()}
_STRUCTS = {k: struct.Struct("<" + {"u1": "B", "i1": "b", "<i2": "h", "<u2": "H", "<i4": "i",
                                     "<u4": "I", "<i8": "q", "<u8": "Q", "<f4": "f",
                                     "<f8": "d"}[v]) for k, v in _PRIMITIVES.items()}
_U32 = struct.Struct("<I")
_DEPTH_LIMIT = 50


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
            self.buf += _U32.pack(len(data) + 1) + data + b"\x00"
            return
        if typ not in _PRIMITIVES:
            raise MechsimError(f"{path}: unknown primitive type {typ}")
        dt = _DTYPES[typ]
        self.align(dt.itemsize)
        self.slots[path] = (len(self.buf), dt)
        if isinstance(value, (bytes, bytearray)):
            value = value[0]
        try:
            self.buf += _STRUCTS[typ].pack(value)
        except (struct.error, TypeError):  # a numpy scalar or an out-of-range value
            self.buf += np.array(value).astype(dt).tobytes()

    def node(self, kind: Any, arg: Any, value: Any, path: str, depth: int) -> None:
        from rosbags.interfaces import Nodetype

        if depth > _DEPTH_LIMIT:
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
                self.buf += _U32.pack(len(items))
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


_STR = "string"


@cache
def _plan(type_name: str) -> tuple[tuple[str, Any], ...]:
    """How to encode ``type_name``: per field (name, op), op being "string", a
    ``struct.Struct`` (a primitive), ("msg", plan, is Time), ("seq", op) or ("arr", length,
    op). Made once per type from its definition."""
    from rosbags.interfaces import Nodetype

    store = typestore_with(type_name)

    def op(kind: Any, arg: Any, depth: int) -> Any:
        if depth > _DEPTH_LIMIT:
            raise MechsimError(f"{type_name}: message nested too deep")
        if kind == Nodetype.BASE:
            typ = arg[0]
            if typ == "string":
                return _STR
            if typ not in _STRUCTS:
                raise MechsimError(f"{type_name}: unsupported primitive type {typ}")
            return _STRUCTS[typ]
        if kind == Nodetype.NAME:
            return ("msg", message(str(arg), depth + 1), str(arg) == TIME_TYPE)
        if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            (sub_kind, sub_arg), length = arg
            sub = op(sub_kind, sub_arg, depth + 1)
            return ("seq", sub) if kind == Nodetype.SEQUENCE else ("arr", length, sub)
        raise MechsimError(f"{type_name}: unsupported field kind {kind}")

    def message(name: str, depth: int) -> tuple[tuple[str, Any], ...]:
        return tuple((field, op(kind, arg, depth)) for field, (kind, arg)
                     in store.fielddefs[name][1])

    return message(type_name, 0)


def _put(buf: bytearray, op: Any, v: Any) -> None:
    """Append ``v`` encoded by ``op`` (see :func:`_plan`) to ``buf``, aligned, padding zero."""
    if op is _STR:
        data = str(v).encode()
        extra = -(len(buf) - 4) % 4
        if extra:
            buf += bytes(extra)
        buf += _U32.pack(len(data) + 1)
        buf += data
        buf += b"\x00"
    elif isinstance(op, struct.Struct):
        extra = -(len(buf) - 4) % op.size
        if extra:
            buf += bytes(extra)
        if isinstance(v, (bytes, bytearray)):
            v = v[0]
        try:
            buf += op.pack(v)
        except (struct.error, TypeError):  # a numpy scalar
            buf += op.pack(np.asarray(v).item())
    elif op[0] == "msg":
        if op[2]:  # builtin_interfaces/Time: 4-aligned
            extra = -(len(buf) - 4) % 4
            if extra:
                buf += bytes(extra)
        get = v.__getitem__ if isinstance(v, dict) else v.__getattribute__
        for name, sub in op[1]:
            _put(buf, sub, get(name))
    else:
        items = list(v)
        if op[0] == "seq":
            extra = -(len(buf) - 4) % 4
            if extra:
                buf += bytes(extra)
            buf += _U32.pack(len(items))
        elif len(items) != op[1]:
            raise MechsimError(f"{len(items)} elements, the array has {op[1]}")
        sub = op[-1]
        for item in items:
            _put(buf, sub, item)


def encode_message(type_name: str, value: Any) -> bytes:
    """The CDR payload (with the encapsulation header, padding zero) of one message of
    ``type_name`` (an rclpy message, or nested dicts and lists): the path for single
    messages (``bag.typeinfo.cdr_bytes``); same rules as :class:`Layout`."""
    pkg, typ = split_type(type_name)
    buf = bytearray(HEADER)
    _put(buf, ("msg", _plan(f"{pkg}/msg/{typ}"), False), value)
    return bytes(buf)


@dataclass(frozen=True)
class Block:
    """Numeric leaves of one type, filled from the columns of one (N, k) matrix: runs of
    adjacent leaves as (first column, last column + 1, byte offset)."""

    dtype: np.dtype[Any]
    width: int
    runs: tuple[tuple[int, int, int], ...]


class Layout:
    """The CDR bytes of ``type_name`` with the shape of ``prototype`` (see the module
    docstring). ``size`` includes the 4-byte encapsulation header."""

    def __init__(self, type_name: str, prototype: Any) -> None:
        pkg, typ = split_type(type_name)
        self.type_name = f"{pkg}/msg/{typ}"
        store = typestore_with(self.type_name)
        w = _Writer(store)
        w.message(self.type_name, prototype, "")
        self.template = np.frombuffer(bytes(w.buf), dtype=np.uint8)
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

    def encode(self, ns: np.ndarray, blocks: Sequence[tuple[Block, np.ndarray]] = ()
               ) -> np.ndarray:
        """(N, size) uint8: one message per row, Time fields from ``ns`` (int64 nanoseconds)
        and each block from its (N, k) matrix (a 1-D array for k = 1)."""
        n = int(np.shape(ns)[0])
        out = np.empty((n, self.size), dtype=np.uint8)
        out[:] = self.template
        if self.time_offsets:
            ns = np.asarray(ns, dtype=np.int64)
            t = np.empty((n, 2), dtype="<u4")
            t[:, 0] = (ns // 1_000_000_000).astype("<i4").view("<u4")
            t[:, 1] = (ns % 1_000_000_000).astype("<u4")
            tb = t.view(np.uint8)
            for off in self.time_offsets:
                out[:, off:off + 8] = tb
        for block, values in blocks:
            m = np.asarray(values, dtype=block.dtype).reshape(n, block.width)
            size = block.dtype.itemsize
            for a, b, off in block.runs:
                out[:, off:off + size * (b - a)] = \
                    np.ascontiguousarray(m[:, a:b]).view(np.uint8)
        return out

    def payloads(self, rows: np.ndarray) -> list[bytes]:
        """The rows of :meth:`encode` as ``bytes`` (what rclpy publishes and MCAP records)."""
        return [r.tobytes() for r in rows]
