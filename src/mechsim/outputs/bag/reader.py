"""Reading bags: checked metadata, messages in recording order, the ``bag info`` text.

Everything read is from outside: ``metadata.yaml`` is size-bounded, UTF-8, alias-free and
checked field by field (``metadata.parse_metadata``); storage files are opened only if they are
regular files and read by the bounded reader (``mcapread``: every size a file declares checked
against the reader's limits before anything is allocated for it); a bag being written (live
lock, see ``lock``) is refused; text printed from a bag has its control characters escaped
(:func:`describe`).
"""

from __future__ import annotations

import contextlib
import os
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mechsim.errors import MechsimError, one_line
from mechsim.files import open_regular, read_bounded
from mechsim.outputs.bag.lock import check_not_in_use, has_stale_lock
from mechsim.outputs.bag.mcapread import BadMcap, McapFile, iter_messages, scan, verify
from mechsim.outputs.bag.metadata import METADATA_FILE, STORAGE_ID, parse_metadata

_FILE_RE = re.compile(r".+_(\d+)\.mcap$")


@dataclass
class BagMessage:
    topic: str
    type_name: str
    log_time: int
    data: bytes


def bag_dir(path: str | Path) -> Path:
    """``path`` as a bag directory that exists (MechsimError otherwise)."""
    d = Path(path)
    if "\x00" in str(path):
        raise MechsimError(f"bag {str(path)!r}: the path contains a NUL byte")
    if not d.is_dir():
        raise MechsimError(f"bag {d}: no such directory")
    return d


def bag_files(d: Path) -> list[Path]:
    """The storage files ``<name>_<N>.mcap`` of a bag directory, by N."""
    try:
        files = [(int(m.group(1)), p) for p in d.iterdir()
                 if (m := _FILE_RE.match(p.name)) and p.is_file()]
    except OSError as e:
        raise MechsimError(f"bag {d}: cannot list ({e.strerror or e})") from None
    return [p for _, p in sorted(files)]


def read_metadata(path: str | Path) -> dict[str, Any]:
    """Checked ``rosbag2_bagfile_information`` of a bag directory (MechsimError if the bag is
    being written, or its metadata is missing, unreadable or malformed)."""
    d = bag_dir(path)
    check_not_in_use(d)
    f = d / METADATA_FILE
    if not f.exists():
        interrupted = bag_files(d) or has_stale_lock(d)
        hint = (f"; an interrupted recording? run `mechsim bag repair {d}`"
                if interrupted else "")
        raise MechsimError(f"bag {d}: no {METADATA_FILE} (not a rosbag2 bag{hint})")
    what = f"bag {d}: {METADATA_FILE}"
    try:
        raw = read_bounded(f)
    except OSError as e:
        raise MechsimError(f"{what}: cannot read ({e.strerror or e})") from None
    meta = parse_metadata(raw, what)
    if meta["storage_identifier"] != STORAGE_ID:
        raise MechsimError(f"{what}: storage_identifier: {meta['storage_identifier']!r} is not "
                           "supported (only mcap)")
    for name in meta["relative_file_paths"]:
        if not (d / name).is_file():
            raise MechsimError(f"bag {d}: storage file {name} missing")
    return meta


def _corrupt(d: Path, f: Path, e: Exception) -> MechsimError:
    if isinstance(e, BadMcap):
        detail = e.args[0]
    else:
        first = str(e).splitlines()[0] if str(e) else ""
        detail = f"{e.strerror or e}" if isinstance(e, OSError) else \
            f"{type(e).__name__}{': ' + first if first else ''}"
    return MechsimError(f"bag {d}: {f.name} is corrupt or truncated ({detail}); try "
                        f"`mechsim bag repair {d}`")


@contextlib.contextmanager
def _storage(d: Path, name: str) -> Iterator[McapFile]:
    """A storage file of the bag opened for bounded reading; any error reading it is one
    line naming the file (and the byte offset where the file is bad)."""
    f = d / name
    try:
        with open_regular(f) as stream:
            yield McapFile(stream, os.fstat(stream.fileno()).st_size)
    except (BadMcap, OSError) as e:
        raise _corrupt(d, f, e) from None


def check_storage(path: str | Path, meta: dict[str, Any]) -> None:
    """The framing of the bag's storage files and every size they declare, within the
    reader's limits (``mcapread.scan``: nothing decompressed); MechsimError otherwise."""
    d = Path(path)
    for name in meta["relative_file_paths"]:
        with _storage(d, name) as f:
            scan(f)


def check_bag(path: str | Path) -> dict[str, Any]:
    """Metadata of a bag whose storage files are complete (a summary) and readable: every
    chunk decompressed within the reader's limits, checked against its CRC and parsed
    (``mcapread.verify``, a chunk at a time); MechsimError otherwise. What reads the bag
    afterwards cannot fail on memory or on a damaged chunk."""
    d = Path(path)
    meta = read_metadata(d)
    for name in meta["relative_file_paths"]:
        with _storage(d, name) as f:
            if not verify(f).summary:
                raise _corrupt(d, d / name, ValueError("no summary section"))
    return meta


def read_messages(path: str | Path, topics: list[str] | None = None) -> Iterator[BagMessage]:
    """Messages of a bag in log-time order within each file, files in order (as ``ros2 bag
    play`` reads them: a recorder writes each node's samples in blocks, so file order
    interleaves nodes block by block); MechsimError on a corrupt file (chunk CRCs are checked:
    a damaged chunk is an error, never wrong messages). Memory stays within the bounded
    reader's limits (``mcapread``) whatever the file declares."""
    d = Path(path)
    meta = read_metadata(d)
    wanted = set(topics) if topics else None
    for name in meta["relative_file_paths"]:
        with _storage(d, name) as f:
            for schema, channel, message in iter_messages(f, wanted):
                yield BagMessage(channel.topic, schema.name if schema else "",
                                 message.log_time, message.data)


def describe(meta: dict[str, Any]) -> str:
    """``ros2 bag info``-like text of checked bag metadata; every text from the bag has its
    control characters escaped (a bag cannot drive the terminal)."""
    dur = meta["duration"]["nanoseconds"] / 1e9
    start = meta["starting_time"]["nanoseconds_since_epoch"] / 1e9
    s = one_line
    lines = [f"Files:             {s(', '.join(meta['relative_file_paths']))}",
             f"Storage id:        {s(meta['storage_identifier'])}",
             f"ROS Distro:        {s(meta.get('ros_distro') or '')}",
             f"Duration:          {dur:.9f}s",
             f"Start:             {start:.9f} (sim time + offset)",
             f"Messages:          {meta['message_count']}",
             "Topic information:"]
    for t in meta["topics_with_message_count"]:
        tm = t["topic_metadata"]
        lines.append(f"  Topic: {s(tm['name'])} | Type: {s(tm['type'])} | "
                     f"Count: {t['message_count']} | "
                     f"Serialization Format: {s(tm['serialization_format'])}")
    custom = meta.get("custom_data") or {}
    if custom:
        lines.append("Custom data:")
        lines += [f"  {s(str(k))}: {s(str(v))}" for k, v in custom.items()]
    return "\n".join(lines)
