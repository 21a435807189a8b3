"""One message as CDR bytes, by a function generated from the message's definition.

The encapsulation is the one rmw uses (XCDR1, little-endian): a 4-byte header, then the fields
in order, each primitive aligned to its size counted from the end of the header, strings as a
uint32 length (with the NUL), the UTF-8 text up to its first NUL (as rmw sends a string), and a
NUL; sequences as a uint32 count then the elements, fixed arrays as their elements alone.
Every padding byte is zero (rclpy's ``serialize_message`` leaves them uninitialised, so equal
messages could differ in their bytes; it also returns rmw's *estimated* size, which counts
padding after the data: sensor_msgs/JointState without effort, 84 bytes where the DDS payload
is 80). The bytes here end where the data ends, as DDS carries them.

For each type, Python source is generated once from its :func:`~.definitions.schema` (every
field inline: no call or dispatch per field) and compiled. The same generator, with ``trace``,
makes a twin that also records where each numeric leaf and each ``builtin_interfaces/Time``
lands: what ``rows.Layout`` fills a chunk of samples from. A value is an rclpy message, nested
dicts (and lists) with the same field names, or tuples of the fields in their order. Sequences
of numbers given as ``array.array`` or 1-D numpy arrays of the field's own type, or ``bytes``
for one-byte types, are copied as they are.
"""

from __future__ import annotations

import itertools
import struct
import sys
from array import array
from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np

from mechsim.errors import MechsimError
from mechsim.outputs.wire.definitions import (
    DEPTH_LIMIT,
    TIME_TYPE,
    Field,
    full_name,
    schema,
    type_of,
)

HEADER = b"\x00\x01\x00\x00"  # CDR little-endian, no options
#: struct format character of each primitive (also its ``array.array`` typecode).
FORMATS = {"bool": "?", "byte": "B", "char": "B", "octet": "B", "int8": "b", "uint8": "B",
           "int16": "h", "uint16": "H", "int32": "i", "uint32": "I", "int64": "q",
           "uint64": "Q", "float32": "f", "float64": "d"}
STRUCTS = {k: struct.Struct("<" + c) for k, c in FORMATS.items()}
DTYPES = {k: np.dtype("<" + c) if c != "?" else np.dtype(bool) for k, c in FORMATS.items()}
U32 = struct.Struct("<I")
#: Values copied as they are into a sequence (``array.array``, numpy) need a little-endian host.
_COPY = sys.byteorder == "little"
_FALLBACK = (struct.error, TypeError, OverflowError)
#: What :func:`encode` turns into one MechsimError line (a value that does not fit its field).
ENCODING_ERRORS = (AttributeError, KeyError, IndexError, TypeError, ValueError, OverflowError,
                   struct.error, RecursionError)

#: Encoded strings (length, bytes, NUL) by value, and the same followed by the padding up to
#: the next multiple of 4 (``_UNITS``): names, keys and labels recur from message to message.
#: Short strings only, and emptied when full, so they stay within a few MB.
_STRINGS: dict[str, bytes] = {}
_UNITS: dict[str, bytes] = {}
_STRINGS_MAX = 4096
_STRING_MEMO_LENGTH = 256
#: Zeros after a string of n bytes (with its NUL) up to a multiple of 4, by n % 4.
_TAILS = (b"", b"\x00\x00\x00", b"\x00\x00", b"\x00")


def _encoded(v: Any) -> bytes:
    if not isinstance(v, str):
        raise TypeError(f"a string field got {type(v).__name__}")
    data = v.partition("\x00")[0].encode()
    return U32.pack(len(data) + 1) + data + b"\x00"


def _remember(memo: dict[str, bytes], v: Any, out: bytes) -> bytes:
    if v.__class__ is str and len(v) <= _STRING_MEMO_LENGTH:
        if len(memo) >= _STRINGS_MAX:
            memo.clear()
        memo[v] = out
    return out


def _string(v: Any) -> bytes:
    """A CDR string (uint32 length with the NUL, the UTF-8 text up to its first NUL, NUL),
    remembered in ``_STRINGS`` if it is a short ``str``."""
    return _remember(_STRINGS, v, _encoded(v))


def _unit(v: Any) -> bytes:
    """:func:`_string` and the zeros up to the next multiple of 4 (a string starts 4-aligned:
    where what follows it is 4-aligned too, its padding is written with it), remembered in
    ``_UNITS``."""
    out = _encoded(v)
    return _remember(_UNITS, v, out + _TAILS[len(out) & 3])


def _value(op: struct.Struct, v: Any) -> bytes:
    """``v`` packed by ``op`` where ``op.pack`` refused it: a byte field's ``bytes`` value is
    its byte, a numpy scalar its value, a float beyond float32's range its infinity (as a C
    cast makes it, and rclpy sends it)."""
    if isinstance(v, (bytes, bytearray)):
        if len(v) != 1:
            raise ValueError(f"a one-byte field got {len(v)} bytes")
        v = v[0]
    elif isinstance(v, np.generic):
        v = v.item()
    try:
        return op.pack(v)
    except OverflowError:
        if op.format[-1] != "f" or not isinstance(v, float):
            raise
        with np.errstate(over="ignore"):
            return np.array(v, dtype="<f4").tobytes()


def _run(op: struct.Struct, items: Any) -> bytes:
    """The elements of an array or sequence of one primitive type, back to back."""
    try:
        return struct.pack(f"<{len(items)}{op.format[-1]}", *items)
    except _FALLBACK:  # bytes elements, numpy scalars, float32 overflow: one at a time
        return b"".join(_value(op, v) for v in items)


def _join(path: str, name: str) -> str:
    """The dotted path of a field (traced encoders)."""
    return f"{path}.{name}" if path else name


class _Source:
    """Python source of an encoder of one type (see the module docstring): ``encode(buf,
    value)``, or with ``trace`` ``encode(buf, value, slots, times)`` that also records
    ``slots[path] = (offset, dtype)`` of each numeric leaf and the offset of each Time.

    ``align`` follows the alignment of the offset known at each point of the source (8 at
    the start; the size of the last primitive; 1 after a string), so a padding that is
    always empty is not emitted; a string followed in its message by a field that starts
    4-aligned is written with its padding (``_unit``). Expressions handed down are names of
    locals."""

    def __init__(self, types: dict[str, tuple[Field, ...]], trace: bool) -> None:
        self.types = types
        self.trace = trace
        self.lines: list[str] = []
        self.count = itertools.count()
        self.align = 8
        self.names: dict[str, Any] = {
            "_strings": _STRINGS, "_string": _string, "_units": _UNITS, "_unit": _unit,
            "_U32": U32.pack, "_value": _value,
            "_run": _run, "_Z": [bytes(k) for k in range(8)], "_dict": dict,
            "_fallback": _FALLBACK, "_sized": (list, tuple, array, np.ndarray, bytes, bytearray),
            "_array": array, "_ndarray": np.ndarray, "_join": _join, "_length": _length}

    def add(self, indent: str, text: str) -> None:
        self.lines.append(indent + text)

    def pad(self, size: int, indent: str) -> None:
        """Zeros up to the next multiple of ``size`` (counted from the header's end)."""
        if size > self.align:
            self.add(indent, f"buf += Z[(4 - len(buf)) & {size - 1}]")
            self.align = size

    def message(self, type_name: str, expr: str, path: str, indent: str, depth: int) -> None:
        if depth > DEPTH_LIMIT:
            raise MechsimError(f"message type {type_name}: nested too deep")
        fields = self.types.get(type_name)
        if fields is None:
            raise MechsimError(f"message type {type_name}: no definition")
        if not fields:  # rosidl gives an empty type one uint8 member (zero)
            self.add(indent, "buf += Z[1]")
            self.align = 1
            return
        k = next(self.count)
        values = [f"a{k}_{i}" for i in range(len(fields))]
        self.add(indent, f"if {expr}.__class__ is tuple: {', '.join(values)}, = {expr}")
        self.add(indent, "else:")
        self.add(indent, f" g{k} = {expr}.__getitem__ if isinstance({expr}, _dict) "
                         f"else {expr}.__getattribute__")
        for f, v in zip(fields, values, strict=True):
            self.add(indent, f" {v} = g{k}({f.name!r})")
        if self.trace and type_name == TIME_TYPE:
            self.pad(4, indent)
            self.add(indent, "times.append(len(buf))")
        for i, (f, v) in enumerate(zip(fields, values, strict=True)):
            follow = self.first_align(fields[i + 1], depth) if i + 1 < len(fields) else 1
            self.field(f, v, f"_join({path}, {f.name!r})", indent, depth, follow)

    def first_align(self, f: Field, depth: int) -> int:
        """The alignment the first byte of field ``f`` has (its first pad)."""
        if f.sequence or f.type == "string":
            return 4
        if not f.is_message:
            return STRUCTS[f.type].size
        fields = self.types.get(f.type)
        if not fields or depth > DEPTH_LIMIT:
            return 1
        return self.first_align(fields[0], depth + 1)

    def field(self, f: Field, expr: str, path: str, indent: str, depth: int,
              follow: int = 1) -> None:
        """Field ``f`` (its value: ``expr``); ``follow``: the alignment of what comes after
        it in the message (1 if not known here)."""
        if f.length is None and not f.sequence:
            self.element(f, expr, path, indent, depth, follow)
            return
        k = next(self.count)
        items = f"items{k}"
        self.add(indent, f"{items} = {expr}")
        self.add(indent, f"if {items}.__class__ not in _sized: {items} = list({items})")
        self.add(indent, f"n{k} = len({items})")
        if f.sequence:
            if f.bound:
                self.add(indent, f"if n{k} > {f.bound}: _length({f.name!r}, n{k}, "
                                 f"'at most {f.bound}')")
            self.pad(4, indent)
            self.add(indent, f"buf += _U32(n{k})")
            self.align = 4
        else:
            self.add(indent, f"if n{k} != {f.length}: _length({f.name!r}, n{k}, "
                             f"'{f.length}')")
        flat = flat_dtype(self.types, f.type) if f.is_message and _COPY else None
        if flat is not None and not self.trace:
            self.records(f, items, f"n{k}", flat, path, indent, depth)
        elif f.is_message or f.type == "string" or self.trace:
            self.loop(f, items, path, indent, depth)
        else:
            self.numbers(f, items, f"n{k}", indent)

    def records(self, f: Field, items: str, count: str, dtype: np.dtype[Any], path: str,
                indent: str, depth: int) -> None:
        """Elements of a flat message type (:func:`flat_dtype`): copied as they are from a
        numpy array of that record type, else one by one (``loop``)."""
        k = next(self.count)
        self.names[f"_rec{k}"] = dtype
        before = self.align
        self.add(indent, f"if {items}.__class__ is _ndarray and {items}.dtype == _rec{k} "
                         f"and {items}.ndim == 1:")
        inner = indent + " "
        if f.sequence:
            self.add(inner, f"if {count}:")
            inner += " "
        self.pad(dtype[0].itemsize, inner)  # the first field's alignment
        self.add(inner, f"buf += {items}.tobytes()")
        self.align = before
        self.add(indent, "else:")
        self.loop(f, items, path, indent + " ", depth)

    def loop(self, f: Field, items: str, path: str, indent: str, depth: int) -> None:
        """The elements one by one. The body is made for the alignment both the first
        element and the ones after it have: made again with less until its end keeps it."""
        k = next(self.count)
        before, start, mark = self.align, self.align, len(self.lines)
        while True:
            del self.lines[mark:]
            self.align = start
            if self.trace:
                self.add(indent, f"for i{k}, x{k} in enumerate({items}):")
                self.element(f, f"x{k}", f"_join({path}, str(i{k}))", indent + " ", depth)
            else:
                self.add(indent, f"for x{k} in {items}:")
                self.element(f, f"x{k}", "", indent + " ", depth)
            if self.align >= start:
                break
            start = self.align
        self.align = min(before, self.align)

    def numbers(self, f: Field, items: str, count: str, indent: str) -> None:
        """An array or sequence of numbers in one go: copied as it is where it has the
        field's own type (see the module docstring), else packed."""
        k = next(self.count)
        op = STRUCTS[f.type]
        self.names[f"_s{k}"] = op
        before = self.align
        inner = indent
        if f.sequence:
            self.add(indent, f"if {count}:")
            inner += " "
        self.pad(op.size, inner)
        if _COPY:
            self.names[f"_dt{k}"] = DTYPES[f.type]
            code = FORMATS[f.type]
            copies = [f"{items}.__class__ is _ndarray and {items}.dtype == _dt{k} "
                      f"and {items}.ndim == 1"]
            if code != "?":
                copies.insert(0, f"{items}.__class__ is _array and {items}.typecode == {code!r}")
            self.add(inner, f"if {' or '.join(f'({c})' for c in copies)}:")
            self.add(inner, f" buf += {items}.tobytes()")
            if code == "B":
                self.add(inner, f"elif {items}.__class__ in (bytes, bytearray):")
                self.add(inner, f" buf += {items}")
            self.add(inner, "else:")
            inner += " "
        self.add(inner, f"buf += _run(_s{k}, {items})")
        self.align = min(before, op.size) if f.sequence else min(self.align, op.size)

    def element(self, f: Field, expr: str, path: str, indent: str, depth: int,
                follow: int = 1) -> None:
        """One value of ``f``'s type (the field itself, or an element of it)."""
        if f.is_message:
            self.message(f.type, expr, path, indent, depth + 1)
            return
        if f.type == "string":
            if f.string_bound:
                self.add(indent, f"if isinstance({expr}, str) and len({expr}) > "
                                 f"{f.string_bound}: _length({f.name!r}, len({expr}), "
                                 f"'at most {f.string_bound} characters')")
            self.pad(4, indent)
            if follow >= 4:  # padded to 4 here: what follows needs it
                self.add(indent, f"buf += unit_of({expr}) or unit({expr})")
                self.align = 4
            else:
                self.add(indent, f"buf += remembered({expr}) or string({expr})")
                self.align = 1
            return
        k = next(self.count)
        op = STRUCTS[f.type]
        self.names[f"_s{k}"] = op
        self.names[f"_pack{k}"] = op.pack
        self.pad(op.size, indent)
        if self.trace:
            self.names[f"_dt{k}"] = DTYPES[f.type]
            self.add(indent, f"slots[{path}] = (len(buf), _dt{k})")
        self.add(indent, "try:")
        self.add(indent, f" buf += _pack{k}({expr})")
        self.add(indent, "except _fallback:")
        self.add(indent, f" buf += _value(_s{k}, {expr})")
        self.align = min(self.align, op.size)

    def compile(self, type_name: str) -> Callable[..., None]:
        self.message(type_name, "value", "''", " ", 0)
        args = "buf, value, slots, times" if self.trace else "buf, value"
        # The names used most, as locals.
        head = [" Z = _Z", " remembered = _strings.get", " string = _string",
                " unit_of = _units.get", " unit = _unit"]
        exec(f"def encode({args}):\n" + "\n".join(head + self.lines), self.names)  # noqa: S102
        return self.names["encode"]  # type: ignore[no-any-return]


def flat_dtype(types: dict[str, tuple[Field, ...]], type_name: str) -> np.dtype[Any] | None:
    """The numpy record type whose array holds elements of ``type_name`` exactly as a CDR
    sequence of them does (e.g. builtin_interfaces/Time: int32 sec, uint32 nanosec), or None
    where there is none: a field that is not one primitive, padding inside an element, or an
    element whose start could fall on different alignments."""
    fields = types.get(type_name)
    if not fields or any(f.is_message or f.type == "string" or f.sequence
                         or f.length is not None for f in fields):
        return None
    sizes = [STRUCTS[f.type].size for f in fields]
    offsets, at = [], 0
    for size in sizes:
        if at % size:
            return None  # padding inside the element
        offsets.append(at)
        at += size
    widest = max(sizes)
    if at % widest or (sizes[0] != widest and widest > 4):
        return None  # the next element, or the first after a count, would start unaligned
    return np.dtype({"names": [f.name for f in fields],
                     "formats": [DTYPES[f.type] for f in fields],
                     "offsets": offsets, "itemsize": at})


def _length(name: str, n: int, expected: str) -> None:
    raise ValueError(f"{name}: {n} elements, expected {expected}")


def compile_encoder(type_name: str, types: dict[str, tuple[Field, ...]],
                    trace: bool = False) -> Callable[..., None]:
    """An encoder of ``type_name`` from the fields ``types`` (:func:`~.definitions.schema`
    or :func:`~.definitions.parse_definition`): ``encode(buf, value)`` appends the message to
    ``buf``, a bytearray that starts with the 4-byte header (see the module docstring)."""
    return _Source(types, trace).compile(full_name(type_name))


@cache
def encoder(type_name: str) -> Callable[[bytearray, Any], None]:
    """The encoder of ``type_name`` from the environment's definition (made once)."""
    return compile_encoder(type_name, schema(type_name))


@cache
def tracer(type_name: str) -> Callable[[bytearray, Any, dict[str, Any], list[int]], None]:
    """:func:`encoder` that also records leaf and Time offsets (``rows.Layout``)."""
    return compile_encoder(type_name, schema(type_name), trace=True)


def encode(type_name: str, value: Any) -> bytes:
    """The CDR payload (header, padding zero) of one message of ``type_name`` (an rclpy
    message, or nested dicts and lists); MechsimError in one line if a value does not fit
    its field."""
    enc = encoder(type_name)
    buf = bytearray(HEADER)
    try:
        enc(buf, value)
    except ENCODING_ERRORS as e:
        raise MechsimError(f"message type {full_name(type_name)}: cannot encode "
                           f"({type(e).__name__}: {e})") from None
    return bytes(buf)


_TYPE_NAMES: dict[type, str] = {}


def cdr_bytes(msg: Any) -> bytes:
    """The CDR payload of the rclpy message ``msg`` as DDS carries it, padding zero."""
    name = _TYPE_NAMES.get(msg.__class__)
    if name is None:
        name = _TYPE_NAMES[msg.__class__] = type_of(msg)
    return encode(name, msg)
