"""rosbag2-compatible MCAP bags: the writer sink, the reader, metadata and repair.

A bag is a directory ``DIR`` holding ``DIR_0.mcap`` and ``metadata.yaml``, exactly as rosbag2's
MCAP storage writes them (ROS_CONVENTIONS §4), so ``ros2 bag info|play``, ``rosbags``,
``mcap`` + ``mcap_ros2``, Foxglove and Rerun read them:

- MCAP profile ``ros2``; one ``ros2msg`` schema per type, holding the full definition text with
  its dependencies (lexicographic, depth-first, each once, 80 ``=`` separators) read from the
  ``.msg`` files of the environment (``<prefix>/share/<pkg>/msg``);
- one ``cdr`` channel per topic, metadata ``offered_qos_profiles`` (YAML, version-9 string
  enums) and ``topic_type_hash`` (RIHS01, from ``share/<pkg>/msg/<Type>.json``);
- messages serialized by ``rclpy.serialization.serialize_message`` (cut to the real CDR length,
  see :func:`cdr_bytes`); ``log_time`` =
  ``publish_time`` = the message stamp (simulation time + offset), so ``ros2 bag play --clock``
  reproduces simulation time;
- zstd-compressed chunks, message indexes and a summary; the ``rosbag2`` metadata record
  (``serialized_metadata``) at open and at close; ``metadata.yaml`` version 9 with
  ``custom_data`` describing the run (scene, instances, systems, parameters, integrators).

Robustness. Records are written by a writer thread (Python runs signal handlers in the main
thread only, so Ctrl-C / SIGTERM can never interrupt a half-written record); the sink only
serializes and queues. A chunk is closed and flushed to the file at least every second of
simulation time and every second of wall time, so after a hard kill (SIGKILL, power loss of the
process) every chunk but the last is in the file. ``metadata.yaml`` is written last, to a
temporary name renamed into place: a bag directory without it is an interrupted recording, which
:func:`repair_bag` (``mechsim bag repair DIR``) turns back into a complete bag (it rewrites the
MCAP from a sequential pass over the readable records, then writes ``metadata.yaml``). A write
error (disk full, ...) stops the recording; the caller removes the partial bag (see
``mechsim.ros.record``).
"""

from __future__ import annotations

import importlib
import json
import os
import queue
import re
import shutil
import struct
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any

import yaml

from mechsim.errors import MechsimError

ROSBAG2_VERSION = 9
STORAGE_ID = "mcap"
SERIALIZATION = "cdr"
PROFILE = "ros2"
SCHEMA_ENCODING = "ros2msg"
ROS_DISTRO = "kilted"
SEPARATOR = "=" * 80
METADATA_FILE = "metadata.yaml"
#: Infinite rmw durations as rosbag2 writes them.
INFINITE = (9223372036, 854775807)
#: A chunk is closed at least this often (simulation time of the stamps, and wall time).
FLUSH_SIM_NS = 1_000_000_000
FLUSH_WALL_S = 1.0
CHUNK_SIZE = 512 * 1024
_PRIMITIVES = frozenset({"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16",
                         "uint16", "int32", "uint32", "int64", "uint64", "string", "wstring"})
_DEP_RE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_FILE_RE = re.compile(r".+_(\d+)\.mcap$")


# --- type information from the environment ----------------------------------------------------
def _share_dirs() -> list[Path]:
    dirs = [Path(sys.prefix) / "share"]
    for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if p and Path(p, "share") not in dirs:
            dirs.append(Path(p) / "share")
    return dirs


def _split_type(name: str) -> tuple[str, str]:
    """('sensor_msgs', 'JointState') for 'sensor_msgs/msg/JointState' or 'pkg/Type'."""
    parts = name.split("/")
    if len(parts) == 3 and parts[1] == "msg":
        return parts[0], parts[2]
    if len(parts) == 2:
        return parts[0], parts[1]
    raise MechsimError(f"message type {name!r}: expected package/msg/Type")


def _interface_file(name: str, suffix: str) -> Path:
    pkg, typ = _split_type(name)
    for share in _share_dirs():
        f = share / pkg / "msg" / f"{typ}{suffix}"
        if f.is_file():
            return f
    raise MechsimError(f"message type {name}: no msg/{typ}{suffix} in any share/{pkg} "
                       f"(searched {', '.join(str(d) for d in _share_dirs())})")


def _dependencies(text: str, package: str) -> list[str]:
    """Types a .msg text uses, named as rosbag2 names them (``pkg/Type``), sorted."""
    deps = set()
    for m in _DEP_RE.finditer(text):
        typ = m.group(1)
        if typ in _PRIMITIVES:
            continue
        deps.add(typ if "/" in typ else f"{package}/{typ}")
    return sorted(deps)


@cache
def message_definition(type_name: str) -> str:
    """The ``ros2msg`` schema text rosbag2 stores for ``type_name`` (full, with dependencies)."""
    seen: set[str] = set()

    def text_with_deps(name: str, depth: int) -> str:
        if depth <= 0:
            raise MechsimError(f"message type {type_name}: dependencies nested too deep")
        text = _interface_file(name, ".msg").read_text()
        out = text
        for dep in _dependencies(text, _split_type(name)[0]):
            if dep not in seen:
                seen.add(dep)
                out += f"\n{SEPARATOR}\nMSG: {dep}\n" + text_with_deps(dep, depth - 1)
        return out

    return text_with_deps(type_name, 50)


@cache
def type_description_hash(type_name: str) -> str:
    """REP-2011 hash ``RIHS01_<hex>`` of a type, from ``share/<pkg>/msg/<Type>.json``."""
    try:
        data = json.loads(_interface_file(type_name, ".json").read_text())
        return str(data["type_hashes"][0]["hash_string"])
    except (MechsimError, KeyError, IndexError, ValueError):
        return ""


def message_class(type_name: str) -> type:
    """The rclpy message class of ``pkg/msg/Type``."""
    pkg, typ = _split_type(type_name)
    try:
        return getattr(importlib.import_module(f"{pkg}.msg"), typ)  # type: ignore[no-any-return]
    except (ImportError, AttributeError):
        raise MechsimError(f"message type {type_name} is not installed") from None


# --- CDR payload length -----------------------------------------------------------------------
# rclpy.serialization.serialize_message returns rmw's *estimated* size, which counts alignment
# padding for an empty trailing sequence of 8-byte values (sensor_msgs/JointState with no effort:
# 84 bytes where the DDS payload is 80). Readers that check the length (rosbags) reject such
# bytes, so the writer cuts the payload at the real end, computed from the message (XCDR1).
_PRIM_SIZE = {"boolean": 1, "octet": 1, "char": 1, "int8": 1, "uint8": 1, "int16": 2,
              "uint16": 2, "short": 2, "unsigned short": 2, "wchar": 2, "int32": 4,
              "uint32": 4, "long": 4, "unsigned long": 4, "float": 4, "int64": 8, "uint64": 8,
              "long long": 8, "unsigned long long": 8, "double": 8}


@cache
def _cdr_plan(cls: type) -> tuple[tuple[str, int, str, int], ...] | None:
    """Per field: (attribute, 0 scalar / 1 sequence / 2 array, kind p|s|m, primitive size)."""
    from rosidl_parser import definition as d

    plan = []
    for slot, t in zip(cls.__slots__, cls.SLOT_TYPES, strict=False):  # type: ignore[attr-defined]
        shape = 0
        if isinstance(t, d.AbstractNestedType):
            shape = 2 if isinstance(t, d.Array) else 1
            t = t.value_type
        if isinstance(t, d.BasicType) and t.typename in _PRIM_SIZE:
            plan.append((slot[1:], shape, "p", _PRIM_SIZE[t.typename]))
        elif isinstance(t, d.AbstractString) and not isinstance(t, d.AbstractWString):
            plan.append((slot[1:], shape, "s", 1))
        elif isinstance(t, d.NamespacedType):
            plan.append((slot[1:], shape, "m", 0))
        else:
            return None
    return tuple(plan)


def _cdr_end(msg: Any, off: int) -> int:
    plan = _cdr_plan(type(msg))
    if plan is None:
        raise LookupError(type(msg).__name__)
    for attr, shape, kind, size in plan:
        v = getattr(msg, attr)
        if shape == 0:
            v = (v,)
        elif shape == 1:
            off = ((off + 3) & ~3) + 4
        if kind == "p":
            if len(v):
                a = size if size < 8 else 8
                off = (off + a - 1) // a * a + len(v) * size
        elif kind == "s":
            for x in v:
                off = ((off + 3) & ~3) + 5 + len(x.encode())
        else:
            for x in v:
                off = _cdr_end(x, off)
    return off


def cdr_bytes(msg: Any) -> bytes:
    """The CDR payload of ``msg`` as DDS carries it: rclpy's serialization, cut at the end of
    the data (see above); rclpy's bytes unchanged if the type cannot be measured."""
    from rclpy.serialization import serialize_message

    data = serialize_message(msg)
    try:
        end = 4 + _cdr_end(msg, 0)
    except (LookupError, AttributeError, UnicodeError):
        return data  # type: ignore[no-any-return]
    return data[:end] if end < len(data) else data  # type: ignore[no-any-return]


# --- QoS --------------------------------------------------------------------------------------
def _duration(d: Any) -> dict[str, int]:
    ns = int(getattr(d, "nanoseconds", 0) or 0)
    if ns <= 0 or ns >= INFINITE[0] * 1_000_000_000:
        return {"sec": INFINITE[0], "nsec": INFINITE[1]}
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def qos_dict(qos: Any) -> dict[str, Any]:
    """One entry of ``offered_qos_profiles`` (version 9: string enums), a fresh dict."""
    return {
        "history": qos.history.name.lower(),
        "depth": int(qos.depth),
        "reliability": qos.reliability.name.lower(),
        "durability": qos.durability.name.lower(),
        "deadline": _duration(qos.deadline),
        "lifespan": _duration(qos.lifespan),
        "liveliness": qos.liveliness.name.lower(),
        "liveliness_lease_duration": _duration(qos.liveliness_lease_duration),
        "avoid_ros_namespace_conventions": bool(qos.avoid_ros_namespace_conventions),
    }


def qos_profile(entries: list[dict[str, Any]], latched_messages: int = 1) -> Any:
    """The rclpy QoSProfile to republish with, from a topic's ``offered_qos_profiles``.
    A transient-local topic keeps up to ``latched_messages`` (at most 100) for late joiners:
    in the recording several publishers (one per system on /tf_static) each kept theirs."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    e = entries[0] if entries else {}
    durability = (DurabilityPolicy.TRANSIENT_LOCAL if e.get("durability") == "transient_local"
                  else DurabilityPolicy.VOLATILE)
    reliability = (ReliabilityPolicy.BEST_EFFORT if e.get("reliability") == "best_effort"
                   else ReliabilityPolicy.RELIABLE)
    depth = int(e.get("depth") or 0) or (1 if durability == DurabilityPolicy.TRANSIENT_LOCAL
                                         else 10)
    if durability == DurabilityPolicy.TRANSIENT_LOCAL:
        depth = max(depth, min(int(latched_messages), 100))
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST, reliability=reliability,
                      durability=durability)


class _Dumper(yaml.SafeDumper):
    """yaml-cpp look: block style, indented sequences, no anchors."""

    def ignore_aliases(self, data: Any) -> bool:
        return True

    def increase_indent(self, flow: bool = False, indentless: bool = False) -> None:
        super().increase_indent(flow, False)


def dump_yaml(data: Any) -> str:
    return yaml.dump(data, Dumper=_Dumper, sort_keys=False, default_flow_style=False,
                     allow_unicode=True, width=1 << 20)


# --- metadata ---------------------------------------------------------------------------------
@dataclass
class TopicInfo:
    name: str
    type: str
    qos: list[dict[str, Any]]
    type_hash: str
    count: int = 0


@dataclass
class BagStats:
    """What a bag holds: per topic, counts, time range, run description."""

    topics: dict[str, TopicInfo] = field(default_factory=dict)
    start_ns: int | None = None
    end_ns: int | None = None
    custom_data: dict[str, str] = field(default_factory=dict)

    @property
    def message_count(self) -> int:
        return sum(t.count for t in self.topics.values())

    def add(self, topic: str, ns: int) -> None:
        self.topics[topic].count += 1
        self.start_ns = ns if self.start_ns is None else min(self.start_ns, ns)
        self.end_ns = ns if self.end_ns is None else max(self.end_ns, ns)


def bag_metadata(stats: BagStats, file_name: str) -> dict[str, Any]:
    """BagMetadata (the mapping under ``rosbag2_bagfile_information``), version 9."""
    start = stats.start_ns or 0
    duration = (stats.end_ns - start) if stats.end_ns is not None else 0
    return {
        "version": ROSBAG2_VERSION,
        "storage_identifier": STORAGE_ID,
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": stats.message_count,
        "topics_with_message_count": [
            {"topic_metadata": {"name": t.name, "type": t.type,
                                "serialization_format": SERIALIZATION,
                                "offered_qos_profiles": [dict(q) for q in t.qos],
                                "type_description_hash": t.type_hash},
             "message_count": t.count}
            for t in stats.topics.values()],
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [file_name],
        "files": [{"path": file_name, "starting_time": {"nanoseconds_since_epoch": start},
                   "duration": {"nanoseconds": duration},
                   "message_count": stats.message_count}],
        "custom_data": dict(stats.custom_data) or None,
        "ros_distro": ROS_DISTRO,
    }


def _write_metadata_yaml(directory: Path, meta: dict[str, Any]) -> None:
    tmp = directory / f".{METADATA_FILE}.tmp"
    with open(tmp, "w") as f:
        f.write(dump_yaml({"rosbag2_bagfile_information": meta}))
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, directory / METADATA_FILE)


def storage_file_name(directory: Path) -> str:
    return f"{directory.resolve().name}_0.mcap"


def expand_path(path: str | Path) -> Path:
    """``~`` and strftime fields (``runs/default_%Y%m%d-%H%M%S``) expanded."""
    text = os.path.expanduser(str(path))
    return Path(time.strftime(text) if "%" in text else text)


def prepare_bag_dir(path: str | Path) -> Path:
    """Check and create a new bag directory (MechsimError naming the path otherwise)."""
    d = expand_path(path)
    if d.exists():
        if not d.is_dir():
            raise MechsimError(f"bag {d}: exists and is not a directory")
        if any(d.iterdir()):
            raise MechsimError(f"bag {d}: directory exists and is not empty (choose a new path)")
    try:
        d.mkdir(parents=True, exist_ok=True)
        probe = d / ".write_test"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as e:
        raise MechsimError(f"bag {d}: cannot write ({e.strerror or e})") from None
    return d


SYSTEM_INFO = "mechsim_msgs/msg/SystemInfo"


def system_info_custom(info: Any) -> dict[str, str]:
    """``custom_data`` entries describing one system instance, from its SystemInfo message."""
    p = f"mechsim.{info.instance}."
    return {p + "system": info.system, p + "formulation": info.formulation,
            p + "parameters": info.parameters_yaml, p + "integrator": info.integrator,
            p + "tolerance": repr(info.tolerance), p + "laws": ",".join(info.laws),
            p + "version": info.mechsim_version}


# --- writer -----------------------------------------------------------------------------------
_STOP = object()


class BagWriter:
    """Sink (see ``mechsim.ros.outlet``) writing every message into a new rosbag2 MCAP bag.

    ``BagWriter(path)`` creates the directory (new or empty; MechsimError otherwise);
    :meth:`close` finishes the MCAP and writes ``metadata.yaml``; :meth:`abort` removes the bag.
    A write error (OSError, or MechsimError for a type without a .msg) is raised by the next
    :meth:`write` and by :meth:`close`.
    """

    def __init__(self, path: str | Path, custom_data: dict[str, str] | None = None,
                 chunk_size: int = CHUNK_SIZE) -> None:
        self.path = prepare_bag_dir(path)
        self.file_name = storage_file_name(self.path)
        self.stats = BagStats(custom_data={k: str(v) for k, v in (custom_data or {}).items()})
        self._types: dict[str, str] = {}
        self._queue: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self.error: Exception | None = None
        self._closed = False
        self._chunk_size = chunk_size
        self._thread = threading.Thread(target=self._run, name="bag-writer", daemon=False)
        self._file: Any = None
        try:
            self._file = open(self.path / self.file_name, "wb")
        except OSError as e:
            shutil.rmtree(self.path, ignore_errors=True)
            raise MechsimError(f"bag {self.path}: cannot write ({e.strerror or e})") from None
        self._thread.start()

    # main thread: serialize and queue (never touches the file)
    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        self.write_serialized(topic, type_name, msg, qos, ns, cdr_bytes(msg))

    def write_serialized(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int,
                         data: bytes) -> None:
        """``write`` with the CDR payload already made (by the Outlet, which publishes the
        same bytes, so each message is serialized once)."""
        if self.error is not None:
            raise self.error
        if self._closed:
            return
        if topic not in self._types:
            self._types[topic] = type_name
            self._queue.put(("channel", topic, type_name, qos_dict(qos)))
        if type_name == SYSTEM_INFO:
            for key, value in system_info_custom(msg).items():
                self._queue.put(("custom", key, value))
        self._queue.put((topic, ns, data))

    def set_custom(self, key: str, value: Any) -> None:
        self._queue.put(("custom", key, str(value)))

    def close(self) -> BagStats:
        """Finish the file and write metadata.yaml (waits for the writer thread)."""
        if not self._closed:
            self._closed = True
            self._queue.put(_STOP)
        self._thread.join()
        if self.error is not None:
            raise self.error
        return self.stats

    def abort(self) -> None:
        """Stop and remove the bag directory (after an error: no half-written bag is left)."""
        if not self._closed:
            self._closed = True
            self._queue.put(_STOP)
        self._thread.join()
        shutil.rmtree(self.path, ignore_errors=True)

    # writer thread
    def _run(self) -> None:
        try:
            self._write_loop()
        except Exception as e:  # noqa: BLE001 - handed to the main thread by write()/close()
            self.error = e
            while self._queue.get() is not _STOP:  # drain until close()/abort()
                pass
        finally:
            try:
                self._file.close()
            except OSError as e:
                self.error = self.error or e

    def _write_loop(self) -> None:
        from mcap.writer import LIBRARY_IDENTIFIER, CompressionType, Writer

        from mechsim import __version__

        w = Writer(self._file, chunk_size=self._chunk_size, compression=CompressionType.ZSTD)
        w.start(profile=PROFILE, library=f"mechsim {__version__}; {LIBRARY_IDENTIFIER}")
        w.add_metadata("rosbag2", {"serialized_metadata": dump_yaml(
            bag_metadata(BagStats(custom_data=dict(self.stats.custom_data)), self.file_name))})
        self._file.flush()
        schemas: dict[str, int] = {}
        channels: dict[str, int] = {}
        # mcap's Writer closes a chunk only when it is full; its (private, name-mangled)
        # __finalize_chunk closes it now. Without it (another mcap version) chunks still close
        # at CHUNK_SIZE, only the "lose at most ~1 s on a hard kill" bound is gone.
        finalize = getattr(w, "_Writer__finalize_chunk", None)
        last_flush_ns: int | None = None
        last_flush_wall = time.monotonic()
        while True:
            item = self._queue.get()
            if item is _STOP:
                break
            if item[0] == "channel":
                _, topic, type_name, qos = item
                if type_name not in schemas:
                    schemas[type_name] = w.register_schema(
                        type_name, SCHEMA_ENCODING, message_definition(type_name).encode())
                h = type_description_hash(type_name)
                channels[topic] = w.register_channel(
                    topic, SERIALIZATION, schemas[type_name],
                    {"offered_qos_profiles": dump_yaml([qos]), "topic_type_hash": h})
                self.stats.topics[topic] = TopicInfo(topic, type_name, [qos], h)
                continue
            if item[0] == "custom":
                self.stats.custom_data[item[1]] = item[2]
                continue
            topic, ns, data = item
            w.add_message(channels[topic], log_time=ns, data=data, publish_time=ns)
            self.stats.add(topic, ns)
            if last_flush_ns is None:
                last_flush_ns = ns
            now = time.monotonic()
            if ns - last_flush_ns >= FLUSH_SIM_NS or now - last_flush_wall >= FLUSH_WALL_S:
                if finalize is not None:
                    finalize()
                self._file.flush()
                last_flush_ns, last_flush_wall = ns, now
        meta = bag_metadata(self.stats, self.file_name)
        w.add_metadata("rosbag2", {"serialized_metadata": dump_yaml(meta)})
        w.finish()
        self._file.flush()
        os.fsync(self._file.fileno())
        _write_metadata_yaml(self.path, meta)


# --- reader -----------------------------------------------------------------------------------
@dataclass
class BagMessage:
    topic: str
    type_name: str
    log_time: int
    data: bytes


def _bag_files(d: Path) -> list[Path]:
    files = [(int(m.group(1)), p) for p in d.iterdir()
             if p.is_file() and (m := _FILE_RE.match(p.name))]
    return [p for _, p in sorted(files)]


def read_metadata(path: str | Path) -> dict[str, Any]:
    """``rosbag2_bagfile_information`` of a bag directory (MechsimError if unusable)."""
    d = Path(path)
    if not d.is_dir():
        raise MechsimError(f"bag {d}: no such directory")
    f = d / METADATA_FILE
    if not f.is_file():
        hint = (f"; an interrupted recording? run `mechsim bag repair {d}`"
                if _bag_files(d) else "")
        raise MechsimError(f"bag {d}: no {METADATA_FILE} (not a rosbag2 bag{hint})")
    try:
        meta = yaml.safe_load(f.read_text())["rosbag2_bagfile_information"]
        for key in ("relative_file_paths", "topics_with_message_count", "storage_identifier"):
            meta[key]  # noqa: B018 - presence check
    except (OSError, yaml.YAMLError, KeyError, TypeError) as e:
        raise MechsimError(f"bag {d}: {METADATA_FILE} is not valid rosbag2 metadata "
                           f"({type(e).__name__})") from None
    if meta["storage_identifier"] != STORAGE_ID:
        raise MechsimError(f"bag {d}: storage {meta['storage_identifier']!r} is not supported "
                           "(only mcap)")
    for rel in meta["relative_file_paths"]:
        if not (d / Path(rel).name).is_file():
            raise MechsimError(f"bag {d}: storage file {Path(rel).name} missing")
    return dict(meta)


def topic_qos(meta: dict[str, Any]) -> dict[str, tuple[str, list[dict[str, Any]], int]]:
    """topic -> (type, offered_qos_profiles entries, message count) from bag metadata."""
    out = {}
    for t in meta["topics_with_message_count"]:
        tm = t["topic_metadata"]
        q = tm.get("offered_qos_profiles") or []
        if isinstance(q, str):
            q = yaml.safe_load(q) or []
        out[tm["name"]] = (tm["type"], list(q), int(t.get("message_count", 0)))
    return out


def _corrupt(d: Path, f: Path, e: Exception) -> MechsimError:
    detail = str(e).splitlines()[0] if str(e) else ""
    return MechsimError(f"bag {d}: {f.name} is corrupt or truncated ({type(e).__name__}"
                        f"{': ' + detail if detail else ''}); try `mechsim bag repair {d}`")


def check_bag(path: str | Path) -> dict[str, Any]:
    """Metadata of a bag whose storage files open with a summary (MechsimError otherwise)."""
    from mcap.reader import make_reader

    d = Path(path)
    meta = read_metadata(d)
    for rel in meta["relative_file_paths"]:
        f = d / Path(rel).name
        try:
            with open(f, "rb") as stream:
                if make_reader(stream).get_summary() is None:
                    raise ValueError("no summary section")
        except Exception as e:  # noqa: BLE001 - whatever the parser throws, the file is bad
            raise _corrupt(d, f, e) from None
    return meta


def read_messages(path: str | Path, topics: list[str] | None = None) -> Iterator[BagMessage]:
    """Messages of a bag in file (= recording) order; MechsimError on a corrupt file."""
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    d = Path(path)
    meta = read_metadata(d)
    wanted = set(topics) if topics else None
    for rel in meta["relative_file_paths"]:
        f = d / Path(rel).name
        try:
            with open(f, "rb") as stream:
                reader = make_reader(stream)
                for schema, channel, message in reader.iter_messages(
                        topics=list(wanted) if wanted else None, log_time_order=False):
                    yield BagMessage(channel.topic, schema.name if schema else "",
                                     message.log_time, message.data)
        except (McapError, OSError, ValueError, EOFError, AssertionError, KeyError,
                struct.error) as e:  # struct.error: a record cut short
            raise _corrupt(d, f, e) from None


# --- repair -----------------------------------------------------------------------------------
@dataclass
class RepairResult:
    path: Path
    messages: int
    topics: int
    complete: bool  # the file had its footer: nothing was lost


def _scan(f: Path) -> tuple[list[Any], dict[str, str], bool, str]:
    """Readable records of a (possibly truncated) MCAP file: (records, rosbag2 metadata,
    footer seen, library)."""
    from mcap.exceptions import McapError
    from mcap.records import Channel, Footer, Header, Message, Metadata, Schema
    from mcap.stream_reader import StreamReader

    records: list[Any] = []
    rosbag2: dict[str, str] = {}
    complete = False
    library = ""
    with open(f, "rb") as stream:
        if stream.read(8) != b"\x89MCAP0\r\n":
            raise ValueError("no MCAP magic")
        stream.seek(0)
        reader = StreamReader(stream, validate_crcs=True)
        try:
            for rec in reader.records:
                if isinstance(rec, Header):
                    library = rec.library
                elif isinstance(rec, Schema | Channel | Message):
                    records.append(rec)
                elif isinstance(rec, Metadata) and rec.name == "rosbag2":
                    rosbag2 = dict(rec.metadata)
                elif isinstance(rec, Footer):
                    complete = True
        except (McapError, OSError, ValueError, EOFError, AssertionError, KeyError):
            pass
    return records, rosbag2, complete, library


def _system_info_from(data: bytes) -> dict[str, str]:
    try:
        from rclpy.serialization import deserialize_message

        return system_info_custom(deserialize_message(data, message_class(SYSTEM_INFO)))
    except Exception:  # noqa: BLE001 - no rclpy or a bad message: the description is optional
        return {}


def repair_bag(path: str | Path) -> RepairResult:
    """Make an interrupted (or any) bag complete: rewrite its MCAP from the readable records
    (footer, summary and indexes), then write metadata.yaml."""
    from mcap.records import Channel, Message, Schema
    from mcap.writer import CompressionType, Writer

    d = Path(path)
    if not d.is_dir():
        raise MechsimError(f"bag {d}: no such directory")
    files = _bag_files(d)
    if len(files) != 1:
        raise MechsimError(f"bag {d}: expected one storage file <name>_0.mcap "
                           f"(found {len(files)})")
    src = files[0]
    try:
        records, rosbag2, complete, library = _scan(src)
    except OSError as e:
        raise MechsimError(f"bag {d}: cannot read {src.name} ({e.strerror or e})") from None
    except Exception as e:  # noqa: BLE001 - anything the parser throws means "not MCAP"
        raise MechsimError(f"bag {d}: {src.name} is not an MCAP file ({type(e).__name__})") \
            from None
    custom: dict[str, str] = {}
    if "serialized_metadata" in rosbag2:
        try:
            custom = dict(yaml.safe_load(rosbag2["serialized_metadata"]).get("custom_data")
                          or {})
        except (yaml.YAMLError, AttributeError, TypeError, ValueError):
            custom = {}
    stats = BagStats(custom_data={str(k): str(v) for k, v in custom.items()})
    tmp = d / f".{src.name}.repair"
    schemas: dict[int, Schema] = {}
    chan_map: dict[int, int] = {}
    chan_topic: dict[int, str] = {}
    try:
        with open(tmp, "wb") as out:
            w = Writer(out, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD)
            w.start(profile=PROFILE, library=library or "mechsim bag repair")
            schema_map: dict[int, int] = {}
            for rec in records:
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec
                elif isinstance(rec, Channel) and rec.id not in chan_map:
                    s = schemas.get(rec.schema_id)
                    if s is None:
                        continue
                    if s.id not in schema_map:
                        schema_map[s.id] = w.register_schema(s.name, s.encoding, s.data)
                    chan_map[rec.id] = w.register_channel(rec.topic, rec.message_encoding,
                                                          schema_map[s.id], dict(rec.metadata))
                    chan_topic[rec.id] = rec.topic
                    q = yaml.safe_load(rec.metadata.get("offered_qos_profiles", "") or "[]")
                    stats.topics.setdefault(rec.topic, TopicInfo(
                        rec.topic, s.name, list(q or []), rec.metadata.get("topic_type_hash", "")))
                elif isinstance(rec, Message) and rec.channel_id in chan_map:
                    topic = chan_topic[rec.channel_id]
                    if stats.topics[topic].type == SYSTEM_INFO:
                        stats.custom_data.update(_system_info_from(rec.data))
                    w.add_message(chan_map[rec.channel_id], log_time=rec.log_time,
                                  data=rec.data, publish_time=rec.publish_time,
                                  sequence=rec.sequence)
                    stats.add(chan_topic[rec.channel_id], rec.log_time)
            meta = bag_metadata(stats, src.name)
            w.add_metadata("rosbag2", {"serialized_metadata": dump_yaml(meta)})
            w.finish()
            out.flush()
            os.fsync(out.fileno())
        os.replace(tmp, src)
        _write_metadata_yaml(d, meta)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        raise MechsimError(f"bag {d}: cannot write ({e.strerror or e})") from None
    return RepairResult(d, stats.message_count, len(stats.topics), complete)


def describe(meta: dict[str, Any]) -> str:
    """``ros2 bag info``-like text of bag metadata."""
    dur = meta["duration"]["nanoseconds"] / 1e9
    start = meta["starting_time"]["nanoseconds_since_epoch"] / 1e9
    lines = [f"Files:             {', '.join(meta['relative_file_paths'])}",
             f"Storage id:        {meta['storage_identifier']}",
             f"ROS Distro:        {meta.get('ros_distro', '')}",
             f"Duration:          {dur:.9f}s",
             f"Start:             {start:.9f} (sim time + offset)",
             f"Messages:          {meta['message_count']}",
             "Topic information:"]
    for t in meta["topics_with_message_count"]:
        tm = t["topic_metadata"]
        lines.append(f"  Topic: {tm['name']} | Type: {tm['type']} | Count: {t['message_count']} "
                     f"| Serialization Format: {tm['serialization_format']}")
    custom = meta.get("custom_data") or {}
    if custom:
        lines.append("Custom data:")
        lines += [f"  {k}: {v!r}" if "\n" in str(v) else f"  {k}: {v}"
                  for k, v in custom.items()]
    return "\n".join(lines)
