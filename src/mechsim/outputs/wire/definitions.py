"""Message definitions: the environment's ``.msg`` texts, the ``ros2msg`` schema text a bag
stores, and the fields the encoder is generated from.

- :func:`message_definition`: the schema text rosbag2 stores (ROS_CONVENTIONS §4): the type's
  ``.msg`` text verbatim, then each dependency once (a line of 80 ``=``, ``MSG: pkg/Type``, its
  text), depth-first, the dependencies of one type in lexicographic order. rosbags'
  ``generate_msgdef`` writes a normalised text without the comments, so the text is assembled
  here; the dependencies come from rosbags' ``.msg`` parser.
- :func:`schema`: the fields of a type and of every type it uses, parsed from such a text
  (by default the type's own :func:`message_definition`; a bag's schema text works as well).
- :func:`type_description_hash`: the REP-2011 ``RIHS01_`` hash, computed by rosbags from the
  same ``.msg`` files (it equals ``share/<pkg>/msg/<Type>.json`` of rosidl).
- :func:`message_class`: the rclpy class.

All texts come from the ``.msg`` files of the environment (the ones rclpy's classes were
generated from), never from a store shipped with rosbags.
"""

from __future__ import annotations

import importlib
import os
import sys
import threading
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

from mechsim.errors import MechsimError

SEPARATOR = "=" * 80
#: Deepest nesting of message types followed (a definition is data: it may be hostile).
DEPTH_LIMIT = 50
TIME_TYPE = "builtin_interfaces/msg/Time"
#: The primitive types of ``.msg`` files (``wstring`` is refused: see :func:`schema`).
PRIMITIVES = ("bool", "byte", "char", "octet", "int8", "uint8", "int16", "uint16", "int32",
              "uint32", "int64", "uint64", "float32", "float64")
_store_lock = threading.Lock()


@dataclass(frozen=True)
class Field:
    """One field of a message type.

    ``type``: a primitive (:data:`PRIMITIVES`), ``"string"``, or a message type
    ``pkg/msg/Type``. ``length``: the element count of a fixed array ``T[N]``, None if the
    field is not one. ``sequence``: ``T[]`` or ``T[<=N]``; ``bound``: the N of ``T[<=N]``
    (0: unbounded). ``string_bound``: the N of ``string<=N`` (characters of each string;
    0: unbounded)."""

    name: str
    type: str
    length: int | None = None
    sequence: bool = False
    bound: int = 0
    string_bound: int = 0

    @property
    def is_message(self) -> bool:
        return "/" in self.type


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


def full_name(name: str) -> str:
    """'pkg/msg/Type' for 'pkg/msg/Type' or 'pkg/Type'."""
    pkg, typ = split_type(name)
    return f"{pkg}/msg/{typ}"


def _short(name: str) -> str:
    """'std_msgs/Header' for 'std_msgs/msg/Header' (rosbag2 names dependencies so)."""
    pkg, typ = split_type(name)
    return f"{pkg}/{typ}"


def type_of(msg: Any) -> str:
    """'sensor_msgs/msg/JointState' for an rclpy JointState message."""
    cls = type(msg)
    return f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}"


@cache
def _msg_text(name: str) -> str:
    pkg, typ = split_type(name)
    for share in _share_dirs():
        f = share / pkg / "msg" / f"{typ}.msg"
        if f.is_file():
            return f.read_text()
    raise MechsimError(f"message type {name}: no msg/{typ}.msg in any share/{pkg} "
                       f"(searched {', '.join(str(d) for d in _share_dirs())})")


def _parse(text: str, name: str) -> dict[str, Any]:
    """rosbags' parse of a ``.msg`` or ``ros2msg`` text: type -> (constants, fields)."""
    from rosbags.typesys import TypesysError, get_types_from_msg

    try:
        return dict(get_types_from_msg(text, name))
    except TypesysError as e:
        first = str(e).splitlines()[0] if str(e) else "no reason given"
        raise MechsimError(f"message type {name}: its definition does not parse ({first})"
                           ) from None


@cache
def _dependencies(name: str) -> tuple[str, ...]:
    """Types the fields of ``pkg/msg/Type`` use, as ``pkg/msg/Type``, sorted, each once."""
    full = full_name(name)
    try:
        fields = _parse(_msg_text(full), full)[full][1]
    except KeyError:
        raise MechsimError(f"message type {full}: its .msg does not define it") from None
    deps = {f.type for f in (_field(n, desc, full) for n, desc in fields) if f.is_message}
    return tuple(sorted(deps, key=_short))


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


def _field(name: str, desc: Any, owner: str) -> Field:
    """A :class:`Field` from rosbags' description of it (``(Nodetype, argument)``)."""
    from rosbags.interfaces import Nodetype

    kind, arg = desc
    length: int | None = None
    sequence = False
    bound = 0
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        (kind, arg), count = arg
        if kind not in (Nodetype.BASE, Nodetype.NAME):
            raise MechsimError(f"{owner}.{name}: arrays of arrays are not a .msg type")
        if desc[0] == Nodetype.ARRAY:
            length = int(count)
        else:
            sequence, bound = True, int(count or 0)
    if kind == Nodetype.BASE:
        typ, string_bound = arg[0], int(arg[1] or 0)
        if typ != "string" and typ not in PRIMITIVES:
            raise MechsimError(f"{owner}.{name}: unknown primitive type {typ}")
        return Field(name, typ, length, sequence, bound, string_bound)
    if kind != Nodetype.NAME:
        raise MechsimError(f"{owner}.{name}: unsupported field kind {kind}")
    typ = full_name(str(arg))
    if typ.rpartition("/")[2] == "wstring":  # rosbags reads a wstring as a type name
        raise MechsimError(f"{owner}.{name}: wstring fields are not supported")
    return Field(name, typ, length, sequence, bound)


def parse_definition(type_name: str, text: str) -> dict[str, tuple[Field, ...]]:
    """The fields of ``type_name`` and of the types it uses, from a ``ros2msg`` schema text
    (:func:`message_definition`'s form: the type's ``.msg`` text, then ``MSG:`` sections)."""
    full = full_name(type_name)
    types = {name: tuple(_field(n, desc, name) for n, desc in fields)
             for name, (_, fields) in _parse(text, full).items()}
    missing = sorted({f.type for fields in types.values() for f in fields
                      if f.is_message and f.type not in types})
    if full not in types or missing:
        raise MechsimError(f"message type {full}: the definition lacks "
                           f"{', '.join(missing) or full}")
    return types


@cache
def schema(type_name: str) -> dict[str, tuple[Field, ...]]:
    """:func:`parse_definition` of the environment's definition of ``type_name``."""
    return parse_definition(type_name, message_definition(full_name(type_name)))


@cache
def _typestore() -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.EMPTY)  # builtin_interfaces Time and Duration only


def typestore_with(type_name: str) -> Any:
    """The rosbags type store holding ``type_name`` and its dependencies (registered from the
    environment's .msg files on first use): for hashes and for decoding without rclpy."""
    from rosbags.typesys import TypesysError

    full = full_name(type_name)
    store = _typestore()
    with _store_lock:
        if full not in store.fielddefs:
            types: dict[str, Any] = {}
            for n in [full, *_closure(full)]:
                if n not in store.fielddefs:
                    types.update(_parse(_msg_text(n), n))
            try:
                store.register(types)
            except TypesysError as e:
                raise MechsimError(f"message type {full}: {e}") from None
    return store


@cache
def type_description_hash(type_name: str) -> str:
    """REP-2011 hash ``RIHS01_<hex>`` of a type ("" if its definition is not available)."""
    try:
        return str(typestore_with(type_name).hash_rihs01(full_name(type_name)))
    except MechsimError:
        return ""


def message_class(type_name: str) -> type:
    """The rclpy message class of ``pkg/msg/Type``."""
    pkg, typ = split_type(type_name)
    try:
        return getattr(importlib.import_module(f"{pkg}.msg"), typ)  # type: ignore[no-any-return]
    except (ImportError, AttributeError):
        raise MechsimError(f"message type {type_name} is not installed") from None
