"""Curves published once per parameter set: the effective potential of a Kepler orbit
(PHYS0500 – Advanced Classical Mechanics, §4.5) and the heavy top's V(θ) (§7.8.1), on the
latched ``<ns>/curves`` topic and in the Rerun recording. The numbers are checked against
U_eff, E and the turning points written here from the initial state."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

import mechsim
from mechsim.outputs.messages import MessageFactory

M1, M2, K, R0, DR0, DTH0 = 1.2, 0.6, 1.5, 1.1, -0.2, 1.0


def _orbit() -> tuple[float, float, float]:
    """μ, l and E of the relative orbit, from the initial state."""
    mu = M1 * M2 / (M1 + M2)
    return mu, mu * R0**2 * DTH0, 0.5 * mu * (DR0**2 + R0**2 * DTH0**2) - K / R0


def _model() -> mechsim.Model:
    return mechsim.load_system("central_force", mass_1=M1, mass_2=M2, force_constant=K,
                               **{"initial.r": R0, "initial_rate.r": DR0,
                                  "initial_rate.theta": DTH0})


def test_effective_potential_markers_are_the_orbit_s() -> None:
    mu, l, E = _orbit()
    markers = MessageFactory(_model(), "orbit").curves(123).markers
    curve, level = markers
    assert curve.ns == level.ns == "orbit/effective_potential"
    assert "U_eff [J] against r [m]" == curve.text
    r = np.array([p.x for p in curve.points])
    u = np.array([p.y for p in curve.points])
    assert np.max(np.abs(u - (-K / r + l * l / (2 * mu * r * r)))) < 1e-12
    assert [p.y for p in level.points] == [E, E]
    # turning points: roots of E r² + K r − l²/(2μ) = 0, named in the level's text
    disc = math.sqrt(K * K + 2 * E * l * l / mu)
    r_min, r_max = (-K + disc) / (2 * E), (-K - disc) / (2 * E)
    assert f"{r_min:.6g}" in level.text and f"{r_max:.6g}" in level.text


def test_a_model_without_curves_has_none() -> None:
    assert mechsim.load_system("pendulum").curves() == ()
    assert not MessageFactory(mechsim.load_system("pendulum"), "p").curves(0).markers


def test_recorded_latched_and_drawn(tmp_path: Path) -> None:
    """``mechsim record`` of the heavy top: one transient-local message on
    /symmetric_top/curves with V(θ) and E′, and the same curve in the Rerun recording."""
    from test_rerun import read_rrd  # the recording reader of the Rerun tests

    bag, rrd = tmp_path / "bag", tmp_path / "top.rrd"
    r = subprocess.run([sys.executable, "-m", "mechsim.cli", "record", "symmetric_top",
                        "--duration", "0.5", "--bag", str(bag), "--rrd", str(rrd)],
                       capture_output=True, text=True, timeout=600,
                       env={**os.environ, "MECHSIM_GRAPH_WAIT": "0"})
    assert r.returncode == 0, r.stderr
    top = mechsim.load_system("symmetric_top")
    theta = np.linspace(0.02, math.pi - 0.02, 400)
    with (next(bag.glob("*.mcap"))).open("rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        channels = {c.topic: c for c in reader.get_summary().channels.values()}
        assert "transient_local" in channels["/symmetric_top/curves"].metadata[
            "offered_qos_profiles"]
        got = [m for _, _, _, m in reader.iter_decoded_messages(
            topics=["/symmetric_top/curves"])]
    assert len(got) == 1
    curve, level = got[0].markers
    x = np.array([p.x for p in curve.points])
    assert np.allclose(x, theta, rtol=0, atol=1e-15)
    assert np.max(np.abs(np.array([p.y for p in curve.points])
                         - top.effective_potential(theta))) < 1e-12
    drawn = read_rrd(rrd)
    strip = drawn["/curves/symmetric_top/top_potential/curve"]["static"]
    points = np.array(strip["LineStrips2D:strips"][0])
    assert np.allclose(points[:, 0], x) and np.allclose(points[:, 1], [p.y for p in curve.points])
    assert "/curves/symmetric_top/top_potential/level_0" in drawn
