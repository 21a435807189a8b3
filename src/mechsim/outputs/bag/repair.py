"""``mechsim bag repair``: complete an interrupted bag and salvage what a damaged one holds.

The MCAP file is walked record by record by the bounded reader (``mcapread.walk``: each record
is ``opcode``, ``length``, content, so one bad record does not hide the ones after it; every
size it declares is checked against the reader's limits before anything is allocated), and a
chunk that breaks a bound, does not decompress or fails its CRC is skipped alone: the intact
chunks around it are kept. The walk stops where the framing itself ends (a file cut by a kill,
a length past the end of the file). The readable schemas, channels and messages are streamed,
a chunk at a time, into a new MCAP (footer, summary, indexes) through an exclusive temporary
renamed over the original, then ``metadata.yaml`` is written the same way. If chunks had to be
skipped, the original file is kept beside the bag's as ``<name>.damaged``.

A bag being recorded is refused (its lock is live); a stale lock (its recorder is gone) is
replaced by the repair's own for the time of the repair.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from mechsim.errors import MechsimError
from mechsim.files import atomic_file, load_yaml, open_regular, write_atomic
from mechsim.outputs.bag.lock import BagLock
from mechsim.outputs.bag.mcapread import (
    BadMcap,
    Channel,
    Header,
    McapFile,
    Message,
    Metadata,
    Salvage,
    Schema,
    walk,
)
from mechsim.outputs.bag.metadata import (
    METADATA_FILE,
    SYSTEM_INFO,
    BagStats,
    TopicInfo,
    bag_metadata,
    dump_yaml,
    metadata_text,
    system_info_custom,
)
from mechsim.outputs.bag.reader import bag_dir, bag_files
from mechsim.outputs.bag.writer import CHUNK_SIZE, PROFILE
from mechsim.outputs.wire import message_class

_YAML_LIMIT = 1024 * 1024


@dataclass
class RepairResult:
    path: Path
    messages: int
    topics: int
    complete: bool  # the file had its footer and every chunk was readable: nothing was lost
    lost_chunks: int = 0
    damaged: Path | None = None  # the original file, kept when chunks were lost
    #: Why the first chunk was skipped, and where the file's framing ended early ("" if not).
    lost_reason: str = ""
    cut: str = ""


def _system_info_from(data: bytes) -> dict[str, str]:
    try:
        from rclpy.serialization import deserialize_message

        return system_info_custom(deserialize_message(data, message_class(SYSTEM_INFO)))
    except Exception:  # noqa: BLE001 - no rclpy or a bad message: the description is optional
        return {}


def _custom_data(rosbag2: dict[str, str]) -> dict[str, str]:
    """``custom_data`` of the MCAP's rosbag2 metadata record (scalars only; {} if unusable)."""
    try:
        meta = load_yaml(rosbag2.get("serialized_metadata", ""), "rosbag2 metadata",
                         _YAML_LIMIT)
    except MechsimError:
        return {}
    custom = meta.get("custom_data") if isinstance(meta, dict) else None
    if not isinstance(custom, dict):
        return {}
    scalar = (str, int, float, bool)
    return {str(k): str(v) for k, v in custom.items()
            if isinstance(k, scalar) and isinstance(v, scalar)}


def _qos(text: str) -> list[dict[str, Any]]:
    try:
        q = load_yaml(text or "[]", "offered_qos_profiles", _YAML_LIMIT)
    except MechsimError:
        return []
    return [e for e in q if isinstance(e, dict)] if isinstance(q, list) else []


def _rewrite(out: IO[bytes], f: McapFile, salvage: Salvage, stats: BagStats,
             file_name: str) -> dict[str, Any]:
    """Write the readable records of ``f`` (``mcapread.walk``, one chunk in memory at a time)
    into a new MCAP on ``out``; the bag's metadata from them."""
    from mcap.writer import CompressionType, Writer

    w = Writer(out, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD)
    started = False
    schemas: dict[int, Schema] = {}
    schema_map: dict[int, int] = {}
    chan_map: dict[int, int] = {}
    chan_topic: dict[int, str] = {}
    rosbag2: dict[str, str] = {}
    info: dict[str, str] = {}  # custom_data from the SystemInfo messages
    for rec in walk(f, salvage):
        if isinstance(rec, Header):
            if not started:
                w.start(profile=PROFILE, library=rec.library or "mechsim bag repair")
                started = True
            continue
        if not started:
            w.start(profile=PROFILE, library="mechsim bag repair")
            started = True
        if isinstance(rec, Metadata):
            if rec.name == "rosbag2":
                rosbag2 = rec.metadata
        elif isinstance(rec, Schema):
            schemas.setdefault(rec.id, rec)
        elif isinstance(rec, Channel) and rec.id not in chan_map:
            sc = schemas.get(rec.schema_id)
            if sc is None:
                continue
            if sc.id not in schema_map:
                schema_map[sc.id] = w.register_schema(sc.name, sc.encoding, sc.data)
            chan_map[rec.id] = w.register_channel(rec.topic, rec.message_encoding,
                                                  schema_map[sc.id], dict(rec.metadata))
            chan_topic[rec.id] = rec.topic
            stats.topics.setdefault(rec.topic, TopicInfo(
                rec.topic, sc.name, _qos(rec.metadata.get("offered_qos_profiles", "")),
                rec.metadata.get("topic_type_hash", "")))
        elif isinstance(rec, Message) and rec.channel_id in chan_map:
            topic = chan_topic[rec.channel_id]
            if stats.topics[topic].type == SYSTEM_INFO:
                info.update(_system_info_from(rec.data))
            w.add_message(chan_map[rec.channel_id], log_time=rec.log_time, data=rec.data,
                          publish_time=rec.publish_time, sequence=rec.sequence)
            stats.add(topic, rec.log_time)
    if not started:
        w.start(profile=PROFILE, library="mechsim bag repair")
    stats.custom_data.update({**_custom_data(rosbag2), **info})
    meta = bag_metadata(stats, file_name)
    w.add_metadata("rosbag2", {"serialized_metadata": dump_yaml(meta)})
    w.finish()
    return meta


def _keep_damaged(src: Path) -> Path:
    """Hard-link the original file under a new name ``<name>.damaged[.N]`` (no overwrite)."""
    for n in range(100):
        target = src.with_name(f"{src.name}.damaged" + (f".{n}" if n else ""))
        try:
            os.link(src, target)
            return target
        except FileExistsError:
            continue
    raise FileExistsError(f"{src}.damaged.*: too many")


def repair_bag(path: str | Path) -> RepairResult:
    """Make an interrupted or damaged bag complete: rewrite its MCAP from the readable records
    (footer, summary and indexes), then write metadata.yaml. Memory stays within the bounded
    reader's limits (``mcapread``) whatever the file declares."""
    d = bag_dir(path)
    files = bag_files(d)
    if len(files) != 1:
        raise MechsimError(f"bag {d}: expected one storage file <name>_0.mcap "
                           f"(found {len(files)})")
    src = files[0]
    with BagLock.acquire(d, "repair", break_stale=True):
        salvage = Salvage()
        stats = BagStats()
        damaged = None
        replaced = False
        try:
            with open_regular(src) as stream, atomic_file(src) as out:
                f = McapFile(stream, os.fstat(stream.fileno()).st_size)
                try:
                    f.check_magic()
                except BadMcap:
                    raise MechsimError(f"bag {d}: {src.name} is not an MCAP file (no "
                                       "magic)") from None
                meta = _rewrite(out, f, salvage, stats, src.name)
                if salvage.lost_chunks:
                    damaged = _keep_damaged(src)
            replaced = True
            write_atomic(d / METADATA_FILE, metadata_text(meta))
        except OSError as e:
            if damaged is not None and not replaced:  # the original is still in place
                with contextlib.suppress(OSError):
                    damaged.unlink()
            raise MechsimError(f"bag {d}: cannot write ({e.strerror or e})") from None
    return RepairResult(d, stats.message_count, len(stats.topics),
                        salvage.footer and not salvage.lost_chunks, salvage.lost_chunks,
                        damaged, salvage.lost_reason, salvage.cut)
