"""rosbag2 metadata: what a bag holds, written as ``metadata.yaml`` and read back checked.

Writing. :func:`dump_yaml` writes every string that is not a plain identifier-like word in
double quotes, with control characters and line breaks escaped, so text from outside
(``custom_data`` from a scene, a remote ``system_info``, an MCAP being repaired) stays one quoted
scalar on one line: it cannot add keys or lines to the file. ``metadata.yaml`` is written with
:func:`mechsim.files.write_atomic`.

Reading. :func:`parse_metadata` takes the file's bytes (size-bounded, UTF-8, YAML without
aliases: :func:`mechsim.files.load_yaml`) and checks every field mechsim uses, so a malformed
file is one line naming the field (``topics_with_message_count[2].topic_metadata.name: expected
a string (got int)``), never a traceback later.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from mechsim.errors import MechsimError
from mechsim.files import load_yaml

ROSBAG2_VERSION = 9
STORAGE_ID = "mcap"
SERIALIZATION = "cdr"
ROS_DISTRO = "kilted"
METADATA_FILE = "metadata.yaml"
ROOT_KEY = "rosbag2_bagfile_information"
SYSTEM_INFO = "mechsim_msgs/msg/SystemInfo"
_PLAIN = re.compile(r"[A-Za-z0-9_./-]+")


# --- what a bag holds ---------------------------------------------------------------------------
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

    def add(self, topic: str, ns: int, count: int = 1, last_ns: int | None = None) -> None:
        """``count`` messages of ``topic`` stamped from ``ns`` to ``last_ns`` (default ``ns``)."""
        last = ns if last_ns is None else last_ns
        self.topics[topic].count += count
        self.start_ns = ns if self.start_ns is None else min(self.start_ns, ns)
        self.end_ns = last if self.end_ns is None else max(self.end_ns, last)


def system_info_custom(info: Any) -> dict[str, str]:
    """``custom_data`` entries describing one system instance, from its SystemInfo message."""
    p = f"mechsim.{info.instance}."
    return {p + "system": info.system, p + "formulation": info.formulation,
            p + "parameters": info.parameters_yaml, p + "integrator": info.integrator,
            p + "tolerance": repr(info.tolerance), p + "laws": ",".join(info.laws),
            p + "version": info.mechsim_version}


def storage_file_name(directory: Path) -> str:
    """``<dir>_0.mcap``, the one storage file of a bag (rosbag2's naming)."""
    return f"{directory.resolve().name}_0.mcap"


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


# --- writing ------------------------------------------------------------------------------------
class _Dumper(yaml.SafeDumper):
    """yaml-cpp look (block style, indented sequences, no anchors); strings other than plain
    words double-quoted with escapes, so no text from outside spans lines."""

    def ignore_aliases(self, data: Any) -> bool:
        return True

    def increase_indent(self, flow: bool = False, indentless: bool = False) -> None:
        super().increase_indent(flow, False)


def _represent_str(dumper: yaml.SafeDumper, text: str) -> yaml.ScalarNode:
    style = None if _PLAIN.fullmatch(text) else '"'
    return dumper.represent_scalar("tag:yaml.org,2002:str", text, style=style)


_Dumper.add_representer(str, _represent_str)


def dump_yaml(data: Any) -> str:
    return yaml.dump(data, Dumper=_Dumper, sort_keys=False, default_flow_style=False,
                     allow_unicode=True, width=1 << 20)


def metadata_text(meta: dict[str, Any], dumped: str | None = None) -> str:
    """The text of ``metadata.yaml`` for BagMetadata ``meta``; ``dumped``: ``dump_yaml(meta)``
    if already made (the MCAP file holds it), then indented under the root key instead of
    dumped again (block style, every scalar on one line: the same text)."""
    if dumped is None:
        return dump_yaml({ROOT_KEY: meta})
    return f"{ROOT_KEY}:\n" + "".join(f"  {line}" for line in dumped.splitlines(True))


# --- reading ------------------------------------------------------------------------------------
_KIND_NAMES = {dict: "a mapping", list: "a list", str: "a string", int: "an integer"}


def _is(value: Any, kind: type) -> bool:
    if kind is int:
        return isinstance(value, int) and not isinstance(value, bool)
    return isinstance(value, kind)


class _Fields:
    """Typed access to one mapping of the metadata; errors name the field's full path."""

    def __init__(self, data: Any, where: str, what: str) -> None:
        if not isinstance(data, dict):
            raise MechsimError(f"{what}: {where or 'the document'}: expected a mapping "
                               f"(got {_type_name(data)})")
        self.data, self.where, self.what = data, where, what

    def path(self, key: str | int) -> str:
        if isinstance(key, int):
            return f"{self.where}[{key}]"
        return f"{self.where}.{key}" if self.where else key

    def fail(self, key: str | int, reason: str) -> MechsimError:
        return MechsimError(f"{self.what}: {self.path(key)}: {reason}")

    def get(self, key: str, kind: type, default: Any = ..., *, none_ok: bool = False) -> Any:
        if key not in self.data:
            if default is ...:
                raise self.fail(key, "missing")
            return default
        value = self.data[key]
        if value is None and none_ok:
            return default if default is not ... else None
        if not _is(value, kind):
            raise self.fail(key, f"expected {_KIND_NAMES[kind]} (got {_type_name(value)})")
        return value

    def sub(self, key: str, default: Any = ...) -> _Fields:
        return _Fields(self.get(key, dict, default), self.path(key), self.what)


def _type_name(value: Any) -> str:
    return "nothing" if value is None else type(value).__name__


def _count(f: _Fields, key: str, default: Any = 0) -> int:
    value = int(f.get(key, int, default))
    if value < 0:
        raise f.fail(key, f"must be >= 0 (got {value})")
    return value


def _file_name(f: _Fields, index: int, rel: Any) -> str:
    if not isinstance(rel, str):
        raise f.fail(index, f"expected a string (got {_type_name(rel)})")
    name = Path(rel).name if "\x00" not in rel else ""
    if name in ("", ".", ".."):
        raise f.fail(index, f"{rel!r} is not a file name")
    return name


def parse_metadata(raw: bytes | str, what: str) -> dict[str, Any]:
    """Checked BagMetadata from the text of a ``metadata.yaml`` (MechsimError naming ``what``
    and the field otherwise). Optional fields get rosbag2's defaults; file names are reduced
    to their last component (a bag never reads outside its directory)."""
    top = _Fields(load_yaml(raw, what), "", what)
    m = top.sub(ROOT_KEY)
    # The fields rosbag2 itself requires of every version (rosbag2_storage's YAML decoder):
    # a document with fewer is not a bag's metadata, whatever else it holds.
    out: dict[str, Any] = {
        "version": m.get("version", int),
        "storage_identifier": m.get("storage_identifier", str),
        "duration": {"nanoseconds": _count(m.sub("duration"), "nanoseconds", ...)},
        "starting_time": {"nanoseconds_since_epoch": _count(
            m.sub("starting_time"), "nanoseconds_since_epoch", ...)},
    }
    rels = m.get("relative_file_paths", list)
    if not rels:
        raise m.fail("relative_file_paths", "empty (a bag has at least one storage file)")
    files = _Fields({}, m.path("relative_file_paths"), what)
    topics = []
    raw_topics = m.get("topics_with_message_count", list)
    for i, entry in enumerate(raw_topics):
        t = _Fields(entry, f"{m.path('topics_with_message_count')}[{i}]", what)
        tm = t.sub("topic_metadata")
        qos = tm.get("offered_qos_profiles", object, [], none_ok=True)
        if isinstance(qos, str):
            qos = load_yaml(qos, f"{what}: {tm.path('offered_qos_profiles')}") or []
        if not isinstance(qos, list):
            raise tm.fail("offered_qos_profiles", f"expected a list (got {_type_name(qos)})")
        topics.append({
            "topic_metadata": {
                "name": tm.get("name", str), "type": tm.get("type", str),
                "serialization_format": tm.get("serialization_format", str, SERIALIZATION),
                "offered_qos_profiles": [q for q in qos if isinstance(q, dict)],
                "type_description_hash": tm.get("type_description_hash", str, ""),
            },
            "message_count": _count(t, "message_count"),
        })
    out["message_count"] = _count(m, "message_count", ...)
    out["topics_with_message_count"] = topics
    out["compression_format"] = m.get("compression_format", str, "", none_ok=True)
    out["compression_mode"] = m.get("compression_mode", str, "", none_ok=True)
    if out["compression_mode"] or out["compression_format"]:
        raise m.fail("compression_mode", f"compressed bags ({out['compression_mode']} "
                     f"{out['compression_format']}) are not supported")
    out["relative_file_paths"] = [_file_name(files, i, r) for i, r in enumerate(rels)]
    custom = m.get("custom_data", dict, {}, none_ok=True)
    c = _Fields(custom, m.path("custom_data"), what)
    for key in custom:
        if not isinstance(key, str):
            raise c.fail(str(key), f"key: expected a string (got {_type_name(key)})")
        c.get(key, str)
    out["custom_data"] = dict(custom) or None
    out["ros_distro"] = m.get("ros_distro", str, "", none_ok=True)
    return out


def topic_qos(meta: dict[str, Any]) -> dict[str, tuple[str, list[dict[str, Any]], int]]:
    """topic -> (type, offered_qos_profiles entries, message count) from checked metadata."""
    out = {}
    for t in meta["topics_with_message_count"]:
        tm = t["topic_metadata"]
        out[tm["name"]] = (tm["type"], list(tm["offered_qos_profiles"]),
                           int(t["message_count"]))
    return out
