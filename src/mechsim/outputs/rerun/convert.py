"""A bag converted to a Rerun recording, and the Rerun viewer of this environment."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

from mechsim.errors import MechsimError
from mechsim.outputs.rerun.sink import HANDLED_TYPES, RerunSink


def convert_bag(bag: str | Path, rrd: str | Path, *, replace: bool = False) -> dict[str, int]:
    """Feed every drawable message of a rosbag2 MCAP bag (``mechsim.outputs.bag.read_messages``,
    recording order) through a RerunSink writing ``rrd``: the same recording as a live run.
    Returns the number of messages per topic that were drawn.

    ``rrd`` appears only once the whole bag was read and the recording written; an existing
    ``rrd`` is replaced only with ``replace`` (MechsimError otherwise, before any work), and on
    any error (a corrupt bag, Ctrl-C) it is left as it was."""
    from mechsim.outputs.bag import check_bag, read_messages

    check_bag(bag)  # a clear error (unreadable, being recorded, too large) before any work
    from mechsim.environment import import_rclpy

    import_rclpy()
    from rclpy.serialization import deserialize_message

    from mechsim.outputs.wire import message_class

    if not replace and os.path.lexists(rrd):
        raise MechsimError(f"rrd {rrd}: exists (not replaced)")
    counts: dict[str, int] = {}
    classes: dict[str, Any] = {}
    sink = RerunSink(rrd, replace=replace)
    try:
        for m in read_messages(bag):
            if m.type_name not in HANDLED_TYPES:
                continue
            cls = classes.get(m.type_name)
            if cls is None:
                cls = classes[m.type_name] = message_class(m.type_name)
            try:
                msg = deserialize_message(m.data, cls)
            except Exception:  # noqa: BLE001 - rclpy raises plain exceptions on bad CDR
                raise MechsimError(f"bag {bag}: a {m.type_name} message on {m.topic} does not "
                                   "deserialize (corrupt bag)") from None
            sink.write(m.topic, m.type_name, msg, None, m.log_time)
            counts[m.topic] = counts.get(m.topic, 0) + 1
    except BaseException:
        sink.discard()
        raise
    sink.close()
    return counts


def viewer_command() -> list[str]:
    """The Rerun viewer of this environment (``rerun`` next to the interpreter)."""
    exe = Path(sys.executable).parent / "rerun"
    return [str(exe) if exe.exists() else "rerun"]
