"""The sink contract (``mechsim.outputs.sink``): a sink declares its capabilities once and the
one dispatch honours them on every path. A sink never receives a topic it does not want, on
any path of a real Outlet (publish, publish_chunk and its hand-over, publish_serialized,
record) nor of the recorder's dispatch, whatever form it takes (messages, columns, bytes);
what it wants arrives in its form, and what no sink wants is not computed."""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np
import pytest

from mechsim.environment import import_rclpy

import_rclpy()

from rclpy.node import Node  # noqa: E402
from rclpy.serialization import deserialize_message  # noqa: E402
from std_msgs.msg import Float64MultiArray, String  # noqa: E402

from mechsim.outputs.sink import Capabilities, ChunkTopic, Sinks, Takes  # noqa: E402
from mechsim.outputs.wire import encode  # noqa: E402
from mechsim.ros.outlet import STATE_QOS, Outlet  # noqa: E402

STRING = "std_msgs/msg/String"


def _keep(topic: str) -> bool:
    return topic.startswith("/keep/")


class _Sink:
    """Records every call, by method and topic."""

    def __init__(self, takes: Takes) -> None:
        self.capabilities = Capabilities(takes, wants=_keep)
        self.calls: list[tuple[str, str, Any]] = []

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        self.calls.append(("write", topic, msg))

    def write_columns(self, topic: str, ns: np.ndarray, values: Any) -> None:
        self.calls.append(("write_columns", topic, (list(ns), values)))

    def write_bytes(self, topic: str, type_name: str, qos: Any, ns: int, data: bytes) -> None:
        self.calls.append(("write_bytes", topic, data))

    def write_rows(self, ns: np.ndarray, topics: list[tuple[str, str, Any, np.ndarray]]
                   ) -> None:
        for topic, _, _, rows in topics:
            self.calls.append(("write_rows", topic, (list(ns), rows.copy())))

    def topics(self) -> set[str]:
        return {topic for _, topic, _ in self.calls}


def _sinks() -> dict[Takes, _Sink]:
    return {takes: _Sink(takes) for takes in Takes}


def test_outlet_never_hands_a_sink_a_topic_it_does_not_want(ros_context: Any) -> None:
    node = Node("sink_contract", context=ros_context)
    sinks = _sinks()
    outlet = Outlet(node, list(sinks.values()))
    try:
        for leaf in ("single", "chunk", "bytes", "input"):
            for ns in ("keep", "drop"):
                outlet.channel(f"/{ns}/{leaf}", String, STATE_QOS)
        assert outlet.wanted("/keep/chunk") and not outlet.wanted("/drop/chunk")
        assert outlet.needs_rows("/keep/chunk") and not outlet.needs_rows("/drop/chunk")
        assert outlet.needs_columns("/keep/chunk") and not outlet.needs_columns("/drop/chunk")
        made: Counter[str] = Counter()

        def message(topic: str) -> Any:
            def make(i: int) -> String:
                made[topic] += 1
                return String(data=f"{topic} {i}")
            return make

        ns = np.array([10, 20, 30], dtype=np.int64)
        for prefix in ("/keep", "/drop"):
            topic = f"{prefix}/chunk"
            rows = np.stack([np.frombuffer(encode(STRING, String(data=f"{topic} {i}")), np.uint8)
                             for i in (0, 1, 2)])
            topics = [(topic, rows, message(topic))]
            columns = {topic: {"x": np.array([1.0, 2.0, 3.0])}}
            outlet.publish_chunk(ns, topics, columns, slice(0, 2))
            outlet.hand_over()  # (as the runner does before a report)
            outlet.publish_chunk(ns, topics, columns, slice(2, 3))
            outlet.publish(f"{prefix}/single", String(data="one"), 40)
            data = encode(STRING, String(data="serialized"))
            outlet.publish_serialized(f"{prefix}/bytes", data, 50,
                                      lambda data=data: deserialize_message(data, String))
            outlet.record(f"{prefix}/input", Float64MultiArray(data=[1.5]), STATE_QOS, 60)
        for takes, sink in sinks.items():
            assert sink.topics() == {"/keep/single", "/keep/chunk", "/keep/bytes",
                                     "/keep/input"}, takes
        assert not any(t.startswith("/drop") for t in made)  # no message made for nobody
        # Each in its form.
        assert {m for m, _, _ in sinks[Takes.BYTES].calls} == {"write_rows", "write_bytes"}
        assert {m for m, _, _ in sinks[Takes.MESSAGES].calls} == {"write"}
        columns = [c for c in sinks[Takes.COLUMNS].calls if c[0] == "write_columns"]
        assert [(c[2][0], list(c[2][1]["x"])) for c in columns] == [([10, 20], [1.0, 2.0]),
                                                                     ([30], [3.0])]
        assert [t for m, t, _ in sinks[Takes.COLUMNS].calls if m == "write"] == [
            "/keep/single", "/keep/bytes", "/keep/input"]
        got = [deserialize_message(d, Float64MultiArray) for m, t, d
               in sinks[Takes.BYTES].calls if t == "/keep/input"]
        assert [list(g.data) for g in got] == [[1.5]]
        chunk_rows = [r for m, t, r in sinks[Takes.BYTES].calls if m == "write_rows"]
        assert [r[0] for r in chunk_rows] == [[10, 20], [30]]
        assert [deserialize_message(row.tobytes(), String).data for _, rows in chunk_rows
                for row in rows] == ["/keep/chunk 0", "/keep/chunk 1", "/keep/chunk 2"]
        assert [m.data for k, t, m in sinks[Takes.MESSAGES].calls if t == "/keep/chunk"] == [
            "/keep/chunk 0", "/keep/chunk 1", "/keep/chunk 2"]
        assert outlet.counts["/drop/chunk"] == 3 and outlet.counts["/drop/input"] == 1
    finally:
        node.destroy_node()


def test_recorder_dispatch_honours_wants_and_encodes_once() -> None:
    """The recorder's path (``Sinks.message`` with a received message): the unwanted topic
    reaches no sink; the bytes a bytes sink gets are the wire encoding."""
    sinks = _sinks()
    dispatch = Sinks(list(sinks.values()))
    msg = String(data="Δ received")
    for topic in ("/keep/x", "/drop/x"):
        dispatch.message(topic, STRING, STATE_QOS, 7, msg=msg)
    for sink in sinks.values():
        assert sink.topics() == {"/keep/x"}
    assert sinks[Takes.BYTES].calls == [("write_bytes", "/keep/x", encode(STRING, msg))]


def test_a_topic_without_rows_reaches_a_bytes_sink_encoded() -> None:
    """A chunk encoded while no sink took bytes (rows None), handed to one attached since:
    each sample's bytes, encoded from its message, in order."""
    sink = _Sink(Takes.BYTES)
    Sinks([sink]).chunk(np.array([1, 2, 3]), [ChunkTopic(
        "/keep/late", STRING, STATE_QOS, None, lambda i: String(data=str(i)))], None,
        slice(1, 3))
    assert [(m, deserialize_message(d, String).data) for m, _, d in sink.calls] == [
        ("write_bytes", "1"), ("write_bytes", "2")]


def test_capabilities_are_checked_when_attached() -> None:
    class Undeclared:
        def write(self, *args: Any) -> None:
            pass

    class NoRows:
        capabilities = Capabilities(Takes.BYTES)

        def write_bytes(self, *args: Any) -> None:
            pass

    with pytest.raises(TypeError, match="declares no capabilities"):
        Sinks([Undeclared()])
    with pytest.raises(TypeError, match="write_rows"):
        Sinks([NoRows()])
    dispatch = Sinks([_Sink(Takes.MESSAGES)])
    with pytest.raises(ValueError, match="takes messages"):
        dispatch.message("/keep/x", STRING, None, 0, data=b"\x00\x01\x00\x00")
