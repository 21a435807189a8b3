"""Two-body central-force problem (PHYS0500 ch. 4, Introduction to analytical mechanics, “Central
force problem – with two body” to “Closed orbits of the two body problem”): independent two-body
Newtonian integration, turning points, Kepler elements and conic classes, harmonic period, −a/r³
barrier and fall time."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp
from scipy.optimize import minimize_scalar

import mechsim
from mechsim.errors import ParameterError

M1, M2 = 1.0, 0.5
MU = M1 * M2 / (M1 + M2)


def load(**kw: object) -> mechsim.systems.base.Model:
    return mechsim.load_system("central_force", **kw)


def world_positions(r: mechsim.SimulationResult) -> tuple[np.ndarray, np.ndarray]:
    names = [f.child for f in r.model.frames]
    F = r.outputs.frames
    cm = F[:, names.index("cm"), :2]
    return cm + F[:, names.index("body_1"), :2], cm + F[:, names.index("body_2"), :2]


def newton_two_body(force: object, r1: np.ndarray, r2: np.ndarray, v1: np.ndarray,
                    v2: np.ndarray, t: np.ndarray) -> np.ndarray:
    """m₁ r̈₁ = F(r₁ − r₂), m₂ r̈₂ = −F: no reduced mass, no CM, no Lagrangian."""
    def f(_: float, s: np.ndarray) -> np.ndarray:
        d = s[0:2] - s[2:4]
        F = force(d)  # type: ignore[operator]
        return np.concatenate([s[4:8], F / M1, -F / M2])
    sol = solve_ivp(f, (t[0], t[-1]), np.concatenate([r1, r2, v1, v2]), method="DOP853",
                    rtol=1e-13, atol=1e-13, dense_output=True)
    return sol.sol(t).T


def initial_bodies(m: mechsim.systems.base.Model) -> tuple[np.ndarray, ...]:
    r0, th = m.value("initial.r"), m.value("initial.theta")
    dr, dth = m.value("initial_rate.r"), m.value("initial_rate.theta")
    rel = r0 * np.array([math.cos(th), math.sin(th)])
    vrel = dr * rel / r0 + r0 * dth * np.array([-math.sin(th), math.cos(th)])
    R = np.array([m.value("initial.cm_x"), m.value("initial.cm_y")])
    V = np.array([m.value("initial_rate.cm_x"), m.value("initial_rate.cm_y")])
    w1, w2 = M2 / (M1 + M2), M1 / (M1 + M2)
    return R + w1 * rel, R - w2 * rel, V + w1 * vrel, V - w2 * vrel


@pytest.fixture(scope="module")
def kepler_runs() -> dict[str, mechsim.SimulationResult]:
    out = {}
    for f in ("cartesian", "polar"):
        m = load(formulation=f, **{"initial.theta": 0.4, "initial.cm_y": 0.3,
                                   "initial_rate.cm_y": -0.05})
        out[f] = mechsim.simulate(m, 12.0, 0.01, tolerance=1e-12, method="dop853")
    return out


def test_kepler_matches_newtonian_two_body(kepler_runs: dict) -> None:
    for r in kepler_runs.values():
        ref = newton_two_body(lambda d: -1.0 * d / np.linalg.norm(d) ** 3,
                              *initial_bodies(r.model), r.t)
        b1, b2 = world_positions(r)
        assert np.max(np.abs(b1 - ref[:, 0:2])) < 1e-8
        assert np.max(np.abs(b2 - ref[:, 2:4])) < 1e-8
    a, b = kepler_runs["cartesian"], kepler_runs["polar"]
    assert np.max(np.abs(a.outputs.frames - b.outputs.frames)) < 1e-8


def test_cm_frame_and_bodies(kepler_runs: dict) -> None:
    r = kepler_runs["cartesian"]
    names = [f.child for f in r.model.frames]
    F = r.outputs.frames
    cm = F[:, names.index("cm"), :2]
    assert np.allclose(cm, np.stack([0.1 * r.t, 0.3 - 0.05 * r.t], axis=1), atol=1e-12)
    b1, b2 = F[:, names.index("body_1"), :2], F[:, names.index("body_2"), :2]
    assert np.allclose(M1 * b1 + M2 * b2, 0.0, atol=1e-12)  # CM at the cm frame origin
    assert np.allclose(np.hypot(*(b1 - b2).T), r.observables["radius"], atol=1e-12)
    for name in ("momentum_x", "momentum_y"):
        assert np.ptp(r.invariants[name]) < 1e-12


def test_kepler_elements_turning_points_and_invariants(kepler_runs: dict) -> None:
    r = kepler_runs["polar"]
    m = r.model
    k, l0 = 1.0, MU * 1.0 * 1.2
    E = 0.5 * MU * (0.3**2 + 1.2**2) - k
    assert m.relative_energy() == pytest.approx(E, rel=1e-15)
    # turning points: E r² + k r − l²/(2μ) = 0 (quadratic, independent of the module)
    disc = math.sqrt(k * k + 2 * E * l0 * l0 / MU)
    roots = sorted([(-k + disc) / (2 * E), (-k - disc) / (2 * E)])
    assert m.turning_points() == pytest.approx(roots, rel=1e-12)
    rad = r.observables["radius"]
    assert rad.min() == pytest.approx(roots[0], rel=1e-6)
    assert rad.max() == pytest.approx(roots[1], rel=1e-6)
    el = m.kepler_elements()
    eps = math.sqrt(1 + 2 * E * l0**2 / (MU * k * k))
    assert el["eccentricity"] == pytest.approx(eps, rel=1e-14)
    assert el["r_min"] == pytest.approx(roots[0], rel=1e-12)
    assert el["r_max"] == pytest.approx(roots[1], rel=1e-12)
    assert el["semi_major_axis"] == pytest.approx(sum(roots) / 2, rel=1e-12)
    assert np.allclose(r.observables["eccentricity"], eps, atol=1e-10)
    Ax, Ay = r.invariants["runge_lenz_x"], r.invariants["runge_lenz_y"]
    assert np.allclose(np.hypot(Ax, Ay), MU * k * eps, rtol=1e-10)
    assert np.ptp(Ax) < 1e-10 and np.ptp(Ay) < 1e-10
    assert np.ptp(r.invariants["angular_momentum"]) < 1e-10
    assert np.allclose(r.observables["areal_velocity"], l0 / (2 * MU), rtol=1e-10)
    # period: the relative orbit closes after 2π√(μa³/k)
    tau = el["period"]
    assert tau == pytest.approx(2 * math.pi * math.sqrt(MU * (sum(roots) / 2) ** 3 / k))
    r2 = mechsim.simulate(m, tau, tau / 4, tolerance=1e-12)
    assert r2.q[-1, 2] == pytest.approx(r2.q[0, 2], abs=1e-9)  # polar: r, θ + 2π
    assert math.remainder(r2.q[-1, 3] - r2.q[0, 3], 2 * math.pi) == pytest.approx(0, abs=1e-9)
    # perifocal frame x axis along the periapsis direction A
    names = [f.child for f in m.frames]
    q = r.outputs.frames[:, names.index("perifocal"), 3:]
    assert np.allclose(2 * np.arctan2(q[:, 2], q[:, 3]), np.arctan2(Ay, Ax), atol=1e-9)


@pytest.mark.parametrize(("rate", "dr", "cls"), [
    (math.sqrt(1.0 / MU), 0.0, "circle"), (1.2, -0.3, "ellipse"),
    (math.sqrt(2.0 / MU), 0.0, "parabola"), (2.0, 2.0, "hyperbola")])
def test_conic_table(rate: float, dr: float, cls: str) -> None:
    m = load(**{"initial_rate.theta": rate, "initial_rate.r": dr})
    assert m.orbit_class() == cls
    E = m.relative_energy()
    assert {"circle": E < 0, "ellipse": E < 0, "parabola": abs(E) < 1e-14,
            "hyperbola": E > 0}[cls]
    if cls == "circle":
        assert E == pytest.approx(m.kepler_elements()["effective_minimum"], rel=1e-14)


def test_harmonic_period_independent_of_energy() -> None:
    for dr, dth in ((-0.3, 1.2), (0.8, 0.4)):
        m = load(potential="harmonic", **{"initial_rate.r": dr, "initial_rate.theta": dth})
        T = m.harmonic_period()
        assert T == pytest.approx(2 * math.pi * math.sqrt(MU / 1.0))
        r = mechsim.simulate(m, 3 * T, T / 8, tolerance=1e-12)
        rel = r.q[:, 2:]
        assert np.allclose(rel[8], rel[0], atol=1e-10) and np.allclose(rel[24], rel[0],
                                                                      atol=1e-10)
        assert np.allclose(rel[4], -rel[0], atol=1e-10)  # centred ellipse: apsidal angle π/2
        # turning points: ½k r⁴ − E r² + l²/(2μ) = 0
        E, l = m.relative_energy(), MU * dth
        disc = math.sqrt(E * E - l * l / MU)
        assert m.turning_points() == pytest.approx(
            [math.sqrt(E - disc), math.sqrt(E + disc)], rel=1e-12)
        assert m.radial_period() == pytest.approx(T / 2, rel=1e-10)  # Δθ = π per radial period


def test_spring_turning_points_and_radial_period() -> None:
    m = load(potential="spring", spring_constant=3.0, rest_length=0.8)
    r = mechsim.simulate(m, 30.0, 0.002, tolerance=1e-12)
    rad = r.observables["radius"]
    lo, hi = m.radial_range()
    assert rad.min() == pytest.approx(lo, rel=1e-6) and rad.max() == pytest.approx(hi, rel=1e-6)
    # independent radial period: time between successive r minima (from the trajectory)
    idx = [i for i in range(1, rad.size - 1) if rad[i] < rad[i - 1] and rad[i] <= rad[i + 1]]
    assert np.diff(r.t[idx]).mean() == pytest.approx(m.radial_period(), abs=3e-3)
    assert np.ptp(r.total) < 1e-10 and np.ptp(r.invariants["angular_momentum"]) < 1e-12
    assert np.max(np.abs(r.balance_residual)) < 1e-10


def test_inverse_cube_barrier_and_reflection() -> None:
    m = load(potential="inverse_cube", **{"initial_rate.r": -0.5})
    rs, Vs = m.barrier()
    opt = minimize_scalar(lambda x: -m.effective_potential(x), bounds=(0.1, 3.0),
                          method="bounded", options={"xatol": 1e-12})
    assert rs == pytest.approx(opt.x, rel=1e-6)
    assert Vs == pytest.approx(-opt.fun, rel=1e-12)
    assert m.relative_energy() < Vs and not m.falls_to_centre()
    assert m.orbit_class() == "unbounded"
    r = mechsim.simulate(m, 20.0, 0.01, tolerance=1e-12)
    assert r.events == []
    assert r.observables["radius"].min() == pytest.approx(m.radial_range()[0], rel=1e-4)
    assert np.ptp(r.total) < 1e-10
    assert "invariant:angular_momentum" in [law.key for law in m.laws()]


def test_inverse_cube_fall_to_centre_event() -> None:
    a, rc = 0.1, 0.02
    times = []
    for f in ("cartesian", "polar"):
        m = load(formulation=f, potential="inverse_cube", **{"initial_rate.r": -0.8})
        assert m.falls_to_centre() and m.orbit_class() == "falls"
        assert m.relative_energy() > m.barrier()[1]
        assert [law.key for law in m.laws()] == ["work_balance", "invariant:momentum_x",
                                                 "invariant:momentum_y"]
        r = mechsim.simulate(m, 3.0, 0.01, tolerance=1e-12)
        assert [n for _, n in r.events] == ["fall"]
        times.append(r.events[0][0])
        after = r.t > r.events[0][0]
        assert np.allclose(r.observables["radius"][after], rc, atol=1e-9)
        assert np.max(np.abs(r.balance_residual)) < 1e-7
        assert np.allclose(r.work_dissipated[after], r.total[0] - r.total[after], atol=1e-7)
        for name in ("momentum_x", "momentum_y"):
            assert np.ptp(r.invariants[name]) < 1e-12
    # fall time t = ∫ dr / √((2/μ)(E − V_eff)) from r₀ to the capture radius (Introduction to
    # analytical mechanics, “Central force problem – with two body”)
    E, l = 0.5 * MU * (0.64 + 1.44) - a, MU * 1.2
    t_fall, _ = quad(lambda x: 1 / math.sqrt(2 / MU * (E + a / x**3 - l * l / (2 * MU * x * x))),
                     rc, 1.0, epsabs=1e-14, epsrel=1e-13)
    assert times == pytest.approx([t_fall, t_fall], rel=1e-8)


def test_long_run_kepler_symplectic() -> None:
    m = load()
    tau = m.kepler_elements()["period"]
    r = mechsim.simulate(m, 1000 * tau, tau / 3, outputs=("energy", "invariants"),
                         method="yoshida8")
    dE = np.abs(r.total - r.total[0]) / abs(r.total[0])
    assert dE.max() < 1e-6  # at default tolerance; bounded, largest at pericentre
    # no secular drift: the error of the last 100 orbits is not larger than of the first 100
    n = len(dE) // 10
    assert dE[-n:].max() < 3 * dE[:n].max() + 1e-12


def test_parameter_errors() -> None:
    with pytest.raises(ParameterError, match="^potential: must be one of"):
        load(potential="yukawa")
    with pytest.raises(ParameterError, match="^initial.r: must be > capture_radius"):
        load(potential="inverse_cube", capture_radius=2.0)
    with pytest.raises(ParameterError, match="^mass_2: must be > 0"):
        load(mass_2=0.0)
