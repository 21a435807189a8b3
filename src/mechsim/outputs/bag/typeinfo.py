"""What a bag needs to know about a message type, from the ``.msg`` files of the environment.

- :func:`message_definition`: the ``ros2msg`` schema text rosbag2 stores (ROS_CONVENTIONS
  §4): the type's ``.msg`` text verbatim, then each dependency once (a line of 80 ``=``,
  ``MSG: pkg/Type``, its text), depth-first, dependencies of one type in lexicographic order.
  rosbags' ``generate_msgdef`` writes a normalised text without the comments, so the text is
  assembled here; the dependencies come from rosbags' ``.msg`` parser.
- :func:`type_description_hash`: the REP-2011 ``RIHS01_`` hash, computed by rosbags from the same
  ``.msg`` files (it equals ``share/<pkg>/msg/<Type>.json`` of rosidl).
- :func:`cdr_bytes`: a message's CDR payload. ``rclpy.serialization.serialize_message`` returns
  rmw's *estimated* size, which counts alignment padding after an empty trailing sequence of
  8-byte values (sensor_msgs/JointState without effort: 84 bytes where the DDS payload is 80);
  readers that check the length (rosbags) reject such bytes, so the payload is cut at the real
  end, which rosbags' size function of the type computes from the message.
- :func:`message_class`: the rclpy class.

All types live in one rosbags type store built from the environment's ``.msg`` files (the ones
rclpy's classes were generated from), not from a store shipped with rosbags.
"""

from __future__ import annotations

import importlib
import os
import sys
import threading
from functools import cache
from pathlib import Path
from typing import Any

from mechsim.errors import MechsimError

SEPARATOR = "=" * 80
_DEPTH_LIMIT = 50
_store_lock = threading.Lock()


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
        if depth > _DEPTH_LIMIT:
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


def cdr_bytes(msg: Any) -> bytes:
    """The CDR payload of ``msg`` as DDS carries it, every padding byte zero: encoded from the
    type's definition (``mechsim.outputs.cdr``; rclpy's serializer leaves its padding bytes
    uninitialised, so equal messages could differ in their bytes). For a type without a known
    definition, rclpy's serialization cut at the end of the data (see the module docstring)."""
    from mechsim.outputs.cdr import encode_message

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
