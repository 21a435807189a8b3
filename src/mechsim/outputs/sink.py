"""The sink protocol: what receives every message a node sends (the bag recorder, the Rerun
logger, the in-process diagnostics feed)."""

from __future__ import annotations

from typing import Any, Protocol


class Sink(Protocol):
    """Receives every message an outlet sends: ``write(topic, type_name, msg, qos, ns)``.

    A sink may also define ``wants(topic) -> bool``; without it, it wants every topic (a
    recorder). Outputs nobody wants are not computed."""

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None: ...
