"""``<ns>/markers_static`` and ``<ns>/markers`` (visualization_msgs/MarkerArray): each system
drawn from its model's own look (``Model.visuals``), in its frames. The frame-locked visuals
are latched, published once per look (again when a parameter changes it); the links and
trails go with every sample, computed only while something consumes them, recorded in bags
with the samples' stamps."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from visualization_msgs.msg import Marker

import mechsim
from mechsim.outputs.markers import BODY, MOVING, SEGMENT, TRAIL_POINTS, TRAIL_SPAN, MarkerEncoder
from mechsim.outputs.messages import MessageFactory, stamps_ns
from mechsim.simulate import OutputShape, evaluate_arrays

ORIGIN = (2.0, -1.0, 0.5)


def _states(model: Any, run: Any) -> np.ndarray:
    """The state rows (q, v, work terms, modes) of a simulate() result."""
    Y = np.tile(model.initial_y(), (len(run.t), 1))
    at = model.layout
    Y[:, at.q], Y[:, at.v] = run.q, run.v
    return Y


def _frames(model: Any, Y: np.ndarray, times: np.ndarray) -> np.ndarray:
    out = evaluate_arrays(model, OutputShape.of(model), times, Y, model.parameter_vector(),
                          ("frames",))
    return MessageFactory(model, "x", ORIGIN).placed(out[3])


#: The systems with frames (one without, lrc_circuit, has no markers topic: see
#: test_graph_as_seen.py).
DRAWN = [s for s in mechsim.system_ids() if mechsim.load_system(s).frames]


@pytest.mark.parametrize("system", DRAWN)
def test_every_system_is_drawn_in_its_frames(system: str) -> None:
    """The static set: a DELETEALL of the namespace, then every frame-locked visual in its
    frame; each sample: only the links and trails, in "world", added in place (no
    DELETEALL), stamped with the sample."""
    model = mechsim.load_system(system)
    run = mechsim.simulate(model, t_end=0.05, output_dt=0.01)
    Y = _states(model, run)
    enc = MarkerEncoder(model, "inst", ORIGIN)
    kinds = [v.kind for v in model.visuals()]
    assert [v.kind for v in enc.visuals] == kinds  # every visual of every system drawn
    frames = {f.child for f in model.frames}
    first, *fixed = enc.fixed(123_000_000_456).markers
    assert first.action == Marker.DELETEALL and first.ns == "inst"
    assert [m.id for m in fixed] == [i for i, k in enumerate(kinds) if k not in MOVING]
    for m in [first, *fixed]:
        assert (m.header.stamp.sec, m.header.stamp.nanosec) == (123, 456)
    for m in fixed:
        assert m.ns == "inst" and m.action == Marker.ADD and m.frame_locked
        assert m.header.frame_id == "world" or (m.header.frame_id.startswith("inst/")
                                                and m.header.frame_id[5:] in frames)
    moving = [i for i, k in enumerate(kinds) if k in MOVING]
    if not moving:
        assert enc.layout is None  # nothing moves: no per-sample markers
        return
    stamps = stamps_ns(run.t, 1.0)
    rows = enc.encode(run.t, stamps, _frames(model, Y, run.t), 100.0)
    assert rows.shape[0] == len(run.t)
    for i, row in enumerate(rows):
        drawn = enc.message(row).markers
        assert [m.id for m in drawn] == moving
        for m in drawn:
            assert m.ns == "inst" and m.action == Marker.ADD
            assert m.header.frame_id == "world" and not m.frame_locked
            assert m.header.stamp.sec * 10**9 + m.header.stamp.nanosec == stamps[i]
            if kinds[m.id] == "trail":
                assert m.type == Marker.LINE_STRIP and len(m.points) == SEGMENT + 1
            else:
                assert m.type == Marker.LINE_LIST and len(m.points) == 2


def test_links_join_the_bobs_where_the_physics_puts_them() -> None:
    """Double pendulum (angles from straight down, in the y–z plane): bob 1 at
    l₁(sin θ₁, −cos θ₁), bob 2 at bob 1 + l₂(sin θ₂, −cos θ₂), plus the instance's origin:
    the frames composed from /tf's parent-relative transforms land there."""
    model = mechsim.load_system("double_pendulum", length_1=0.7, length_2=1.3)
    run = mechsim.simulate(model, t_end=2.0, output_dt=0.05)
    Y = _states(model, run)
    enc = MarkerEncoder(model, "dp", ORIGIN)
    rows = enc.encode(run.t, stamps_ns(run.t, 1.0), _frames(model, Y, run.t), 20.0)
    th1, th2 = run.q[:, 0], run.q[:, 1]
    bob1 = np.column_stack([0 * th1, 0.7 * np.sin(th1), -0.7 * np.cos(th1)]) + ORIGIN
    bob2 = bob1 + np.column_stack([0 * th2, 1.3 * np.sin(th2), -1.3 * np.cos(th2)])
    links = [k for k, i in enumerate(enc.moving_ids) if enc.visuals[i].kind == "link"]
    for i, row in enumerate(rows):
        markers = enc.message(row).markers
        (p0, p1), (q0, q1) = ([np.array([pt.x, pt.y, pt.z]) for pt in markers[k].points]
                              for k in links)
        assert np.allclose(p0, ORIGIN, atol=1e-12) and np.allclose(p1, bob1[i], atol=1e-12)
        assert np.allclose(q0, bob1[i], atol=1e-12) and np.allclose(q1, bob2[i], atol=1e-12)
        trail = next(m for m in markers if m.type == Marker.LINE_STRIP and not m.frame_locked)
        assert np.allclose([trail.points[-1].x, trail.points[-1].y, trail.points[-1].z],
                           bob2[i], atol=1e-12)


def _points(marker: Any) -> np.ndarray:
    return np.array([[p.x, p.y, p.z] for p in marker.points])


def _trail(enc: MarkerEncoder, rows: np.ndarray, bodies: list[tuple[int, bytes]],
           i: int) -> np.ndarray:
    """The trail drawn at sample ``i`` of ``rows``: the latest body made up to it, then its
    head after the point they share (points repeated in a row shown once)."""
    body = _points(enc.message(np.frombuffer(max(
        (b for b in bodies if b[0] <= i), key=lambda b: b[0])[1], np.uint8)).markers[0])
    head = next(m for m in enc.message(rows[i]).markers if m.type == Marker.LINE_STRIP)
    assert np.array_equal(body[-1], _points(head)[0])  # one line
    line = np.vstack([body, _points(head)[1:]])
    return line[np.r_[True, np.any(line[1:] != line[:-1], axis=1)]]


def test_a_trail_is_a_body_that_changes_every_segment_and_a_head() -> None:
    """The trail at each sample: the points kept every stride-th sample (the last 57 to 64
    of them: the body holds BODY, up to the newest whose number is a multiple of SEGMENT;
    the head those since), then the current point; a body is made only where it
    changes."""
    model = mechsim.load_system("pendulum", **{"initial.angle": 1.0})
    enc = MarkerEncoder(model, "p", (0.0, 0.0, 0.0))
    rate = 100.0
    run = mechsim.simulate(model, t_end=8.0, output_dt=1 / rate)
    placed = _frames(model, _states(model, run), run.t)
    path = enc.world_origins(placed)[:, enc.trails[0]]
    stride = math.ceil(TRAIL_SPAN * model.time_scale() * rate / TRAIL_POINTS)
    assert stride > 1
    rows = enc.encode(run.t, stamps_ns(run.t, 1), placed, rate)
    bodies = enc.bodies()(0, len(run.t))
    assert [k for k, _ in bodies] == list(range(0, len(run.t), stride * SEGMENT))
    for i in range(0, len(run.t), 7):
        kept = np.arange(0, i + 1, stride)
        shown = kept[max(0, len(kept) - 1 - (BODY - 1) - (len(kept) - 1) % SEGMENT):]
        expected = np.vstack([path[shown], path[i:i + 1]])
        expected = expected[np.r_[True, np.any(expected[1:] != expected[:-1], axis=1)]]
        assert np.array_equal(_trail(enc, rows, bodies, i), expected), i


def test_a_trail_forgets_what_was_dropped() -> None:
    """Samples computed ahead and dropped, or an epoch that ended (a reset), leave no point
    behind: the trail is the one of a run that never computed them."""
    model = mechsim.load_system("pendulum", **{"initial.angle": 1.0})
    enc = MarkerEncoder(model, "p", (0.0, 0.0, 0.0))
    rate = 100.0
    run = mechsim.simulate(model, t_end=8.0, output_dt=1 / rate)
    placed = _frames(model, _states(model, run), run.t)

    def encode(e: MarkerEncoder, a: int, b: int) -> tuple[np.ndarray, list[tuple[int, bytes]]]:
        rows = e.encode(run.t[a:b], stamps_ns(run.t[a:b], 1), placed[a:b], rate)
        return rows, e.bodies()(0, b - a)

    first_rows, first_bodies = encode(enc, 0, 500)
    first = _trail(enc, first_rows, first_bodies, 499)
    ahead_rows, ahead_bodies = encode(enc, 500, 700)
    ahead = _trail(enc, ahead_rows, [(k - 500, b) for k, b in first_bodies] + ahead_bodies,
                   199)
    again_rows, again_bodies = encode(enc, 500, 600)  # 600 … 699 dropped: again from 500
    assert again_bodies and again_bodies[0][0] == 0  # the body anew at the first sample
    again = _trail(enc, again_rows, again_bodies, 99)
    whole = MarkerEncoder(model, "p", (0.0, 0.0, 0.0))
    straight_rows, straight_bodies = encode(whole, 0, 600)
    assert np.array_equal(again, _trail(whole, straight_rows, straight_bodies, 599))
    assert not np.array_equal(ahead[-SEGMENT:], again[-SEGMENT:])
    assert len(first) > TRAIL_POINTS // 2  # a path, not a point
    reset_rows, reset_bodies = encode(enc, 0, 1)
    assert len(_trail(enc, reset_rows, reset_bodies, 0)) == 1  # t = 0 again: one point


def test_a_bag_holds_the_static_markers_once_and_the_moving_ones_every_sample(
        tmp_path: Path) -> None:
    """``mechsim record``: /pendulum/markers_static once, latched (transient local, as
    /tf_static), stamped and logged with the first sample; /pendulum/markers with every
    sample (the stamps of the state's), each holding the link and the trail's head only;
    /pendulum/markers_trails (latched) with the samples where the trail's body changes, the
    first with the first sample: from any sample, its latest body meets its head."""
    bag = tmp_path / "bag"
    out = subprocess.run([sys.executable, "-m", "mechsim.cli", "record", "pendulum",
                          "--duration", "1.5", "--bag", str(bag)], capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    from rosbags.highlevel import AnyReader

    stamps: dict[str, list[int]] = {}
    kinds = [v.kind for v in mechsim.load_system("pendulum").visuals()]
    bodies: dict[int, np.ndarray] = {}
    heads: dict[int, np.ndarray] = {}
    with AnyReader([bag]) as reader:
        qos = {c.topic: c.ext.offered_qos_profiles[0] for c in reader.connections}
        assert qos["/pendulum/markers_static"].durability.name == "TRANSIENT_LOCAL"
        assert qos["/pendulum/markers_static"].depth == 1
        assert qos["/pendulum/markers_trails"].durability.name == "TRANSIENT_LOCAL"
        for con, t, raw in reader.messages():
            stamps.setdefault(con.topic, []).append(t)
            if con.topic.startswith("/pendulum/markers"):
                msg = reader.deserialize(raw, con.msgtype)
                if con.topic.endswith("static"):
                    assert msg.markers[0].action == Marker.DELETEALL
                    assert [kinds[m.id] for m in msg.markers[1:]] == ["sphere"]
                    assert msg.markers[1].frame_locked
                    assert msg.markers[1].header.frame_id == "pendulum/bob"
                elif con.topic.endswith("trails"):
                    (body,) = msg.markers
                    assert kinds[body.id] == "trail" and len(body.points) == BODY
                    bodies[t] = _points(body)
                else:
                    assert sorted(kinds[m.id] for m in msg.markers) == ["link", "trail"]
                    heads[t] = _points(next(m for m in msg.markers if kinds[m.id] == "trail"))
    assert stamps["/pendulum/markers_static"] == stamps["/pendulum/state"][:1]
    assert stamps["/pendulum/markers"] == stamps["/pendulum/state"]
    assert len(stamps["/pendulum/markers"]) == 151
    assert stamps["/pendulum/markers_trails"][0] == stamps["/pendulum/state"][0]
    assert 1 < len(bodies) < 151 and set(bodies) <= set(heads)
    for t, head in heads.items():
        assert np.array_equal(bodies[max(b for b in bodies if b <= t)][-1], head[0])


def test_the_static_markers_are_latched_and_published_again_for_a_new_look(
        mechsim_graph: Any) -> None:
    """A subscriber that joins late gets the one static set; a parameter change that keeps
    the look publishes nothing on it, one that changes the look (the hoop's radius)
    publishes the new set; the moving markers hold only the links and trails."""
    g = mechsim_graph
    node = g.start("rotating_hoop", name="hoop", diagnostics=False).nodes[0]
    kinds = [v.kind for v in mechsim.load_system("rotating_hoop").visuals()]
    moving = g.collect("/hoop/markers")
    moving.wait_for(count=20)
    for msg in moving.messages:
        assert sorted(kinds[m.id] for m in msg.markers) == sorted(
            k for k in kinds if k in MOVING)
        assert all(m.action == Marker.ADD and m.header.frame_id == "world"
                   and not m.frame_locked for m in msg.markers)
    static = g.collect("/hoop/markers_static")  # after the set was published: latched
    (first,) = static.wait_for(count=1)
    assert first.markers[0].action == Marker.DELETEALL and first.markers[0].ns == "hoop"
    assert [kinds[m.id] for m in first.markers[1:]] == [k for k in kinds if k not in MOVING]
    assert all(m.frame_locked and m.header.frame_id.startswith("hoop/")
               for m in first.markers[1:])
    assert node.outlet.counts["/hoop/markers_static"] == 1
    assert g.set_parameters("/hoop/simulator", mass=2.0)[0].successful
    assert g.set_parameters("/hoop/simulator", length=2.0)[0].successful
    _, second = static.wait_for(count=2)
    assert node.outlet.counts["/hoop/markers_static"] == 2  # the mass left the look alone
    hoop = kinds.index("polyline")
    before, after = (next(m for m in msg.markers[1:] if m.id == hoop)
                     for msg in (first, second))
    radius = [max(abs(p.x) + abs(p.y) + abs(p.z) for p in m.points) for m in (before, after)]
    assert radius[1] > radius[0]
    n = len(moving.messages)
    moving.wait_for(count=n + 5)  # the run goes on; nothing more on the latched topic
    assert node.outlet.counts["/hoop/markers_static"] == 2


def test_markers_cost_nothing_unless_consumed(ros_context: Any) -> None:
    from mechsim.ros.simulator import SimulatorNode
    from mechsim.scene import Instance

    node = SimulatorNode(Instance("pendulum", "unwatched"), context=ros_context,
                         real_time_factor=0.0)
    try:
        node.advance_to(1.0)
        assert node.topics.t_markers == "/unwatched/markers"
        assert node.outlet.counts["/unwatched/markers_static"] == 1  # latched, once
        assert node.computed["frames"] == 0  # no /tf subscriber, no markers subscriber
    finally:
        node.destroy_node()
