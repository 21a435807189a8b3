"""The sink protocol: what receives every message a node sends (the bag recorder, the Rerun
logger, the in-process diagnostics feed)."""

from __future__ import annotations

from typing import Any, Protocol


class Sink(Protocol):
    """Receives every message an outlet sends: ``write(topic, type_name, msg, qos, ns)``.

    A sink may also define ``wants(topic) -> bool``; without it, it wants every topic (a
    recorder). Outputs nobody wants are not computed. Optional faster paths (see
    ``mechsim.ros.outlet.Outlet``), used instead of ``write`` where a sink has them:
    ``write_chunk(ns, [(topic, type_name, qos, rows)])`` a chunk of samples as CDR rows,
    ``write_columns(topic, ns, values)`` a chunk's evaluated values, for the topics that
    have them (``mechsim.outputs.messages.Columns``: state positions, energy, invariants,
    observables, /tf), messages for the others,
    ``write_bytes(topic, type_name, qos, ns, data)`` one message already encoded,
    ``write_serialized(topic, type_name, msg, qos, ns, data)`` a message with its bytes.

    A paced run hands a sink each node's samples a block at a time (those computed ahead),
    in the order they were published, not as each is published; a sink with a true
    ``immediate`` attribute (a live view) gets every sample as it is published."""

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None: ...
