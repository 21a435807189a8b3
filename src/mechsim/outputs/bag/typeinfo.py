"""What a bag needs to know about a message type, from the ``.msg`` files of the environment.

- :func:`message_definition`: the ``ros2msg`` schema text rosbag2 stores (ROS_CONVENTIONS
  §4): the type's ``.msg`` text verbatim, then each dependency once (a line of 80 ``=``,
  ``MSG: pkg/Type``, its text), depth-first, dependencies of one type in lexicographic order.
  rosbags' ``generate_msgdef`` writes a normalised text without the comments, so the text is
  assembled here; the dependencies come from rosbags' ``.msg`` parser.
- :func:`type_description_hash`: the REP-2011 ``RIHS01_`` hash, computed by rosbags from the same
  ``.msg`` files (it equals ``share/<pkg>/msg/<Type>.json`` of rosidl).
- :func:`cdr_bytes` / :func:`encode_message`: a message's CDR payload, encoded here from the
  type's definition with every padding byte zero (rclpy's ``serialize_message`` leaves padding
  uninitialised, so equal messages could differ in their bytes; it also returns rmw's
  *estimated* size, which counts alignment padding after an empty trailing sequence of 8-byte
  values: sensor_msgs/JointState without effort, 84 bytes where the DDS payload is 80). For a
  type without a known definition, rclpy's bytes are cut at the real end, which rosbags' size
  function of the type computes from the message.
- :func:`message_class`: the rclpy class.

All types live in one rosbags type store built from the environment's ``.msg`` files (the ones
rclpy's classes were generated from), not from a store shipped with rosbags.
"""

from __future__ import annotations

import importlib
import os
import struct
import sys
import threading
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

import numpy as np

from mechsim.errors import MechsimError

SEPARATOR = "=" * 80
_store_lock = threading.Lock()

# CDR (XCDR1 little-endian, as rmw encodes): shared with ``mechsim.outputs.cdr``.
HEADER = b"\x00\x01\x00\x00"  # CDR little-endian, no options
TIME_TYPE = "builtin_interfaces/msg/Time"
PRIMITIVES: dict[str, str] = {
    "bool": "u1", "byte": "u1", "char": "u1", "octet": "u1", "int8": "i1", "uint8": "u1",
    "int16": "<i2", "uint16": "<u2", "int32": "<i4", "uint32": "<u4", "int64": "<i8",
    "uint64": "<u8", "float32": "<f4", "float64": "<f8",
}
DTYPES = {k: np.dtype(v) for k, v in PRIMITIVES.items()}
STRUCTS = {k: struct.Struct("<" + {"u1": "B", "i1": "b", "<i2": "h", "<u2": "H", "<i4": "i",
                                     "<u4": "I", "<i8": "q", "<u8": "Q", "<f4": "f",
                                     "<f8": "d"}[v]) for k, v in PRIMITIVES.items()}
U32 = struct.Struct("<I")
DEPTH_LIMIT = 50
_STR = "string"


def _share_dirs() -> list[Path]:
    dirs = [Path(sys.prefix) / "share"]
    for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if p and Path(p, "share") not in dirs:
            dirs.append(Path(p) / "share")
    return dirs


def split_type(name: str) -> tuple[str, str]:
    """('sensor_msgs', 'JointState') for 'sensor_msgs/msg/JointState' or 'pkg/Type'."""
    parts = name.split("/")
    if len(parts) == 3 and parts[1] == "msg" and all(parts):
        return parts[0], parts[2]
    if len(parts) == 2 and all(parts):
        return parts[0], parts[1]
    raise MechsimError(f"message type {name!r}: expected package/msg/Type")


@cache
def _msg_text(name: str) -> str:
    pkg, typ = split_type(name)
    for share in _share_dirs():
        f = share / pkg / "msg" / f"{typ}.msg"
        if f.is_file():
            return f.read_text()
    raise MechsimError(f"message type {name}: no msg/{typ}.msg in any share/{pkg} "
                       f"(searched {', '.join(str(d) for d in _share_dirs())})")


@cache
def _dependencies(name: str) -> tuple[str, ...]:
    """Types the fields of ``pkg/msg/Type`` use, as ``pkg/msg/Type``, sorted, each once."""
    from rosbags.interfaces import Nodetype
    from rosbags.typesys import TypesysError, get_types_from_msg

    pkg, typ = split_type(name)
    full = f"{pkg}/msg/{typ}"
    try:
        _, fields = get_types_from_msg(_msg_text(full), full)[full]
    except (TypesysError, KeyError) as e:
        raise MechsimError(f"message type {full}: its .msg does not parse ({e})") from None
    deps = set()
    for _, desc in fields:
        kind, arg = desc
        if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            kind, arg = arg[0]
        if kind == Nodetype.NAME:
            deps.add(str(arg))
    return tuple(sorted(deps, key=_short))


def _short(name: str) -> str:
    """'std_msgs/Header' for 'std_msgs/msg/Header' (rosbag2 names dependencies so)."""
    pkg, typ = split_type(name)
    return f"{pkg}/{typ}"


def _closure(name: str) -> list[str]:
    """``name``'s dependencies in rosbag2's order: depth-first, lexicographic, each once."""
    seen: set[str] = set()
    order: list[str] = []

    def visit(n: str, depth: int) -> None:
        if depth > DEPTH_LIMIT:
            raise MechsimError(f"message type {name}: dependencies nested too deep")
        for dep in _dependencies(n):
            if dep not in seen:
                seen.add(dep)
                order.append(dep)
                visit(dep, depth + 1)

    visit(name, 0)
    return order


@cache
def message_definition(type_name: str) -> str:
    """The ``ros2msg`` schema text rosbag2 stores for ``type_name`` (full, with dependencies)."""
    text = _msg_text(type_name)
    for dep in _closure(type_name):
        text += f"\n{SEPARATOR}\nMSG: {_short(dep)}\n" + _msg_text(dep)
    return text


@cache
def _typestore() -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.EMPTY)  # builtin_interfaces Time and Duration only


def typestore_with(type_name: str) -> Any:
    """The rosbags type store holding ``type_name`` and its dependencies (registered from the
    environment's .msg files on first use)."""
    from rosbags.typesys import TypesysError, get_types_from_msg

    pkg, typ = split_type(type_name)
    full = f"{pkg}/msg/{typ}"
    store = _typestore()
    with _store_lock:
        if full not in store.fielddefs:
            types: dict[str, Any] = {}
            for n in [full, *_closure(full)]:
                if n not in store.fielddefs:
                    types.update(get_types_from_msg(_msg_text(n), n))
            try:
                store.register(types)
            except TypesysError as e:
                raise MechsimError(f"message type {full}: {e}") from None
    return store


@cache
def type_description_hash(type_name: str) -> str:
    """REP-2011 hash ``RIHS01_<hex>`` of a type ("" if its definition is not available)."""
    pkg, typ = split_type(type_name)
    try:
        return str(typestore_with(type_name).hash_rihs01(f"{pkg}/msg/{typ}"))
    except MechsimError:
        return ""


def message_class(type_name: str) -> type:
    """The rclpy message class of ``pkg/msg/Type``."""
    pkg, typ = split_type(type_name)
    try:
        return getattr(importlib.import_module(f"{pkg}.msg"), typ)  # type: ignore[no-any-return]
    except (ImportError, AttributeError):
        raise MechsimError(f"message type {type_name} is not installed") from None


@cache
def _size_function(cls: type) -> Any:
    """(getsize_cdr, store) of an rclpy message class, or None if the type is not known."""
    pkg = cls.__module__.split(".")[0]
    name = f"{pkg}/msg/{cls.__name__}"
    try:
        store = typestore_with(name)
        return store.get_msgdef(name).getsize_cdr, store
    except (MechsimError, KeyError):
        return None


@cache
def _plan(type_name: str) -> tuple[tuple[str, Any], ...]:
    """How to encode ``type_name``: per field (name, op), op being "string", a
    ``struct.Struct`` (a primitive), ("msg", plan, is Time), ("seq", op) or ("arr", length,
    op). Made once per type from its definition."""
    from rosbags.interfaces import Nodetype

    store = typestore_with(type_name)

    def op(kind: Any, arg: Any, depth: int) -> Any:
        if depth > DEPTH_LIMIT:
            raise MechsimError(f"{type_name}: message nested too deep")
        if kind == Nodetype.BASE:
            typ = arg[0]
            if typ == "string":
                return _STR
            if typ not in STRUCTS:
                raise MechsimError(f"{type_name}: unsupported primitive type {typ}")
            return STRUCTS[typ]
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


#: Encoded strings (length, bytes, NUL) by value: names, keys and labels recur from message
#: to message. Short strings only, and emptied when full, so it stays within a few MB.
_STRINGS: dict[str, bytes] = {}
_STRINGS_MAX = 4096
_STRING_MEMO_LENGTH = 256


def _string(v: Any) -> bytes:
    """A CDR string (uint32 length with the NUL, the UTF-8 bytes, NUL), remembered in
    ``_STRINGS`` if it is a short ``str``."""
    data = str(v).encode()
    out = U32.pack(len(data) + 1) + data + b"\x00"
    if v.__class__ is str and len(v) <= _STRING_MEMO_LENGTH:
        if len(_STRINGS) >= _STRINGS_MAX:
            _STRINGS.clear()
        _STRINGS[v] = out
    return out


def _struct_value(op: struct.Struct, v: Any) -> bytes:
    """``v`` packed by ``op`` (a byte field's ``bytes`` value is its first byte; a value
    ``struct`` refuses, such as some numpy scalars, goes through numpy)."""
    if isinstance(v, (bytes, bytearray)):
        v = v[0]
    try:
        return op.pack(v)
    except (struct.error, TypeError):
        return op.pack(np.asarray(v).item())


def _struct_run(op: struct.Struct, items: list[Any]) -> bytes:
    """The elements of an array or sequence of one primitive type, back to back."""
    try:
        return struct.pack(f"<{len(items)}{op.format[-1]}", *items)
    except (struct.error, TypeError):  # bytes elements, numpy scalars: one at a time
        return b"".join(_struct_value(op, v) for v in items)


def _array_length(items: list[Any], length: int) -> list[Any]:
    if len(items) != length:
        raise MechsimError(f"{len(items)} elements, the array has {length}")
    return items


@cache
def _encoder(type_name: str) -> Callable[[bytearray, Any], None]:
    """A function appending one message of ``type_name`` (an rclpy message, or nested dicts
    and lists) to a buffer that starts with the 4-byte encapsulation header: Python source
    generated once from :func:`_plan`, every field inline (no call or dispatch per field).
    Alignment counts from the end of the header; padding bytes are zero."""
    names: dict[str, Any] = {
        "_strings": _STRINGS, "_string": _string, "_U32": U32.pack,
        "_Z": [bytes(k) for k in range(8)], "_isdict": dict, "_error": struct.error,
        "_struct_value": _struct_value, "_struct_run": _struct_run,
        "_array_length": _array_length}
    lines: list[str] = []
    count = iter(range(1_000_000))

    def pad(size: int, indent: str) -> None:
        if size > 1:
            lines.append(f"{indent}buf += _Z[(4 - len(buf)) & {size - 1}]")

    def emit(op: Any, expr: str, indent: str) -> None:
        k = next(count)
        if op is _STR:
            pad(4, indent)
            lines.append(f"{indent}v{k} = {expr}")
            lines.append(f"{indent}buf += (_strings.get(v{k}) or _string(v{k})) "
                         f"if v{k}.__class__ is str else _string(v{k})")
        elif isinstance(op, struct.Struct):
            names[f"_s{k}"] = op
            names[f"_pack{k}"] = op.pack
            pad(op.size, indent)
            lines.append(f"{indent}v{k} = {expr}")
            lines.append(f"{indent}try:")
            lines.append(f"{indent} buf += _pack{k}(v{k})")
            lines.append(f"{indent}except (_error, TypeError):")
            lines.append(f"{indent} buf += _struct_value(_s{k}, v{k})")
        elif op[0] == "msg":
            if op[2]:  # builtin_interfaces/Time: 4-aligned
                pad(4, indent)
            lines.append(f"{indent}m{k} = {expr}")
            lines.append(f"{indent}g{k} = m{k}.__getitem__ if isinstance(m{k}, _isdict) "
                         f"else m{k}.__getattribute__")
            for name, sub in op[1]:
                emit(sub, f"g{k}({name!r})", indent)
        else:
            sub = op[-1]
            items = f"list({expr})"
            if op[0] == "seq":
                lines.append(f"{indent}items{k} = {items}")
                pad(4, indent)
                lines.append(f"{indent}buf += _U32(len(items{k}))")
            else:
                lines.append(f"{indent}items{k} = _array_length({items}, {int(op[1])})")
            if isinstance(sub, struct.Struct):
                names[f"_s{k}"] = sub
                lines.append(f"{indent}if items{k}:")
                pad(sub.size, indent + " ")
                lines.append(f"{indent} buf += _struct_run(_s{k}, items{k})")
            else:
                lines.append(f"{indent}for x{k} in items{k}:")
                emit(sub, f"x{k}", indent + " ")

    pkg, typ = split_type(type_name)
    emit(("msg", _plan(f"{pkg}/msg/{typ}"), False), "value", " ")
    exec("def encode(buf, value):\n" + "\n".join(lines), names)  # noqa: S102 - our source
    return names["encode"]  # type: ignore[no-any-return]


def encode_message(type_name: str, value: Any) -> bytes:
    """The CDR payload (with the encapsulation header, padding zero) of one message of
    ``type_name`` (an rclpy message, or nested dicts and lists): the path for single
    messages (:func:`cdr_bytes`); same rules as ``mechsim.outputs.cdr.Layout``."""
    buf = bytearray(HEADER)
    _encoder(type_name)(buf, value)
    return bytes(buf)


#: A diagnostic_msgs/DiagnosticStatus as plain values: level, name, message, hardware_id and
#: the (key, value) pairs.
StatusRow = tuple[int, str, str, str, list[tuple[str, str]]]
_TIME = struct.Struct("<iI")
#: A string's NUL and the padding after it, by its CDR length (with the NUL) modulo 4.
_STRING_TAILS = (b"\x00", b"\x00" * 4, b"\x00" * 3, b"\x00" * 2)
#: Strings of reports as 4-aligned units (``_unit``): names, keys and most values recur.
_UNITS: dict[str, bytes] = {}


def _unit(text: str) -> bytes:
    """A CDR string that starts 4-aligned, with the padding up to the next 4-aligned byte
    (remembered in ``_UNITS``, up to ``_STRINGS_MAX`` of them)."""
    unit = _UNITS.get(text)
    if unit is None:
        data = text.encode()
        unit = U32.pack(len(data) + 1) + data + _STRING_TAILS[(len(data) + 1) & 3]
        if len(_UNITS) >= _STRINGS_MAX:
            _UNITS.clear()
        _UNITS[text] = unit
    return unit


def encode_diagnostic_array(sec: int, nanosec: int, frame_id: str,
                            statuses: list[StatusRow]) -> bytes:
    """The CDR payload of a diagnostic_msgs/DiagnosticArray (stamp ``sec``, ``nanosec``),
    equal to :func:`encode_message` of the same fields: the diagnostics node's report, made
    every second of a run, a few µs per status. Every field after the stamp is a 4-aligned
    string or count but a status's level byte, so each string is a unit with the padding
    after it (``_unit``); a level that follows a string takes the first byte of that
    padding, and the message ends at its last string's NUL."""
    count = U32.pack
    unit = _unit
    parts = [HEADER, _TIME.pack(sec, nanosec), unit(frame_id), count(len(statuses))]
    pad = 0  # padding at the end of parts[-1] (a string unit's)
    for level, name, message, hardware_id, values in statuses:
        if pad:  # the level right after the string's NUL, then padding to 4
            parts[-1] = parts[-1][:-pad] + bytes((level,)) + bytes(pad - 1)
        else:
            parts.append(bytes((level, 0, 0, 0)))
        parts += (unit(name), unit(message), unit(hardware_id), count(len(values)))
        pad = 0
        for key, value in values:
            last = unit(value)
            parts += (unit(key), last)
        if values:
            pad = len(last) - 4 - U32.unpack_from(last)[0]
    data = b"".join(parts)
    return data[:len(data) - pad] if pad else data


def cdr_bytes(msg: Any) -> bytes:
    """The CDR payload of ``msg`` as DDS carries it, every padding byte zero: encoded from the
    type's definition (``mechsim.outputs.cdr``; rclpy's serializer leaves its padding bytes
    uninitialised, so equal messages could differ in their bytes). For a type without a known
    definition, rclpy's serialization cut at the end of the data (see the module docstring)."""
    cls = type(msg)
    pkg = cls.__module__.split(".")[0]
    try:
        return encode_message(f"{pkg}/msg/{cls.__name__}", msg)
    except (MechsimError, KeyError, AttributeError, TypeError, ValueError):
        return _rclpy_bytes(msg)


def _rclpy_bytes(msg: Any) -> bytes:
    """rclpy's serialization of ``msg``, cut at the end of the data (unchanged if the size
    is unknown)."""
    from rclpy.serialization import serialize_message

    data: bytes = serialize_message(msg)
    size = _size_function(type(msg))
    if size is None:
        return data
    getsize, store = size
    try:
        end = 4 + int(getsize(0, msg, store))
    except (AttributeError, TypeError, ValueError, UnicodeError):
        return data
    return data[:end] if end < len(data) else data
