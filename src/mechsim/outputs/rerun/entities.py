"""Names the Rerun modules share: the timeline, the energy terms, entity paths, stamps."""

from __future__ import annotations

import functools
from typing import Any

TIMELINE = "sim_time"
ENERGY_TERMS = ("kinetic", "potential", "total", "energy_function", "work_external",
                "work_dissipated")


def stamp_ns(stamp: Any) -> int:
    """A builtin_interfaces/Time in nanoseconds."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _part(name: str) -> str:
    import rerun as rr

    return str(rr.escape_entity_path_part(name))


@functools.lru_cache(maxsize=65536)
def path(*names: str) -> str:
    """An entity path from plain names, each '/'-separated name split into parts."""
    return "/".join(_part(p) for n in names for p in n.split("/") if p)
