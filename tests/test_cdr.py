"""The chunk encoder of the node's topics (``messages.ChunkEncoder``, on ``wire.Layout``),
checked against rclpy's serializer of the messages the ``MessageFactory`` builds from the same
stepper output, and against rosbags' deserializer (independent readers), for every system and
topic."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from mechsim.systems import system_class, system_ids

TOPICS = ("state", "pose", "twist", "energy", "invariants", "observables", "tf", "clock")


def _chunk(system: str, n: int = 7) -> tuple[Any, Any, Any]:
    """(factory, chunk, per-sample Sample list) from a real run of ``system``."""
    from mechsim.integrators import make_stepper
    from mechsim.outputs.messages import Chunk, MessageFactory, Sample, stamp_ns
    from mechsim.simulate import evaluate

    model = system_class(system)()
    stepper = make_stepper(model, "auto", 1e-9)
    times = 0.01 * np.arange(1, n + 1)
    Y = stepper.advance(times)
    which = ("energy", "invariants", "observables", "frames")
    out = evaluate(model, times, Y, model.parameter_vector(), which)
    at = model.layout
    inv = np.column_stack([out.invariants[q.name] for q in model.invariants]) \
        if model.invariants else np.zeros((n, 0))
    obs = np.column_stack([out.observables[q.name] for q in model.observables]) \
        if model.observables else np.zeros((n, 0))
    energy = np.column_stack([out.kinetic, out.potential, out.energy_function])
    factory = MessageFactory(model, "inst", origin=(1.5, -2.0, 0.25))
    ns = np.array([stamp_ns(t, factory.time_offset) for t in times], dtype=np.int64)
    chunk = Chunk(ns, Y[:, at.q], Y[:, at.v],
                  np.column_stack([Y[:, at.work_external], Y[:, at.work_dissipated]]),
                  energy, inv, obs, out.frames)
    samples = [Sample(float(times[i]), Y[i, at.q], Y[i, at.v], float(Y[i, at.work_external]),
                      float(Y[i, at.work_dissipated]), energy[i], inv[i], obs[i],
                      out.frames[i] if out.frames is not None else None)
               for i in range(n)]
    return factory, chunk, samples


def _reference(factory: Any, topic: str, s: Any, ns: int) -> Any:
    from mechsim.outputs import messages

    if topic == "clock":
        return messages.clock(ns)
    return getattr(factory, topic)(s, ns)


@pytest.mark.parametrize("system", system_ids())
def test_every_topic_equals_rclpy_serialization(system: str) -> None:
    """Byte for byte equal to rclpy's serialization (cut at the data's end, as DDS carries it)
    of the factory's messages for the same samples, and decoding (rosbags) to the same
    values; every padding byte of ours is zero."""
    from rclpy.serialization import deserialize_message, serialize_message

    from mechsim.outputs.messages import ChunkEncoder
    from mechsim.outputs.wire import message_class, typestore_with

    factory, chunk, samples = _chunk(system)
    enc = ChunkEncoder(factory)
    model = factory.model
    for topic in TOPICS:
        if (topic == "tf" and not enc.dynamic) or (
                topic in ("pose", "twist") and model.attitude is None):
            continue
        rows = enc.encode(topic, chunk)
        layout = getattr(enc, topic)
        for i, s in enumerate(samples):
            ref = _reference(factory, topic, s, int(chunk.ns[i]))
            ours = rows[i].tobytes()
            # rclpy leaves padding uninitialised and may count padding after the data (rmw's
            # estimated size): compare the data's bytes and require ours to be zero wherever
            # the two differ.
            theirs = serialize_message(ref)
            assert len(ours) <= len(theirs), topic
            d = np.frombuffer(ours, np.uint8) != np.frombuffer(theirs[:len(ours)], np.uint8)
            assert not np.frombuffer(ours, np.uint8)[d].any(), (system, topic)
            # Decoded by rclpy: equal to the reference message.
            back = deserialize_message(ours, message_class(layout.type_name))
            assert back == ref, (system, topic, i)
            # Decoded by rosbags (a reader that checks lengths): the same numbers.
            store = typestore_with(layout.type_name)
            msg = store.deserialize_cdr(ours, layout.type_name)
            if topic == "state":
                # Joint-like coordinates only: a quaternion attitude is on pose and twist.
                quat = model.attitude.quaternion if model.attitude else ()
                j = [k for k in range(len(model.coordinates)) if k not in quat]
                assert np.array_equal(msg.position, s.q[j])
                assert np.array_equal(msg.velocity, s.v[j])
                assert list(msg.name) == [model.coordinates[k].name for k in j]
                assert not any(model.coordinates[k].name.startswith("quaternion_") for k in j)
            if topic == "pose":
                o = msg.pose.orientation
                quat_q = s.q[list(model.attitude.quaternion)]
                np.testing.assert_allclose([o.x, o.y, o.z, o.w],
                                           quat_q / np.sqrt(np.sum(quat_q ** 2)), rtol=1e-15)
                assert (msg.pose.position.x, msg.pose.position.y,
                        msg.pose.position.z) == (1.5, -2.0, 0.25)
                assert msg.header.frame_id == "world"
            if topic in ("invariants", "observables"):
                qs = getattr(model, topic)
                assert [(r.name, r.unit) for r in msg.scalars] == [(q.name, q.unit) for q in qs]
                assert [r.value for r in msg.scalars] == list(getattr(s, topic))
            if topic == "energy":
                assert msg.kinetic == s.energy[0] and msg.work_external == s.work_external
            stamp = msg.clock if topic == "clock" else (
                msg.transforms[0].header.stamp if topic == "tf" else msg.header.stamp)
            assert stamp.nanosec == int(chunk.ns[i]) % 1_000_000_000


def test_padding_zero_and_layout_generic() -> None:
    """A type with every kind of field and alignment (any installed .msg, here
    DiagnosticArray and TFMessage): bytes equal to rosbags' own serializer (which writes zero
    padding) and every number placed where rosbags reads it."""
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
    from rclpy.serialization import deserialize_message

    from mechsim.outputs.wire import Layout, typestore_with

    proto = DiagnosticArray(status=[DiagnosticStatus(
        level=DiagnosticStatus.WARN, name="a", message="xyz", hardware_id="h",
        values=[KeyValue(key="k", value="v")])])
    proto.header.frame_id = "f"
    lay = Layout("diagnostic_msgs/msg/DiagnosticArray", proto)
    ns = np.array([5_000_000_001, 7_999_999_999], dtype=np.int64)
    rows = lay.encode(ns)
    store = typestore_with(lay.type_name)
    for i in range(2):
        msg = store.deserialize_cdr(rows[i].tobytes(), lay.type_name)
        assert store.serialize_cdr(msg, lay.type_name).tobytes() == rows[i].tobytes()
        back = deserialize_message(rows[i].tobytes(), DiagnosticArray)
        assert back.header.stamp.sec == ns[i] // 10**9
        assert back.status[0].level == DiagnosticStatus.WARN
    # A numeric leaf of the rclpy message at an odd offset (byte level, then a float64).
    from sensor_msgs.msg import JointState
    js = JointState(name=["a"], position=[1.0, 2.0], velocity=[], effort=[3.0])
    js.header.frame_id = "abc"
    lay = Layout("sensor_msgs/msg/JointState", js)
    block = lay.block(["position.0", "position.1", "effort.0"])
    assert len(block.runs) == 2
    vals = np.array([[0.5, -0.25, 9.0]])
    data = lay.encode(np.array([3]), [(block, vals)])[0].tobytes()
    store = typestore_with(lay.type_name)
    assert store.serialize_cdr(store.deserialize_cdr(data, lay.type_name),
                               lay.type_name).tobytes() == data
    back = deserialize_message(data, JointState)
    assert list(back.position) == [0.5, -0.25] and list(back.effort) == [9.0]
    assert back.velocity.tolist() == [] and back.header.stamp.nanosec == 3
