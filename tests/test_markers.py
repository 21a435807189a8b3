"""``<ns>/markers`` (visualization_msgs/MarkerArray): each system drawn from its model's own
look (``Model.visuals``), in its frames, computed only while something consumes it, recorded
in bags with the samples' stamps."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from visualization_msgs.msg import Marker

import mechsim
from mechsim.outputs.markers import TRAIL_POINTS, MarkerEncoder
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
    model = mechsim.load_system(system)
    run = mechsim.simulate(model, t_end=0.05, output_dt=0.01)
    Y = _states(model, run)
    enc = MarkerEncoder(model, "inst", ORIGIN)
    rows = enc.encode(run.t, stamps_ns(run.t, 1.0), _frames(model, Y, run.t), 100.0)
    assert rows.shape[0] == len(run.t)
    for i, row in enumerate(rows):
        msg = enc.message(row)
        first, *drawn = msg.markers
        assert first.action == Marker.DELETEALL and first.ns == "inst"
        assert len(drawn) == len(enc.visuals) > 0
        frames = {f.child for f in model.frames}
        for m, v in zip(drawn, enc.visuals, strict=True):
            assert m.ns == "inst" and m.action == Marker.ADD
            stamp = m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
            assert stamp == stamps_ns(run.t, 1.0)[i]
            if v.kind in ("link", "trail"):
                assert m.header.frame_id == "world" and not m.frame_locked
            else:
                assert m.frame_locked and (m.header.frame_id == "world" or (
                    m.header.frame_id.startswith("inst/")
                    and m.header.frame_id[5:] in frames))
            if v.kind == "trail":
                assert len(m.points) == TRAIL_POINTS + 1


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
    links = [k for k, v in enumerate(enc.visuals) if v.kind == "link"]
    for i, row in enumerate(rows):
        markers = enc.message(row).markers[1:]
        (p0, p1), (q0, q1) = ([np.array([pt.x, pt.y, pt.z]) for pt in markers[k].points]
                              for k in links)
        assert np.allclose(p0, ORIGIN, atol=1e-12) and np.allclose(p1, bob1[i], atol=1e-12)
        assert np.allclose(q0, bob1[i], atol=1e-12) and np.allclose(q1, bob2[i], atol=1e-12)
        trail = next(m for m in markers if m.type == Marker.LINE_STRIP and not m.frame_locked)
        assert np.allclose([trail.points[-1].x, trail.points[-1].y, trail.points[-1].z],
                           bob2[i], atol=1e-12)


def test_a_trail_keeps_the_path_and_forgets_what_was_dropped() -> None:
    """Points are kept along the way (every stride-th sample), the current one last; samples
    computed ahead and dropped, or an epoch that ended (a reset), leave no point behind."""
    model = mechsim.load_system("pendulum", **{"initial.angle": 1.0})
    enc = MarkerEncoder(model, "p", (0.0, 0.0, 0.0))
    rate = 100.0
    run = mechsim.simulate(model, t_end=8.0, output_dt=1 / rate)
    placed = _frames(model, _states(model, run), run.t)
    trail_at = next(k for k, v in enumerate(enc.visuals) if v.kind == "trail") + 1

    def trail(rows: np.ndarray) -> np.ndarray:
        pts = enc.message(rows[-1]).markers[trail_at].points
        return np.array([[p.x, p.y, p.z] for p in pts])

    first = trail(enc.encode(run.t[:500], stamps_ns(run.t[:500], 1), placed[:500], rate))
    ahead = trail(enc.encode(run.t[500:700], stamps_ns(run.t[500:700], 1), placed[500:700],
                             rate))
    again = trail(enc.encode(run.t[500:600], stamps_ns(run.t[500:600], 1), placed[500:600],
                             rate))  # 600 … 699 dropped: computed again from 500
    whole = MarkerEncoder(model, "p", (0.0, 0.0, 0.0))
    straight = trail(whole.encode(run.t[:600], stamps_ns(run.t[:600], 1), placed[:600], rate))
    assert np.array_equal(again, straight)
    assert not np.array_equal(ahead, again)
    assert len(np.unique(first.round(12), axis=0)) > TRAIL_POINTS // 2  # a path, not a point
    reset = trail(enc.encode(run.t[:1], stamps_ns(run.t[:1], 1), placed[:1], rate))
    assert np.allclose(reset, reset[-1])  # t = 0 again: only the current point


def test_markers_are_recorded_with_the_samples(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    out = subprocess.run([sys.executable, "-m", "mechsim.cli", "record", "pendulum",
                          "--duration", "0.5", "--bag", str(bag)], capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    from rosbags.highlevel import AnyReader

    stamps: dict[str, list[int]] = {}
    with AnyReader([bag]) as reader:
        for con, t, _ in reader.messages():
            stamps.setdefault(con.topic, []).append(t)
    assert stamps["/pendulum/markers"] == stamps["/pendulum/state"]
    assert len(stamps["/pendulum/markers"]) == 51


def test_markers_cost_nothing_unless_consumed(ros_context: Any) -> None:
    from mechsim.ros.simulator import SimulatorNode
    from mechsim.scene import Instance

    node = SimulatorNode(Instance("pendulum", "unwatched"), context=ros_context,
                         real_time_factor=0.0)
    try:
        node.advance_to(1.0)
        assert node.topics.t_markers == "/unwatched/markers"
        assert node.computed["frames"] == 0  # no /tf subscriber, no markers subscriber
    finally:
        node.destroy_node()
