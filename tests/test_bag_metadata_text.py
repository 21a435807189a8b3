"""metadata.yaml made from the MCAP file's own dump of the metadata (indented under the root
key) is the text a direct dump of the whole file gives, and reads back as the metadata, for
topics with QoS profiles and custom data with quotes, colons, newlines, tabs, non-ASCII text,
empty strings and YAML keywords."""

from __future__ import annotations

import yaml

from mechsim.outputs.bag.metadata import (
    ROOT_KEY,
    BagStats,
    TopicInfo,
    bag_metadata,
    dump_yaml,
    metadata_text,
)

_QOS = {"history": 1, "depth": 10, "reliability": 1, "durability": 2,
        "deadline": {"sec": 9223372036, "nsec": 854775807}, "liveliness": 1,
        "avoid_ros_namespace_conventions": False}


def _stats() -> BagStats:
    stats = BagStats(custom_data={
        "mechsim.scene": "a: b # c", "mechsim.quote": 'say "hi" \\ bye',
        "mechsim.lines": "first\nsecond\n", "mechsim.tab": "x\ty", "mechsim.text": "énergie Δ 🙂",
        "mechsim.empty": "", "mechsim.word": "null", "mechsim.yes": "yes", "mechsim.num": "1e3",
        "mechsim.p.parameters": "g: 9.81\nlength: 1.0\n"})
    for k, topic in enumerate(["/clock", "/pendulum/state", "/diagnostics", "/tf"]):
        stats.topics[topic] = TopicInfo(topic, "std_msgs/msg/String", [dict(_QOS, depth=k)],
                                        f"RIHS01_{k:064x}")
        stats.add(topic, 1_000_000_000 + k, 3 + k, 2_000_000_000 + k)
    return stats


def test_metadata_text_from_the_mcap_dump_equals_a_direct_dump() -> None:
    for stats in (_stats(), BagStats()):
        meta = bag_metadata(stats, "run_0.mcap")
        text = metadata_text(meta, dump_yaml(meta))
        assert text == metadata_text(meta)
        assert yaml.safe_load(text) == {ROOT_KEY: meta}
