"""Rerun recordings (mechsim.outputs.rerun), read back with Rerun's own reader
(rerun.chunk.RrdReader) and compared with the ROS messages the run published (captured by an
independent sink)."""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pytest

from mechsim.environment import import_rclpy

import_rclpy()

from rerun.chunk import RrdReader  # noqa: E402

from mechsim.outputs.sink import Capabilities  # noqa: E402

OFFSET_NS = 1_000_000_000  # messages.DEFAULT_TIME_OFFSET, stated independently
DURATION = 2.0
RATE = 50.0


class Capture:
    """Keeps what the run published: (topic, type, message) in order."""

    capabilities = Capabilities()

    def __init__(self) -> None:
        self.messages: list[tuple[str, str, Any]] = []

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        self.messages.append((topic, type_name, msg))

    def on(self, topic: str) -> list[Any]:
        return [m for t, _, m in self.messages if t == topic]


def read_rrd(path: Path) -> dict[str, dict[str, Any]]:
    """entity -> {"static": {column: value}, "time": int64 ns array, "<column>": [values]}."""
    out: dict[str, dict[str, Any]] = defaultdict(lambda: {"static": {}, "time": [],
                                                          "cols": defaultdict(list)})
    for chunk in RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        e = out[chunk.entity_path]
        names = [n for n in batch.schema.names if n != "rerun.controls.RowId"]
        if chunk.is_static:
            for n in names:
                e["static"][n] = batch.column(n).to_pylist()[0]
            continue
        e["time"].extend(batch.column("sim_time").cast(pa.int64()).to_pylist())
        for n in names:
            if n != "sim_time":
                e["cols"][n].extend(batch.column(n).to_pylist())
    for e in out.values():
        order = np.argsort(np.asarray(e["time"], dtype=np.int64), kind="stable")
        e["time"] = np.asarray(e["time"], dtype=np.int64)[order]
        for n, v in e["cols"].items():
            e["cols"][n] = [v[i] for i in order]
    return dict(out)


def scalars(e: dict[str, Any]) -> np.ndarray:
    return np.array([v[0] for v in e["cols"]["Scalars:scalars"]])


def strips(e: dict[str, Any]) -> list[list[list[float]]]:
    """The one line strip of each row."""
    rows = e["cols"]["LineStrips3D:strips"]
    assert all(len(r) == 1 for r in rows)
    return [r[0] for r in rows]


def stamp_ns(stamp: Any) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """One run of pendulum + kepler with the Rerun sink, the bag writer and a capture attached;
    then the bag converted. (run_scene makes its own rclpy context.)"""
    from mechsim.outputs.bag import BagWriter
    from mechsim.outputs.rerun import RerunSink, convert_bag
    from mechsim.ros.launch import run_scene
    from mechsim.scene import parse_scene

    d = tmp_path_factory.mktemp("rerun")
    scene = parse_scene({"name": "t", "publish_rate": RATE, "systems": [
        {"system": "pendulum", "parameters": {"initial.angle": 1.0}},
        {"system": "kepler", "origin": [3.0, 0.0, 0.0]}]})
    cap = Capture()
    live = RerunSink(d / "live.rrd")
    bag = BagWriter(d / "bag")
    run = run_scene(scene, fast=True, duration=DURATION, sinks=[cap, live, bag])
    live.close()
    bag.close()
    counts = convert_bag(d / "bag", d / "converted.rrd")
    return {"run": run, "cap": cap, "live": read_rrd(d / "live.rrd"),
            "converted": read_rrd(d / "converted.rrd"), "dir": d, "counts": counts}


def test_stores_and_timeline(recorded: dict[str, Any]) -> None:
    r = RrdReader(recorded["dir"] / "live.rrd")
    assert len(r.recordings()) == 1
    assert r.recordings()[0].application_id == "mechsim"
    assert len(r.blueprints()) >= 1
    # One timeline only: simulation time (no wall-clock log_time).
    assert [str(c) for c in r.store().schema().index_columns()] == ["Index(timeline:sim_time)"]
    world = recorded["live"]["/world"]["static"]
    # Rerun's ViewDir codes: Up 1, Down 2, Right 3, Left 4, Forward 5, Back 6. REP-103: x forward
    # is a convention of bodies; the world axes are x right, y forward, z up (right-handed).
    assert world["ViewCoordinates:xyz"] == [[3, 5, 1]]


def test_entities_of_frames_visuals_and_plots(recorded: dict[str, Any]) -> None:
    live = recorded["live"]
    expected = {
        # frames: entity tree = tf tree, transforms relative to the parent entity
        "/world/pendulum/pivot": "Transform3D:translation",
        "/world/pendulum/pivot/bob": "Transform3D:quaternion",
        "/world/kepler/perifocal/body": "Transform3D:translation",
        # visuals
        "/world/pendulum/visuals/link_pivot_bob": "LineStrips3D:strips",
        "/world/pendulum/visuals/trail_bob": "LineStrips3D:strips",
        "/world/kepler/visuals/trail_body": "LineStrips3D:strips",
        # plots
        "/plots/pendulum/balance_residual": "Scalars:scalars",
        "/plots/pendulum/observables/tension": "Scalars:scalars",
        "/plots/pendulum/state/angle": "Scalars:scalars",
        "/plots/pendulum/diagnostics/energy": "Scalars:scalars",
        "/plots/kepler/drift/angular_momentum": "Scalars:scalars",
        "/plots/kepler/drift/runge_lenz_x": "Scalars:scalars",
        "/plots/kepler/invariants/angular_momentum": "Scalars:scalars",
        "/plots/kepler/diagnostics/invariant/angular_momentum": "Scalars:scalars",
    }
    for ns in ("pendulum", "kepler"):
        for term in ("kinetic", "potential", "total", "energy_function", "work_external",
                     "work_dissipated"):
            expected[f"/plots/{ns}/energy/{term}"] = "Scalars:scalars"
    for entity, column in expected.items():
        assert entity in live, entity
        assert column in live[entity]["cols"], (entity, live[entity]["cols"].keys())
    sphere = live["/world/pendulum/pivot/bob/sphere"]["static"]
    assert sphere["Points3D:positions"] == [[0.0, 0.0, 0.0]]
    assert "SeriesLines:names" in live["/plots/pendulum/energy/total"]["static"]


def test_sample_counts_and_times(recorded: dict[str, Any]) -> None:
    live, cap, run = recorded["live"], recorded["cap"], recorded["run"]
    energy = cap.on("/pendulum/energy")
    n = int(round(DURATION * RATE)) + 1
    assert len(energy) == n == run.messages["/pendulum/energy"]
    total = live["/plots/pendulum/energy/total"]
    assert len(total["time"]) == n
    # sim_time = stamp − time offset, exactly (ns)
    assert total["time"].tolist() == [stamp_ns(m.header.stamp) - OFFSET_NS for m in energy]
    assert total["time"][0] == 0 and total["time"][-1] == int(DURATION * 1e9)
    np.testing.assert_array_equal(scalars(total), [m.total for m in energy])
    tf_with_bob = [m for m in cap.on("/tf")
                   if any(t.child_frame_id == "pendulum/bob" for t in m.transforms)]
    assert len(live["/world/pendulum/pivot/bob"]["time"]) == len(tf_with_bob) == n
    assert len(live["/world/pendulum/visuals/trail_bob"]["time"]) == n
    kepler_inv = cap.on("/kepler/invariants")
    assert len(live["/plots/kepler/drift/angular_momentum"]["time"]) == len(kepler_inv) == n


def test_balance_residual_and_drift_values(recorded: dict[str, Any]) -> None:
    live, cap = recorded["live"], recorded["cap"]
    energy = cap.on("/pendulum/energy")
    e0 = energy[0].total
    want = [(m.total - e0) - (m.work_external - m.work_dissipated) for m in energy]
    np.testing.assert_allclose(scalars(live["/plots/pendulum/balance_residual"]), want,
                               rtol=0, atol=1e-15)
    inv = cap.on("/kepler/invariants")
    k = [s.name for s in inv[0].scalars].index("angular_momentum")
    want = [m.scalars[k].value - inv[0].scalars[k].value for m in inv]
    np.testing.assert_allclose(scalars(live["/plots/kepler/drift/angular_momentum"]), want,
                               rtol=0, atol=1e-15)


def test_transforms_and_world_geometry(recorded: dict[str, Any]) -> None:
    live, cap = recorded["live"], recorded["cap"]
    bob_tf = [t for m in cap.on("/tf") for t in m.transforms if t.child_frame_id == "pendulum/bob"]
    bob = live["/world/pendulum/pivot/bob"]["cols"]
    i = len(bob_tf) // 3
    tr, q = bob_tf[i].transform.translation, bob_tf[i].transform.rotation
    np.testing.assert_allclose(bob["Transform3D:translation"][i][0], [tr.x, tr.y, tr.z], atol=1e-6)
    np.testing.assert_allclose(bob["Transform3D:quaternion"][i][0], [q.x, q.y, q.z, q.w],
                               atol=1e-6)  # xyzw, as in ROS
    # Trail and link live in world coordinates: the bob is 1 m (rod length) from the pivot.
    pivot = [t for m in cap.on("/tf_static") for t in m.transforms
             if t.child_frame_id == "pendulum/pivot"][0].transform.translation
    p0 = np.array([pivot.x, pivot.y, pivot.z])
    trail = strips(live["/world/pendulum/visuals/trail_bob"])
    link = strips(live["/world/pendulum/visuals/link_pivot_bob"])
    assert len(trail) == len(link) == len(bob_tf)
    for seg, ln in zip(trail, link, strict=True):
        a, b = np.array(seg[0]), np.array(seg[1])
        assert abs(np.linalg.norm(a - p0) - 1.0) < 1e-5
        assert abs(np.linalg.norm(b - p0) - 1.0) < 1e-5
        np.testing.assert_allclose(ln[0], p0, atol=1e-6)
        np.testing.assert_allclose(ln[1], b, atol=1e-6)
    for prev, seg in zip(trail, trail[1:], strict=False):  # consecutive segments join up
        np.testing.assert_allclose(prev[1], seg[0], atol=1e-7)
    # Kepler's origin [3, 0, 0] shows up in world.
    kepler_trail = strips(live["/world/kepler/visuals/trail_body"])
    assert np.mean([s[1][0] for s in kepler_trail]) > 1.5


def test_diagnostic_levels(recorded: dict[str, Any]) -> None:
    live, cap = recorded["live"], recorded["cap"]
    levels = [(stamp_ns(m.header.stamp) - OFFSET_NS, s.level[0]) for m in cap.on("/diagnostics")
              for s in m.status if s.name == "mechsim/pendulum/energy"]
    assert levels
    e = live["/plots/pendulum/diagnostics/energy"]
    assert e["time"].tolist() == [t for t, _ in levels]
    assert scalars(e).tolist() == [float(lv) for _, lv in levels]
    assert set(scalars(e)) <= {0.0, 1.0, 2.0, 3.0}


def test_convert_bag_gives_the_live_recording(recorded: dict[str, Any]) -> None:
    live, conv = recorded["live"], recorded["converted"]
    assert recorded["counts"]["/pendulum/energy"] == int(round(DURATION * RATE)) + 1
    assert sorted(conv) == sorted(live)
    for entity, e in live.items():
        c = conv[entity]
        assert c["time"].tolist() == e["time"].tolist(), entity
        assert sorted(c["cols"]) == sorted(e["cols"]), entity
        assert c["static"].keys() == e["static"].keys(), entity
    np.testing.assert_array_equal(scalars(conv["/plots/pendulum/energy/total"]),
                                  scalars(live["/plots/pendulum/energy/total"]))


def test_static_visual_kinds(tmp_path: Path) -> None:
    """box, polyline, axes visuals from a system_info message alone (no samples needed)."""
    from mechsim.outputs.rerun import RerunSink
    from mechsim_msgs.msg import SystemInfo

    path = tmp_path / "v.rrd"
    with RerunSink(path) as sink:
        for system, name in (("harmonic_oscillator", "osc"), ("moving_frames", "mf")):
            info = SystemInfo(instance=name, system=system, parameters_yaml="{}\n")
            info.header.stamp.sec = 1
            sink.write(f"/{name}/system_info", "mechsim_msgs/msg/SystemInfo", info, None,
                       1_000_000_000)
    got = read_rrd(path)
    assert "Boxes3D:half_sizes" in got["/world/osc/anchor/box"]["static"]
    polyline = got["/world/mf/polyline"]["static"]["LineStrips3D:strips"]
    assert len(polyline[0]) == 161  # the twisted cubic, in world
    for frame in ("vbn", "ric", "frenet"):
        assert math.isclose(got[f"/world/mf/{frame}"]["static"]["TransformAxes3D:axis_length"][0],
                            0.6, rel_tol=1e-6)


def test_view_without_display_prints_how(tmp_path: Path, recorded: dict[str, Any],
                                         monkeypatch: pytest.MonkeyPatch,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    from mechsim.cli import main

    rrd = recorded["dir"] / "live.rrd"
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", str(rrd)]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert len(out) == 1 and f"rerun --bind 127.0.0.1 --web-viewer {rrd}" in out[0]
    assert main(["view", str(tmp_path / "missing.rrd")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mechsim: error:")


def test_view_with_display_starts_the_viewer(recorded: dict[str, Any],
                                             monkeypatch: pytest.MonkeyPatch) -> None:
    import subprocess

    from mechsim.cli import main

    calls: list[list[str]] = []
    monkeypatch.setenv("DISPLAY", ":99")
    monkeypatch.setattr(subprocess, "call", lambda cmd: calls.append(cmd) or 0)
    rrd = recorded["dir"] / "live.rrd"
    assert main(["view", str(rrd)]) == 0
    assert Path(calls[0][0]).name == "rerun" and calls[0][-1] == str(rrd)
    assert calls[0][1:3] == ["--bind", "127.0.0.1"]


def test_cli_run_rrd_and_convert_errors(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    from mechsim.cli import main

    rrd = tmp_path / "out" / "p.rrd"
    assert main(["run", "pendulum", "--duration", "0.2", "--fast", "--rrd", str(rrd)]) == 0
    got = read_rrd(rrd)
    assert len(got["/plots/pendulum/energy/total"]["time"]) == 21  # 100 Hz, t = 0 … 0.2
    capsys.readouterr()
    assert main(["convert", str(tmp_path / "no_bag"), "--rrd", str(tmp_path / "x.rrd")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mechsim: error:")
    assert not (tmp_path / "x.rrd").exists()


def same_values(a: Any, b: Any) -> bool:
    """Equal, element by element, NaN equal to NaN."""
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(same_values(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(a == b)


def test_columns_and_messages_give_one_recording(tmp_path: Path) -> None:
    """A run's recording (drawn from the chunks' columns) equals the one converted from the
    same run's bag (drawn message by message), entity by entity, every row and value: frame
    chains of several depths, an attitude, many frames, more samples than one drawing
    takes."""
    import yaml

    from mechsim.cli import main

    scene = tmp_path / "scene.yaml"
    scene.write_text(yaml.safe_dump({"name": "columns", "publish_rate": 1000.0, "systems": [
        {"system": "double_pendulum"},
        {"system": "rigid_body", "origin": [3.0, 0.0, 0.0]},
        {"system": "two_body_field", "origin": [6.0, 0.0, 0.0]},
        {"system": "moving_frames", "origin": [9.0, 0.0, 0.0]},
        {"system": "gas_in_box", "origin": [12.0, 0.0, 0.0]}]}))
    bag, rrd, converted = tmp_path / "bag", tmp_path / "run.rrd", tmp_path / "converted.rrd"
    assert main(["run", str(scene), "--fast", "--duration", "1.5", "--bag", str(bag),
                 "--rrd", str(rrd)]) == 0
    assert main(["convert", str(bag), "--rrd", str(converted)]) == 0
    run, conv = read_rrd(rrd), read_rrd(converted)
    assert sorted(run) == sorted(conv)
    n = 1501  # 1000 Hz, t = 0 … 1.5: one drawing (``DRAW_ROWS``) and part of the next
    for entity in ("/plots/double_pendulum/energy/total", "/plots/gas_in_box/state/x_8",
                   "/world/double_pendulum/visuals/trail_bob_2",
                   "/plots/two_body_field/drift/angular_momentum_z"):
        assert len(run[entity]["time"]) == n, entity
    rows = 0
    for entity, e in run.items():
        c = conv[entity]
        assert c["time"].tolist() == e["time"].tolist(), entity
        if entity != "/__properties":  # the recording's own id and start time
            assert same_values(c["static"], e["static"]), entity
        assert sorted(c["cols"]) == sorted(e["cols"]), entity
        for column, values in e["cols"].items():
            assert same_values(c["cols"][column], values), (entity, column)
        rows += len(e["time"])
    assert rows > 100 * n


@pytest.mark.parametrize("path", ["columns", "messages"])
@pytest.mark.parametrize("draw_rows", [2, 1024])
def test_resets_rebase_drifts_and_trails(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                         path: str, draw_rows: int) -> None:
    """Samples whose time goes back (a reset), inside one chunk and across chunks, drawn in
    small or large blocks, from columns or from messages: the balance residual and the
    invariant drifts start again from the epoch's first sample (a constraint residual is
    drawn as it is), the trail restarts at the frame, and links and trails are composed
    through a rotated static parent."""
    from geometry_msgs.msg import TransformStamped

    import mechsim.outputs.rerun as rerun_output
    import mechsim.outputs.rerun.drawing as drawing
    from mechsim.outputs.messages import EnergyColumns, TransformColumns
    from mechsim_msgs.msg import Energy, NamedScalar, NamedScalars, SystemInfo
    from tf2_msgs.msg import TFMessage

    monkeypatch.setattr(drawing, "DRAW_ROWS", draw_rows)
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.0, 0.1, 0.2])  # reset after the 4th sample
    ns = (np.round(t * 1e9) + OFFSET_NS).astype(np.int64)
    total = np.array([5.0, 5.5, 6.0, 7.0, 2.0, 2.25, 3.0])
    w_ext = np.array([0.0, 0.25, 0.5, 1.0, 0.0, 0.5, 0.5])
    w_diss = np.array([0.0, 0.0, 0.125, 0.25, 0.0, 0.0, 0.5])
    momentum = np.array([1.0, 1.5, 0.5, 2.0, 4.0, 3.0, 8.0])
    residual = np.array([1e-9, -2e-9, 0.0, 3e-9, 5e-9, 0.0, -1e-9])
    bob = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0],
                    [1.0, 0.0, 0.0], [0.5, 0.5, 0.0], [0.0, 0.0, -1.0]])
    s45 = math.sqrt(0.5)
    pivot, turn = np.array([10.0, 0.0, 2.0]), np.array([0.0, 0.0, s45, s45])  # 90° about z
    chunks = [slice(0, 2), slice(2, 6), slice(6, 7)]  # the reset inside the second chunk

    sink = rerun_output.RerunSink(tmp_path / "r.rrd")
    info = SystemInfo(instance="pendulum", system="pendulum", parameters_yaml="{}\n")
    info.header.stamp.sec = 1
    sink.write("/pendulum/system_info", "mechsim_msgs/msg/SystemInfo", info, None, OFFSET_NS)
    static = TransformStamped()
    static.header.stamp.sec = 1
    static.header.frame_id, static.child_frame_id = "world", "pendulum/pivot"
    tr, q = static.transform.translation, static.transform.rotation
    tr.x, tr.y, tr.z = pivot.tolist()
    q.x, q.y, q.z, q.w = turn.tolist()
    sink.write("/tf_static", "tf2_msgs/msg/TFMessage", TFMessage(transforms=[static]), None,
               OFFSET_NS)
    poses = np.concatenate([bob, np.tile([0.0, 0.0, 0.0, 1.0], (len(t), 1))], axis=1)
    for rows in chunks:
        if path == "columns":
            sink.write_columns("/pendulum/energy", ns[rows], EnergyColumns(
                np.zeros(len(t))[rows], total[rows], total[rows], total[rows], w_ext[rows],
                w_diss[rows]))
            sink.write_columns("/pendulum/invariants", ns[rows], {
                "angular_momentum": momentum[rows], "constraint_rod": residual[rows]})
            sink.write_columns("/tf", ns[rows], TransformColumns(
                ["pendulum/pivot"], ["pendulum/bob"], poses[rows, None, :]))
            continue
        for i in range(len(t))[rows]:
            stamp = {"sec": int(ns[i]) // 1_000_000_000, "nanosec": int(ns[i]) % 1_000_000_000}
            e = Energy(kinetic=0.0, potential=total[i], total=total[i],
                       energy_function=total[i], work_external=w_ext[i],
                       work_dissipated=w_diss[i])
            e.header.stamp.sec, e.header.stamp.nanosec = stamp["sec"], stamp["nanosec"]
            sink.write("/pendulum/energy", "mechsim_msgs/msg/Energy", e, None, int(ns[i]))
            m = NamedScalars(scalars=[NamedScalar(name="angular_momentum", value=momentum[i]),
                                      NamedScalar(name="constraint_rod", value=residual[i])])
            m.header.stamp.sec, m.header.stamp.nanosec = stamp["sec"], stamp["nanosec"]
            sink.write("/pendulum/invariants", "mechsim_msgs/msg/NamedScalars", m, None,
                       int(ns[i]))
            tf = TransformStamped()
            tf.header.stamp.sec, tf.header.stamp.nanosec = stamp["sec"], stamp["nanosec"]
            tf.header.frame_id, tf.child_frame_id = "pendulum/pivot", "pendulum/bob"
            tf.transform.translation.x, tf.transform.translation.y = bob[i, 0], bob[i, 1]
            tf.transform.translation.z = bob[i, 2]
            sink.write("/tf", "tf2_msgs/msg/TFMessage", TFMessage(transforms=[tf]), None,
                       int(ns[i]))
    sink.close()
    got = read_rrd(tmp_path / "r.rrd")

    epoch = [0, 0, 0, 0, 4, 4, 4]  # each sample's epoch's first sample
    balance = total - (w_ext - w_diss)
    e = got["/plots/pendulum/balance_residual"]
    # Sorted by time: the two epochs interleave; compare as multisets of (time, value).
    want = sorted(zip(np.round(t * 1e9).astype(int).tolist(),
                      (balance - balance[epoch]).tolist(), strict=True))
    assert sorted(zip(e["time"].tolist(), scalars(e).tolist(), strict=True)) == want
    e = got["/plots/pendulum/drift/angular_momentum"]
    want = sorted(zip(np.round(t * 1e9).astype(int).tolist(),
                      (momentum - momentum[epoch]).tolist(), strict=True))
    assert sorted(zip(e["time"].tolist(), scalars(e).tolist(), strict=True)) == want
    e = got["/plots/pendulum/drift/constraint_rod"]
    want = sorted(zip(np.round(t * 1e9).astype(int).tolist(), residual.tolist(), strict=True))
    assert sorted(zip(e["time"].tolist(), scalars(e).tolist(), strict=True)) == want
    # The bob in world: the pivot's rotation (x -> y, y -> -x) applied to its offset.
    world = pivot + np.column_stack([-bob[:, 1], bob[:, 0], bob[:, 2]])
    previous = [0, 0, 1, 2, 4, 4, 5]  # the trail restarts at the reset
    want_trail = sorted(zip(np.round(t * 1e9).astype(int).tolist(),
                            [[world[p].tolist(), world[i].tolist()]
                             for i, p in enumerate(previous)], strict=True))
    e = got["/world/pendulum/visuals/trail_bob"]
    trail = sorted(zip(e["time"].tolist(), strips(e), strict=True))
    assert [w for w, _ in trail] == [w for w, _ in want_trail]
    for (_, seg), (_, want_seg) in zip(trail, want_trail, strict=True):
        np.testing.assert_allclose(seg, want_seg, rtol=0, atol=1e-6)  # float32 in the file
    e = got["/world/pendulum/visuals/link_pivot_bob"]
    link = sorted(zip(e["time"].tolist(), strips(e), strict=True))
    want_link = sorted(zip(np.round(t * 1e9).astype(int).tolist(),
                           [[pivot.tolist(), w.tolist()] for w in world], strict=True))
    for (tl, seg), (tw, want_seg) in zip(link, want_link, strict=True):
        assert tl == tw
        np.testing.assert_allclose(seg, want_seg, rtol=0, atol=1e-6)
