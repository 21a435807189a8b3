"""The bag writer: a sink taking CDR bytes (``mechsim.outputs.sink``) recording every message
into a new bag.

Files. The bag directory is claimed exclusively: created with ``mkdir`` (or, if it exists and is
empty, claimed by creating its lock), then locked for the whole recording (see ``lock``) with
the recorder's PID, so ``repair``, ``convert``, ``replay`` and ``bag info`` leave it alone. The
MCAP file is created with ``O_EXCL|O_NOFOLLOW``; ``metadata.yaml`` is written last, through an
exclusive temporary renamed into place; then the lock is removed.

Robustness. Records are written by a writer thread (Python runs signal handlers in the main
thread only, so Ctrl-C / SIGTERM can never interrupt a half-written record); the sink only
serializes and queues (a chunk of samples, already encoded by the nodes, is one item: see
``mcapfile``). A chunk is closed and flushed to the file when it passes ``CHUNK_SIZE`` and at
least every second of wall time (``McapFile.flush``), so after a hard kill every chunk but
the last is in the file and ``mechsim bag repair`` completes the bag. Memory stays flat however
long the recording: the queue is bounded, and the chunk indexes the summary needs wait in an
anonymous file inside the bag directory (``mcapfile.Spill``).

A recording is never deleted after its first message: :meth:`BagWriter.abort` (after an error
anywhere) completes the bag if the writer is healthy; after a write error (disk full, ...) the
file keeps every chunk that reached the disk and the error says to repair it. Only a bag that
holds no message is removed.
"""

from __future__ import annotations

import contextlib
import os
import queue
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from mechsim.errors import MechsimError
from mechsim.files import make_dir, open_exclusive, write_atomic
from mechsim.outputs.bag.lock import LOCK_FILE, BagLock
from mechsim.outputs.bag.mcapfile import McapFile
from mechsim.outputs.bag.metadata import (
    METADATA_FILE,
    SERIALIZATION,
    SYSTEM_INFO,
    BagStats,
    TopicInfo,
    bag_metadata,
    dump_yaml,
    metadata_text,
    storage_file_name,
    system_info_custom,
)
from mechsim.outputs.bag.qos import qos_dict
from mechsim.outputs.sink import Capabilities, Takes
from mechsim.outputs.wire import message_definition, type_description_hash, typestore_with

PROFILE = "ros2"
SCHEMA_ENCODING = "ros2msg"
#: A chunk is closed at least this often [s of wall time], and when it passes ``CHUNK_SIZE``
#: bytes. (Not by simulation time: a fast run would close a small chunk for every second it
#: simulates, many a second, and the writer, compressing and indexing each, would
#: hold the simulation back.)
FLUSH_WALL_S = 1.0
CHUNK_SIZE = 512 * 1024
#: Items (a message, or a chunk of samples on several topics) queued for the writer thread at
#: most; a producer faster than the disk waits (memory stays bounded however long the run).
QUEUE_ITEMS = 64
#: Single messages (a /diagnostics report each second of a fast run) are handed over
#: together, with whatever is queued next, when this many are held or the first of them was
#: held this long [s] (one hand-off, one wake-up of the writer thread, instead of each).
HELD_MESSAGES = 32
HELD_WALL_S = 0.05
_STOP = object()


def expand_path(path: str | Path) -> Path:
    """``~`` and strftime fields (``runs/default_%Y%m%d-%H%M%S``) expanded."""
    text = os.path.expanduser(str(path))
    return Path(time.strftime(text) if "%" in text else text)


def claim_bag_dir(path: str | Path) -> tuple[Path, BagLock, bool]:
    """Create (or claim an empty) bag directory and lock it for recording: (directory, lock,
    created). MechsimError naming the path if it exists with content, is being recorded, or
    cannot be written."""
    d = expand_path(path)
    if "\x00" in str(d):
        raise MechsimError(f"bag {d!r}: the path contains a NUL byte")
    try:
        created = make_dir(d)
    except MechsimError as e:
        raise MechsimError(f"bag {e}") from None
    except OSError as e:
        raise MechsimError(f"bag {d}: cannot create ({e.strerror or e})") from None
    not_empty = MechsimError(f"bag {d}: directory exists and is not empty (choose a new path)")
    try:
        if not created and any(d.iterdir()):
            raise not_empty
        lock = BagLock.acquire(d, "recording", break_stale=False)
    except OSError as e:
        _remove_dir(d, created)
        raise MechsimError(f"bag {d}: cannot write ({e.strerror or e})") from None
    try:
        others = any(p.name != LOCK_FILE for p in d.iterdir())  # appeared before the lock?
    except OSError:
        others = True
    if others:
        lock.release()
        raise not_empty
    return d, lock, created


def _remove_dir(d: Path, created: bool) -> None:
    if created:
        with contextlib.suppress(OSError):
            d.rmdir()


class BagWriter:
    """Sink writing every message, as CDR bytes, into a new rosbag2 MCAP bag (a context
    manager).

    ``BagWriter(path)`` claims the directory (new or empty; MechsimError otherwise) and locks
    it; :meth:`close` finishes the MCAP, writes ``metadata.yaml`` and unlocks; :meth:`abort`
    stops after an error elsewhere, keeping what was recorded (see the module docstring). A
    write error (a MechsimError naming the bag) is raised by the next :meth:`write_bytes` or
    :meth:`write_rows` and by :meth:`close`.
    """

    capabilities = Capabilities(Takes.BYTES)

    def __init__(self, path: str | Path, custom_data: dict[str, str] | None = None,
                 chunk_size: int = CHUNK_SIZE,
                 topics: Callable[[str], bool] | None = None) -> None:
        """``topics``: which topics the bag records, by name (None: every one)."""
        if topics is not None:
            self.capabilities = Capabilities(Takes.BYTES, wants=topics)
        self.path, self._lock, self._created = claim_bag_dir(path)
        self.file_name = storage_file_name(self.path)
        self.stats = BagStats(custom_data={k: str(v) for k, v in (custom_data or {}).items()})
        self._types: dict[str, str] = {}
        self._queue: queue.Queue[Any] = queue.Queue(maxsize=QUEUE_ITEMS)
        #: Single messages not yet queued (``write_bytes``) and when the first was held.
        self._held: list[tuple[str, int, bytes]] = []
        self._held_since = 0.0
        self.error: Exception | None = None
        #: Messages handed to the bag so far (has the recording begun?).
        self.received = 0
        self._closed = False
        self._finished = False
        self._chunk_size = chunk_size
        #: Seconds the writer thread spent writing (not waiting for work).
        self.write_seconds = 0.0
        self._thread = threading.Thread(target=self._run, name="bag-writer", daemon=False)
        try:
            self._file = open_exclusive(self.path / self.file_name)
        except OSError as e:
            self._lock.release()
            _remove_dir(self.path, self._created)
            raise MechsimError(f"bag {self.path}: cannot write ({e.strerror or e})") from None
        self._thread.start()

    # main thread: queue (never touches the file)
    def write_bytes(self, topic: str, type_name: str, qos: Any, ns: int, data: bytes) -> None:
        """One message's CDR payload (a system_info's fields also go to the bag's custom
        data)."""
        if self.error is not None:
            raise self.error
        if self._closed:
            return
        self.received += 1
        if type_name == SYSTEM_INFO:
            info = typestore_with(SYSTEM_INFO).deserialize_cdr(data, SYSTEM_INFO)
            for key, value in system_info_custom(info).items():
                self._put(("custom", key, value))
        if topic not in self._types:
            self._types[topic] = type_name
            self._put(("channel", topic, type_name, qos_dict(qos)))
        held = self._held
        if not held:
            self._held_since = time.monotonic()
        held.append((topic, ns, data))
        if len(held) >= HELD_MESSAGES or time.monotonic() - self._held_since >= HELD_WALL_S:
            self._put_held()

    def write_rows(self, ns: np.ndarray, topics: list[tuple[str, str, Any, np.ndarray]]
                   ) -> None:
        """A chunk of N samples stamped ``ns`` (int64, in time order): for each (topic,
        type_name, qos, rows), rows is the (N, size) uint8 array of the topic's CDR payloads
        (none of them system_info). One hand-off to the writer thread for the whole chunk;
        the arrays must not be changed afterwards."""
        if self.error is not None:
            raise self.error
        if self._closed or not topics or len(ns) == 0:
            return
        self.received += len(ns) * len(topics)
        for topic, type_name, qos, _ in topics:
            if topic not in self._types:
                self._types[topic] = type_name
                self._put(("channel", topic, type_name, qos_dict(qos)))
        self._put(("chunk", ns, [(t, rows) for t, _, _, rows in topics]))

    def set_custom(self, key: str, value: Any) -> None:
        self._put(("custom", key, str(value)))

    def _put(self, item: Any) -> None:
        """Queue ``item`` for the writer thread after the single messages held before it
        (everything reaches the writer in the order it was given)."""
        if self._held:
            self._put_held()
        self._queue.put(item)

    def _put_held(self) -> None:
        held, self._held = self._held, []
        self._queue.put(("messages", held))

    def close(self) -> BagStats:
        """Finish the file, write metadata.yaml, unlock (waits for the writer thread); raises
        the write error if there was one (the recording is kept, see :meth:`abort`)."""
        self._finish(remove_empty=False)
        if self.error is not None:
            raise self.error
        return self.stats

    def abort(self) -> None:
        """Stop after an error. What was recorded is kept: completed (footer, metadata.yaml)
        if the writer is healthy, as far as it reached the disk after a write error (then
        ``mechsim bag repair`` completes it). A bag without any message is removed."""
        self._finish(remove_empty=True)

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type: Any, *exc: object) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()

    def _finish(self, *, remove_empty: bool) -> None:
        if not self._closed:
            self._closed = True
            self._put(_STOP)
        self._thread.join()
        if self._finished:
            return
        self._finished = True
        empty = remove_empty and self.stats.message_count == 0
        if empty:
            for name in (self.file_name, METADATA_FILE):
                with contextlib.suppress(OSError):
                    (self.path / name).unlink()
        self._lock.release()
        if empty:
            _remove_dir(self.path, self._created)

    # writer thread
    def _run(self) -> None:
        try:
            self._write_loop()
        except Exception as e:  # noqa: BLE001 - handed to the main thread by write()/close()
            self.error = self._describe(e)
            while self._queue.get() is not _STOP:  # drain until close()/abort()
                pass
        finally:
            try:
                self._file.close()
            except OSError as e:
                self.error = self.error or self._describe(e)

    def _describe(self, e: Exception) -> Exception:
        if not isinstance(e, OSError):
            return e
        kept = (f"; the chunks written so far are kept: `mechsim bag repair {self.path}` "
                "completes the bag" if self.stats.message_count else "; nothing was recorded")
        return MechsimError(f"bag {self.path}: write failed ({e.strerror or e}){kept}")

    def _write_loop(self) -> None:
        from mcap.writer import LIBRARY_IDENTIFIER

        from mechsim import __version__

        w = McapFile(self._file, chunk_size=self._chunk_size, scratch=self.path)
        w.start(profile=PROFILE, library=f"mechsim {__version__}; {LIBRARY_IDENTIFIER}")
        w.add_metadata("rosbag2", {"serialized_metadata": dump_yaml(
            bag_metadata(BagStats(custom_data=dict(self.stats.custom_data)), self.file_name))})
        self._file.flush()
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._qos_yaml: dict[str, str] = {}
        self._last_flush_wall = time.monotonic()
        try:
            while True:
                item = self._queue.get()
                if item is _STOP:
                    break
                started = time.perf_counter()
                self._write_item(w, item)
                self.write_seconds += time.perf_counter() - started
            meta = bag_metadata(self.stats, self.file_name)
            dumped = dump_yaml(meta)
            w.add_metadata("rosbag2", {"serialized_metadata": dumped})
            w.finish()
        finally:
            w.chunk_indexes.close()
        self._file.flush()
        os.fsync(self._file.fileno())
        write_atomic(self.path / METADATA_FILE, metadata_text(meta, dumped))

    def _write_item(self, w: McapFile, item: Any) -> None:
        channels = self._channels
        if item[0] == "channel":
            _, topic, type_name, qos = item
            if type_name not in self._schemas:
                self._schemas[type_name] = w.register_schema(
                    type_name, SCHEMA_ENCODING, message_definition(type_name).encode())
            h = type_description_hash(type_name)
            key = repr(qos)  # a few distinct profiles among a scene's topics: YAML once each
            offered = self._qos_yaml.get(key)
            if offered is None:
                offered = self._qos_yaml[key] = dump_yaml([qos])
            channels[topic] = w.register_channel(
                topic, SERIALIZATION, self._schemas[type_name],
                {"offered_qos_profiles": offered, "topic_type_hash": h})
            self.stats.topics[topic] = TopicInfo(topic, type_name, [qos], h)
            return
        if item[0] == "custom":
            self.stats.custom_data[item[1]] = item[2]
            return
        if item[0] == "messages":  # single messages, each as if queued alone
            for message in item[1]:
                self._write_item(w, message)
            return
        if item[0] == "chunk":
            _, ns, rows = item
            w.add_batch(ns, [(channels[topic], r) for topic, r in rows])
            first, last = int(ns[0]), int(ns[-1])
            for topic, _ in rows:
                self.stats.add(topic, first, len(ns), last)
        else:
            topic, first, data = item
            w.add_message(channels[topic], first, data)
            self.stats.add(topic, first)
        now = time.monotonic()
        if now - self._last_flush_wall >= FLUSH_WALL_S:
            w.flush()  # closes the chunk in progress and flushes the stream
            self._last_flush_wall = now
