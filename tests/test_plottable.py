"""Messages users can plot by name, read back from a recorded bag by decoders that are not ours:
rosbags, PlotJuggler's parser (``rosx_introspection``, the flattening library PlotJuggler
uses) and Foxglove's ROS 2 decoding stack (``@mcap/core``, ``@foxglove/rosmsg``,
``@foxglove/rosmsg2-serialization``, installed by `make test` in tests/foxglove; run with node).
An invariant is selected by its name ("angular_momentum"), never by its index; an attitude
system publishes geometry_msgs pose and twist, and no quaternion in JointState.

Oracles: the Kepler orbit's angular momentum L = √(μ² GM a (1 − e²)) (PHYS0500 §4.6), and a
rigid body spinning about a principal axis, whose body angular velocity stays (0, 0, ω₀) and
whose attitude is q(t) = q₀ ⊗ (0, 0, sin(ω₀t/2), cos(ω₀t/2)) (PHYS0500 §7.7: stable spin
about the axis of largest moment), with q₀ from scipy's z-x-z Euler angles.
"""

from __future__ import annotations

import json
import math
import shutil
import subprocess
from pathlib import Path
from typing import Any

import numpy as np
import pytest

SPIN = 3.0  # rad/s about principal axis 3
PHI, THETA, PSI = 0.4, 0.3, -0.2  # initial z-x-z Euler angles of the rigid body


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Kepler and a spinning rigid body recorded for 1 s (fast pacing, in process)."""
    from mechsim.ros import record
    from mechsim.scene import parse_scene

    scene = parse_scene({"name": "plottable", "pacing": "fast", "duration": 1.0,
                         "publish_rate": 50.0, "systems": [
                             {"system": "kepler"},
                             {"system": "rigid_body", "name": "spinner", "origin": [1, 2, 3],
                              "parameters": {"initial.phi": PHI, "initial.theta": THETA,
                                             "initial.psi": PSI, "initial.omega_1": 0.0,
                                             "initial.omega_2": 0.0,
                                             "initial.omega_3": SPIN}}]})
    path = tmp_path_factory.mktemp("bags") / "plot"
    run, _ = record.run_with_outputs(scene, fast=True, duration=1.0, bag=str(path))
    assert run.messages and not run.failures
    return path


def _mcap(path: Path) -> Path:
    return path / f"{path.name}_0.mcap"


def _by_name_plotjuggler(path: Path, topic: str, name: str) -> list[tuple[int, float, str]]:
    """(log time, value, unit) of the record called ``name`` on ``topic``, flattened by
    PlotJuggler's parser: the index whose ``/scalars[i]/name`` is ``name`` gives the value."""
    import msgpack
    rosx = pytest.importorskip("rosx_introspection")
    from mcap.reader import make_reader

    out = []
    with open(_mcap(path), "rb") as f:
        parser = None
        for schema, _channel, message in make_reader(f).iter_messages(topics=[topic]):
            if parser is None:
                parser = rosx.Parser(topic_name=topic, type_name=schema.name,
                                     schema=schema.data.decode())
            flat = msgpack.unpackb(parser.parse_to_msgpack(message.data))
            keys = [k for k, v in flat.items() if k.endswith("/name") and v == name]
            assert len(keys) == 1, (topic, name, sorted(flat))
            base = keys[0][:-len("/name")]
            out.append((message.log_time, float(flat[f"{base}/value"]), flat[f"{base}/unit"]))
    return out


def test_angular_momentum_selected_by_name_plotjuggler(bag: Path) -> None:
    """PlotJuggler's parser finds "angular_momentum" on /kepler/invariants by name, with its
    unit, in every message, equal to the Kepler orbit's L."""
    from mechsim.systems import system_class

    model = system_class("kepler")()
    mu, GM = model.value("reduced_mass"), model.value("gravitational_parameter")
    a, e = model.value("semi_major_axis"), model.value("eccentricity")
    expected = math.sqrt(mu * mu * GM * a * (1 - e * e))
    got = _by_name_plotjuggler(bag, "/kepler/invariants", "angular_momentum")
    assert len(got) == 51  # t = 0, 0.02, ..., 1.0
    assert {unit for _, _, unit in got} == {"kg m^2/s"}
    np.testing.assert_allclose([v for _, v, _ in got], expected, rtol=1e-9)
    # A name that is not published is not found (the selection can fail).
    with pytest.raises(AssertionError):
        _by_name_plotjuggler(bag, "/kepler/invariants", "angular_momentum_z")


def test_invariants_by_name_rosbags_agree_with_plotjuggler(bag: Path) -> None:
    """rosbags decodes records (name, value, unit); every named value on every
    NamedScalars topic equals what PlotJuggler's parser selects by that name."""
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        cons = [c for c in reader.connections if c.msgtype == "mechsim_msgs/msg/NamedScalars"]
        assert {c.topic for c in cons} >= {"/kepler/invariants", "/kepler/observables",
                                           "/spinner/invariants", "/spinner/observables"}
        for con in cons:
            rows = [(ts, reader.deserialize(raw, con.msgtype))
                    for _, ts, raw in reader.messages(connections=[con])]
            names = [s.name for s in rows[0][1].scalars]
            assert names and len(set(names)) == len(names)
            for name in names:
                theirs = _by_name_plotjuggler(bag, con.topic, name)
                ours = [(ts, next(s.value for s in m.scalars if s.name == name))
                        for ts, m in rows]
                assert [(t, v) for t, v, _ in theirs] == ours, (con.topic, name)


FOXGLOVE = Path(__file__).resolve().parent / "foxglove"


def _foxglove(path: Path, topic: str) -> list[dict[str, Any]]:
    """Every message of ``topic`` as Foxglove's decoders give it (``{log_time, message}``)."""
    node = shutil.which("node")
    if node is None or not (FOXGLOVE / "node_modules" / "@foxglove" / "rosmsg").is_dir():
        pytest.skip("Foxglove's decoders are not installed (`make test` runs `npm ci` in "
                    "tests/foxglove where node and npm exist: tools/test_tools.py)")
    out = subprocess.run([node, str(FOXGLOVE / "read.cjs"), str(_mcap(path)), topic],
                         capture_output=True, text=True, timeout=120, check=False)
    assert out.returncode == 0, out.stderr
    return [json.loads(line) for line in out.stdout.splitlines()]


def test_angular_momentum_selected_by_name_foxglove(bag: Path) -> None:
    """Foxglove's decoders give records: the message path
    ``/kepler/invariants.scalars[:]{name=="angular_momentum"}.value`` (every element of
    ``scalars`` whose ``name`` equals, then its ``value``) selects one value per message, equal
    to PlotJuggler's selection and to the Kepler orbit's L; the spinner's twist decodes with
    its body rates."""
    got = _foxglove(bag, "/kepler/invariants")
    selected = [[s["value"] for s in m["message"]["scalars"] if s["name"] == "angular_momentum"]
                for m in got]
    assert len(selected) == 51 and all(len(v) == 1 for v in selected)
    pj = _by_name_plotjuggler(bag, "/kepler/invariants", "angular_momentum")
    assert [(int(m["log_time"]), v[0]) for m, v in zip(got, selected, strict=True)] == [
        (t, v) for t, v, _ in pj]
    twist = _foxglove(bag, "/spinner/twist")
    assert len(twist) == 51
    for m in twist:
        w = m["message"]["twist"]["angular"]
        assert m["message"]["header"]["frame_id"] == "spinner/principal"
        np.testing.assert_allclose([w["x"], w["y"], w["z"]], [0.0, 0.0, SPIN], atol=1e-9)


def _quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])


def test_attitude_as_pose_and_twist(bag: Path) -> None:
    """The spinning body: PoseStamped in "world" at the instance origin with the unit
    quaternion of the spin, TwistStamped in body axes with ω = (0, 0, ω₀) rad/s, the pose
    equal to the body's /tf transform, and no JointState (no joint-like coordinates)."""
    from rosbags.highlevel import AnyReader
    from scipy.spatial.transform import Rotation

    q0 = Rotation.from_euler("ZXZ", [PHI, THETA, PSI]).as_quat()  # (x, y, z, w)
    by_topic: dict[str, list[tuple[int, Any]]] = {}
    with AnyReader([bag]) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        for con, ts, raw in reader.messages():
            if con.topic.startswith("/spinner/") or con.topic == "/tf":
                by_topic.setdefault(con.topic, []).append((ts, reader.deserialize(
                    raw, con.msgtype)))
    assert types["/spinner/pose"] == "geometry_msgs/msg/PoseStamped"
    assert types["/spinner/twist"] == "geometry_msgs/msg/TwistStamped"
    assert "/spinner/state" not in types and "/kepler/state" in types
    poses, twists = by_topic["/spinner/pose"], by_topic["/spinner/twist"]
    assert len(poses) == len(twists) == 51
    tf = {ts: t.transform for ts, m in by_topic["/tf"] for t in m.transforms
          if t.child_frame_id == "spinner/principal"}
    for (ts, p), (ts2, w) in zip(poses, twists, strict=True):
        t = (ts - 1_000_000_000) / 1e9
        assert ts == ts2 and p.header.frame_id == "world"
        assert w.header.frame_id == "spinner/principal"
        pos, o = p.pose.position, p.pose.orientation
        assert (pos.x, pos.y, pos.z) == (1.0, 2.0, 3.0)
        q = np.array([o.x, o.y, o.z, o.w])
        assert abs(np.linalg.norm(q) - 1.0) < 1e-15
        want = _quat_mul(q0, np.array([0.0, 0.0, math.sin(SPIN * t / 2),
                                       math.cos(SPIN * t / 2)]))
        assert min(np.max(np.abs(q - want)), np.max(np.abs(q + want))) < 1e-8, t
        np.testing.assert_allclose([w.twist.angular.x, w.twist.angular.y, w.twist.angular.z],
                                   [0.0, 0.0, SPIN], atol=1e-9)
        assert (w.twist.linear.x, w.twist.linear.y, w.twist.linear.z) == (0.0, 0.0, 0.0)
        r = tf[ts].rotation
        np.testing.assert_allclose([r.x, r.y, r.z, r.w], q, rtol=0, atol=1e-15)


def test_new_types_in_the_bag_match_rosidl(bag: Path) -> None:
    """Each new type's RIHS01 hash in the MCAP channel metadata and in metadata.yaml is the one
    rosidl generated (share/<pkg>/msg/<Type>.json), and its schema text carries NamedScalar."""
    import json
    import sys

    import yaml
    from mcap.reader import make_reader

    def rosidl_hash(type_name: str) -> str:
        pkg, _, typ = type_name.split("/")
        desc = json.loads((Path(sys.prefix) / "share" / pkg / "msg" / f"{typ}.json")
                          .read_text())
        return next(h["hash_string"] for h in desc["type_hashes"]
                    if h["type_name"] == type_name)

    with open(_mcap(bag), "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    in_yaml = {t["topic_metadata"]["name"]: t["topic_metadata"]["type_description_hash"]
               for t in meta["topics_with_message_count"]}
    seen = set()
    for ch in summary.channels.values():
        schema = summary.schemas[ch.schema_id]
        if schema.name in ("mechsim_msgs/msg/NamedScalars", "geometry_msgs/msg/PoseStamped",
                           "geometry_msgs/msg/TwistStamped"):
            seen.add(schema.name)
            assert ch.metadata["topic_type_hash"] == rosidl_hash(schema.name) == \
                in_yaml[ch.topic], ch.topic
        if schema.name == "mechsim_msgs/msg/NamedScalars":
            text = schema.data.decode()
            assert "NamedScalar[] scalars" in text
            assert "\nMSG: mechsim_msgs/NamedScalar\n" in text
    assert len(seen) == 3
