"""QoS in bags: rclpy profiles to ``offered_qos_profiles`` entries and back (ROS_CONVENTIONS §4).

An entry is the version-9 mapping (string enums, infinite durations as
``{sec: 9223372036, nsec: 854775807}``). rosbags converts these only inside its own writer and
reader (no public function takes an rclpy profile or returns one), so the two small mappings
are here.
"""

from __future__ import annotations

from typing import Any

#: Infinite rmw durations as rosbag2 writes them.
INFINITE = (9223372036, 854775807)
#: Most messages a replayed transient-local topic keeps for late joiners.
MAX_LATCHED = 100


def _duration(d: Any) -> dict[str, int]:
    ns = int(getattr(d, "nanoseconds", 0) or 0)
    if ns <= 0 or ns >= INFINITE[0] * 1_000_000_000:
        return {"sec": INFINITE[0], "nsec": INFINITE[1]}
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def qos_dict(qos: Any) -> dict[str, Any]:
    """One entry of ``offered_qos_profiles`` for an rclpy QoSProfile (a fresh dict)."""
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


def _policy(entry: dict[str, Any], key: str, string: str, number: int) -> bool:
    """Does ``entry[key]`` name this policy (v9 string enum, or v8 and older integer)?"""
    value = entry.get(key)
    if isinstance(value, str):
        return value.lower() == string
    return isinstance(value, int) and not isinstance(value, bool) and value == number


def qos_profile(entries: list[dict[str, Any]], latched_messages: int = 1) -> Any:
    """The rclpy QoSProfile to republish with, from a topic's ``offered_qos_profiles``.
    A transient-local topic keeps up to ``latched_messages`` (at most 100) for late joiners:
    in the recording several publishers (one per system on /tf_static) each kept theirs."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    e = entries[0] if entries and isinstance(entries[0], dict) else {}
    latched = _policy(e, "durability", "transient_local", 1)
    durability = DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE
    reliability = (ReliabilityPolicy.BEST_EFFORT if _policy(e, "reliability", "best_effort", 2)
                   else ReliabilityPolicy.RELIABLE)
    depth = e.get("depth")
    depth = depth if isinstance(depth, int) and not isinstance(depth, bool) else 0
    depth = min(max(depth, 0), 10_000) or (1 if latched else 10)
    if latched:
        depth = max(depth, min(int(latched_messages), MAX_LATCHED))
    return QoSProfile(depth=depth, history=HistoryPolicy.KEEP_LAST, reliability=reliability,
                      durability=durability)
