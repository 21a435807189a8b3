"""Designs of a recording measured beside the one ``mechsim record`` uses
(``mechsim bench --streaming``): the slowest systems recorded again with each design in turn.

- ``shipped``: as recorded (each block integrated after the previous one is released; the bag
  writer's thread lays out, compresses (zstd level ``mcapfile.ZSTD_LEVEL``), checksums and
  writes the chunks).
- ``ahead``: each block's successor integrated on a thread of its own while the block is
  released (``SystemRun.integrates_ahead``).
- ``zstd_1``: chunks compressed at zstd level -1 (smaller, slower).
- ``process``: the chunks' work (layout, compression, checksum, write) in a process of its own,
  out of reach of the recording process's interpreter lock: the writer thread only hands each
  chunk of rows to it through a pipe.
- ``dropped``: every chunk of rows encoded and handed to the writer thread, then dropped (no
  layout, compression or write): the ceiling of any bag writer behind these nodes.
"""

from __future__ import annotations

import contextlib
import multiprocessing
from collections.abc import Iterator
from typing import Any

from mechsim.outputs.bag import mcapfile
from mechsim.outputs.bag.writer import CHUNK_SIZE, BagWriter

#: Design name: what the bench's table says of it.
DESIGNS = {
    "shipped": "as recorded above",
    "ahead": "next block integrated meanwhile",
    "zstd_1": "chunks at zstd level -1",
    "process": "chunks written by a process of their own",
    "dropped": "chunks dropped before the writer's work (ceiling of any bag writer)",
}


def _write_chunks(conn: Any, path: str, scratch: str) -> None:
    """The ``process`` design's child: every (stamps, [(channel, rows)]) received written as
    ``McapFile.add_batch`` writes it, to ``path``, until None."""
    with open(path, "xb") as stream:
        w = mcapfile.McapFile(stream, chunk_size=CHUNK_SIZE, scratch=scratch)
        w.start(profile="ros2", library="mechsim bench")
        while (item := conn.recv()) is not None:
            ns, rows = item
            while len(w.channels) < max(c for c, _ in rows):
                w.register_channel(f"/c{len(w.channels)}", "cdr", 0, {})
            w.add_batch(ns, rows)
        w.finish()


class _ChunksInAProcess(BagWriter):
    """A bag writer whose chunks of rows go to a child process (``_write_chunks``); closing it
    waits for the child's file to be complete."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        ctx = multiprocessing.get_context("spawn")
        self._conn, child = ctx.Pipe()
        super().__init__(*args, **kwargs)
        self._child = ctx.Process(target=_write_chunks, args=(
            child, str(self.path / "chunks.mcap"), str(self.path)), daemon=True)
        self._child.start()
        child.close()

    def _write_item(self, w: Any, item: Any) -> None:
        if item[0] == "chunk":
            _, ns, rows = item
            self._conn.send((ns, [(self._channels[topic], r) for topic, r in rows]))
            return
        super()._write_item(w, item)

    def _finish(self, *, remove_empty: bool) -> None:
        super()._finish(remove_empty=remove_empty)
        if self._child.is_alive():
            self._conn.send(None)
            self._child.join()


class _ChunksDropped(BagWriter):
    """A bag writer that drops every chunk of rows (single messages are written)."""

    def _write_item(self, w: Any, item: Any) -> None:
        if item[0] != "chunk":
            super()._write_item(w, item)


@contextlib.contextmanager
def design(name: str) -> Iterator[None]:
    """The recording made with design ``name`` (see :data:`DESIGNS`) inside the block."""
    from mechsim.outputs import bag
    from mechsim.runcore.run import SystemRun

    writer, ahead, level = bag.BagWriter, SystemRun.integrates_ahead, mcapfile.ZSTD_LEVEL
    try:
        if name == "ahead":
            SystemRun.integrates_ahead = True
        elif name == "zstd_1":
            mcapfile.ZSTD_LEVEL = -1
        elif name == "process":
            bag.BagWriter = _ChunksInAProcess  # type: ignore[misc]
        elif name == "dropped":
            bag.BagWriter = _ChunksDropped  # type: ignore[misc]
        elif name != "shipped":
            raise ValueError(f"no recording design {name!r}")
        yield
    finally:
        bag.BagWriter, SystemRun.integrates_ahead = writer, ahead  # type: ignore[misc]
        mcapfile.ZSTD_LEVEL = level
