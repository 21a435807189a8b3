"""Gas in a container (Introduction to analytical mechanics, “Classification of constraints”:
inequality constraints): point particles in a box with elastic walls. Oracle written here: walls ⟂
each axis make every coordinate an independent triangle wave (unfold the free motion s = s₀ + vt on
a circle of length 2ℓ), which gives the positions, the velocities, the hit times and counts, hence
the impulses on every wall; the time-averaged pressure then approaches (1/V)Σmvₐ² (= 2E/(3V)
isotropic) within 2Σm|vₐ|/(tA)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import mechsim
from mechsim.errors import ParameterError

ELL = np.array([2.0, 1.5, 1.0])  # default box
MASS = 1.0


def model(**kw):
    return mechsim.load_system("gas_in_box", **kw)


def unfolded(x0: np.ndarray, v0: np.ndarray, t: np.ndarray, ell: np.ndarray = ELL
             ) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities (len(t), N, 3) of free motion folded into [−ℓ/2, ℓ/2]."""
    s = (x0 + ell / 2)[None] + v0[None] * t[:, None, None]
    u = np.mod(s, 2 * ell)
    back = u > ell
    x = np.where(back, 2 * ell - u, u) - ell / 2
    v = np.where(back, -v0[None], v0[None]) * np.ones_like(s)
    return x, v


def hits(x0: np.ndarray, v0: np.ndarray, t: float, ell: np.ndarray = ELL
         ) -> tuple[np.ndarray, np.ndarray]:
    """Number of hits on the low and the high wall of each axis by time t, (N, 3) each: the
    unfolded coordinate s crosses 2ℓk (low wall) and ℓ + 2ℓk (high wall)."""
    s0 = x0 + ell / 2
    s1 = s0 + v0 * t
    lo, hi = np.minimum(s0, s1), np.maximum(s0, s1)

    def count(offset: np.ndarray) -> np.ndarray:
        return np.floor((hi - offset) / (2 * ell)) - np.floor((lo - offset) / (2 * ell))

    return count(0.0 * ell), count(ell)


@pytest.fixture(scope="module")
def run() -> mechsim.SimulationResult:
    return mechsim.simulate(model(), 400.0, 0.05, tolerance=1e-12)


def initial(run: mechsim.SimulationResult) -> tuple[np.ndarray, np.ndarray]:
    return run.q[0].reshape(-1, 3), run.v[0].reshape(-1, 3)


def test_start_is_inside_with_the_asked_energy(run: mechsim.SimulationResult) -> None:
    x0, v0 = initial(run)
    n = x0.shape[0]
    assert n == 8
    assert np.all(np.abs(x0) < ELL / 2)
    assert np.sum(v0**2) / n == pytest.approx(1.0, rel=1e-14)  # v_rms² = 1
    np.testing.assert_allclose(np.sum(v0**2, axis=0), n / 3, rtol=1e-14)  # isotropic


def test_motion_is_the_folded_free_flight(run: mechsim.SimulationResult) -> None:
    x0, v0 = initial(run)
    x, v = unfolded(x0, v0, run.t)
    np.testing.assert_allclose(run.q.reshape(x.shape), x, atol=1e-9)
    np.testing.assert_allclose(run.v.reshape(v.shape), v, atol=1e-12)
    # the inequality holds everywhere and every |vₐ| is conserved
    assert np.all(np.abs(run.q.reshape(x.shape)) <= ELL / 2 + 1e-12)
    assert np.max(np.ptp(np.abs(run.v.reshape(v.shape)), axis=0)) == 0.0


def test_event_times_and_impulses(run: mechsim.SimulationResult) -> None:
    x0, v0 = initial(run)
    # first hits of particle 1 on the high x wall: t_k = (ℓ/2 − x₀)/v + 2ℓk/v for v > 0, or
    # after the low wall first for v < 0
    vx, xx = v0[0, 0], x0[0, 0]
    first = (ELL[0] / 2 - xx) / vx if vx > 0 else (xx + ELL[0] / 2) / -vx + ELL[0] / -vx
    times = first + 2 * ELL[0] / abs(vx) * np.arange(5)
    got = run.event_times("wall_x_high_1")
    np.testing.assert_allclose(got[:5], times, rtol=1e-12)
    # every wall's accumulated impulse equals Σ 2m|vₐ| × hits (hits from the unfolding)
    low, high = hits(x0, v0, run.t[-1])
    for k, a in enumerate("xyz"):
        for side, n_hits in (("low", low), ("high", high)):
            expected = float(np.sum(2 * MASS * np.abs(v0[:, k]) * n_hits[:, k]))
            assert run.mode(f"impulse_{a}_{side}")[-1] == pytest.approx(expected, rel=1e-12)
            assert len(run.event_times(f"wall_{a}_{side}_1")) == int(n_hits[0, k])
    assert len(run.events) == int(np.sum(low) + np.sum(high))


def test_time_averaged_pressure(run: mechsim.SimulationResult) -> None:
    """P_wall(t) = impulse/(tA) → (1/V)Σmvₐ² = 2E/(3V); off by at most one hit per particle:
    |P_wall − P| ≤ 2Σm|vₐ|/(tA)."""
    x0, v0 = initial(run)
    V = float(np.prod(ELL))
    E = 0.5 * MASS * float(np.sum(v0**2))
    for k, a in enumerate("xyz"):
        P = MASS * float(np.sum(v0[:, k] ** 2)) / V
        assert P == pytest.approx(2 * E / (3 * V), rel=1e-13)
        np.testing.assert_allclose(run.observables[f"kinetic_pressure_{a}"], P, rtol=1e-13)
        area = V / ELL[k]
        bound = 2 * MASS * float(np.sum(np.abs(v0[:, k]))) / (run.t[1:] * area)
        for side in ("low", "high"):
            p = run.observables[f"pressure_{a}_{side}"]
            assert p[0] == 0.0
            assert np.all(np.abs(p[1:] - P) <= bound * (1 + 1e-9))
            assert abs(p[-1] - P) < 0.02 * P  # 400 s: ~1%
    np.testing.assert_allclose(run.observables["ideal_gas_pressure"], 2 * E / (3 * V),
                               rtol=1e-13)


def test_anisotropic_gas_pressure_per_axis() -> None:
    """Without equipartition each pair of walls sees its own (1/V)Σmvₐ², not 2E/(3V)."""
    mod = model(**{"initial.isotropic": False, "initial.seed": 7})
    run = mechsim.simulate(mod, 300.0, 1.0, tolerance=1e-12)
    x0, v0 = initial(run)
    V = float(np.prod(ELL))
    P = MASS * np.sum(v0**2, axis=0) / V
    assert np.ptp(P) > 0.1 * P.mean()
    np.testing.assert_allclose(mod.kinetic_pressure(), P, rtol=1e-14)
    for k, a in enumerate("xyz"):
        bound = 2 * MASS * float(np.sum(np.abs(v0[:, k]))) / (run.t[-1] * V / ELL[k])
        for side in ("low", "high"):
            assert abs(run.observables[f"pressure_{a}_{side}"][-1] - P[k]) <= bound


def test_long_run_conservation() -> None:
    run = mechsim.simulate(model(), 2000.0, 1.0, tolerance=1e-12)
    assert len(run.events) > 10000
    e0 = run.total[0]
    assert np.max(np.abs(run.total - e0)) < 1e-14 * e0
    for a in "xyz":
        assert np.ptp(run.invariants[f"kinetic_energy_{a}"]) < 1e-14 * e0
    assert np.max(np.abs(run.work_external)) == 0.0
    assert np.max(np.abs(run.work_dissipated)) == 0.0
    x0, v0 = initial(run)
    x, _ = unfolded(x0, v0, run.t[-10:])
    np.testing.assert_allclose(run.q[-10:].reshape(x.shape), x, atol=1e-8)


def test_names_and_laws() -> None:
    mod = model(count=2)
    d = mod.describe()
    assert [c["name"] for c in d["coordinates"]] == ["x_1", "y_1", "z_1", "x_2", "y_2", "z_2"]
    assert [e["name"] for e in d["events"]][:6] == [
        "wall_x_low_1", "wall_x_high_1", "wall_y_low_1", "wall_y_high_1", "wall_z_low_1",
        "wall_z_high_1"]
    assert all(e["direction"] == -1 for e in d["events"])
    assert d["modes"] == [f"impulse_{a}_{s}" for a in "xyz" for s in ("low", "high")]
    assert [law.key for law in mod.laws()] == [
        "energy", "energy_function", "work_balance", "invariant:kinetic_energy_x",
        "invariant:kinetic_energy_y", "invariant:kinetic_energy_z"]
    assert mod.ideal_gas_pressure() == pytest.approx(2 * 0.5 * 2 * 1.0 / (3 * math.prod(ELL)))


@pytest.mark.parametrize("kw,field", [({"count": 0}, "count"), ({"count": 33}, "count"),
                                      ({"box_length_y": 0.0}, "box_length_y"),
                                      ({"initial.rms_speed": -1.0}, "initial.rms_speed"),
                                      ({"initial.isotropic": "maybe"}, "initial.isotropic")])
def test_parameter_validation(kw: dict, field: str) -> None:
    with pytest.raises(ParameterError) as err:
        model(**kw)
    assert err.value.field == field


def test_a_node_keeps_no_record_of_past_bounces(ros_context: object) -> None:
    """simulate() returns the wall events; a node, which may run for ever, keeps none (the
    record grew by ~8 events per simulated second: gigabytes over a long fast recording)."""
    from mechsim.ros.launch import run_scene
    from mechsim.scene import parse_scene

    nodes: list[object] = []
    scene = parse_scene({"name": "gas", "pacing": "fast",
                         "systems": [{"system": "gas_in_box", "name": "gas"}]})
    run = run_scene(scene, fast=True, duration=60.0, context=ros_context,
                    before_first_message=nodes.append)
    assert not run.failures and len(nodes) == 1
    stepper = nodes[0].stepper  # type: ignore[attr-defined]
    assert stepper.events == []
    assert stepper._last_event_t > 30.0  # it bounced all along (the Zeno check's record)
