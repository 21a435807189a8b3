"""Two bodies in a uniform field (Introduction to analytical mechanics, “Central force problem –
with two body”): the centre of mass falls on the parabola R₀ + V₀t − ½gt²ẑ; the relative motion is
the Kepler orbit, here from Kepler's equation solved with mpmath (elements written out in the test);
L and the LRL vector conserved; both formulations agree with each other and with a Newtonian
integration of m₁r̈₁ = m₁g + F,
m₂r̈₂ = m₂g − F by scipy."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

import mechsim
from mechsim.errors import ParameterError

M1, M2, K, G = 1.0, 0.5, 1.0, 9.81
MU = M1 * M2 / (M1 + M2)


def model(**kw):
    return mechsim.load_system("two_body_field", **kw)


def kepler_orbit(r0: np.ndarray, v0: np.ndarray, gm: float, t: np.ndarray) -> np.ndarray:
    """r(t) of r̈ = −GM r/r³ on an ellipse: elements from (r₀, v₀), Kepler's equation
    E − e sin E = M₀ + nt solved by mpmath, position a(cos E − e)P̂ + b sin E Q̂."""
    h = np.cross(r0, v0)
    r = float(np.linalg.norm(r0))
    ecc = np.cross(v0, h) / gm - r0 / r
    e = float(np.linalg.norm(ecc))
    a = 1.0 / (2.0 / r - float(v0 @ v0) / gm)
    P = ecc / e
    Q = np.cross(h / np.linalg.norm(h), P)
    E0 = math.atan2(float(r0 @ v0) / (e * math.sqrt(gm * a)), (1 - r / a) / e)
    M0 = E0 - e * math.sin(E0)
    n = math.sqrt(gm / a**3)
    out = []
    for tk in t:
        M = M0 + n * tk
        E = float(mpmath.findroot(lambda x, M=M: x - e * mpmath.sin(x) - M, M))
        out.append(a * (math.cos(E) - e) * P + a * math.sqrt(1 - e * e) * math.sin(E) * Q)
    return np.array(out)


def relative(run: mechsim.SimulationResult) -> np.ndarray:
    if run.model.formulation == "cm":
        return run.q[:, 3:6]
    return run.q[:, 0:3] - run.q[:, 3:6]


def cm(run: mechsim.SimulationResult) -> np.ndarray:
    if run.model.formulation == "cm":
        return run.q[:, 0:3]
    return (M1 * run.q[:, 0:3] + M2 * run.q[:, 3:6]) / (M1 + M2)


@pytest.fixture(scope="module", params=["cm", "bodies"])
def run(request: pytest.FixtureRequest) -> mechsim.SimulationResult:
    return mechsim.simulate(model(formulation=request.param), 6.0, 0.02, tolerance=1e-13,
                            method="dop853")


def test_centre_of_mass_falls_freely(run: mechsim.SimulationResult) -> None:
    t = run.t
    expected = np.stack([1.0 * t, 0 * t, 8.0 * t - 0.5 * G * t**2], axis=1)
    np.testing.assert_allclose(cm(run), expected, atol=1e-9)
    np.testing.assert_allclose(run.model.cm_position(t), expected, atol=1e-12)
    np.testing.assert_allclose(run.observables["cm_height"], expected[:, 2], atol=1e-9)
    np.testing.assert_allclose(run.invariants["momentum_z_falling_frame"], (M1 + M2) * 8.0,
                               rtol=1e-12)
    # the frame ``cm`` is posed there
    np.testing.assert_allclose(run.outputs.frames[:, 0, :3], expected, atol=1e-9)


def test_relative_motion_is_the_kepler_orbit(run: mechsim.SimulationResult) -> None:
    r0, v0 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.2, 0.4])
    exact = kepler_orbit(r0, v0, K / MU, run.t[::10])
    np.testing.assert_allclose(relative(run)[::10], exact, atol=1e-9)


def test_orbit_plane_and_vectors(run: mechsim.SimulationResult) -> None:
    r0, v0 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.2, 0.4])
    L0 = MU * np.cross(r0, v0)
    A0 = MU * np.cross(v0, L0) - MU * K * r0 / np.linalg.norm(r0)
    inv = run.invariants
    L = np.stack([inv[f"angular_momentum_{c}"] for c in "xyz"], axis=1)
    A = np.stack([inv[f"runge_lenz_{c}"] for c in "xyz"], axis=1)
    np.testing.assert_allclose(L, np.broadcast_to(L0, L.shape), atol=1e-11)
    np.testing.assert_allclose(A, np.broadcast_to(A0, A.shape), atol=1e-10)
    # the relative orbit stays in the plane normal to L
    assert np.max(np.abs(relative(run) @ (L0 / np.linalg.norm(L0)))) < 1e-11
    # eccentricity |A|/(μk) equals √(1 + 2El²/(μk²))
    E = 0.5 * MU * float(v0 @ v0) - K
    e = math.sqrt(1 + 2 * E * float(L0 @ L0) / (MU * K * K))
    np.testing.assert_allclose(run.observables["eccentricity"], e, rtol=1e-10)
    # the orbit frame: z along L, x toward periapsis (along A)
    q = run.outputs.frames[:, 3, 3:]
    rot = Rotation.from_quat(q).as_matrix()
    np.testing.assert_allclose(rot[:, :, 2], np.broadcast_to(L0 / np.linalg.norm(L0),
                                                             (q.shape[0], 3)), atol=1e-10)
    np.testing.assert_allclose(rot[:, :, 0], np.broadcast_to(A0 / np.linalg.norm(A0),
                                                             (q.shape[0], 3)), atol=1e-9)


def test_agrees_with_newtonian_integration() -> None:
    """scipy on m₁r̈₁ = m₁g + F, m₂r̈₂ = m₂g − F, F = −k r/r³ (the document's L1416–1485)."""
    mod = model(formulation="bodies")
    q0, v0 = mod.initial_state()
    g = np.array([0.0, 0.0, -G])

    def rhs(_t: float, s: np.ndarray) -> np.ndarray:
        r1, r2, u1, u2 = s[0:3], s[3:6], s[6:9], s[9:12]
        d = r1 - r2
        F = -K * d / np.linalg.norm(d) ** 3
        return np.concatenate([u1, u2, g + F / M1, g - F / M2])

    t = np.linspace(0.0, 4.0, 81)
    ref = solve_ivp(rhs, (0, 4.0), np.concatenate([q0, v0]), t_eval=t, method="DOP853",
                    rtol=1e-13, atol=1e-13)
    run = mechsim.simulate(mod, 4.0, 0.05, tolerance=1e-13, method="dop853")
    np.testing.assert_allclose(run.q, ref.y[:6].T, atol=1e-9)
    cmrun = mechsim.simulate(model(formulation="cm"), 4.0, 0.05, tolerance=1e-13)
    np.testing.assert_allclose(cm(cmrun), cm(run), atol=1e-9)
    np.testing.assert_allclose(relative(cmrun), relative(run), atol=1e-9)
    np.testing.assert_allclose(cmrun.total, run.total, rtol=1e-10)


def test_long_run_conservation() -> None:
    """200 relative periods: relative energy, L and A hold; the fall stays on its parabola."""
    mod = model(**{"initial_rate.cm_z": 0.0})
    period = 2 * math.pi * math.sqrt(mod.kepler_elements()["semi_major_axis"] ** 3 * MU / K)
    run = mechsim.simulate(mod, 200 * period, period / 10, tolerance=1e-13, method="yoshida8")
    e0 = run.invariants["relative_energy"][0]
    assert np.max(np.abs(run.invariants["relative_energy"] - e0)) < 1e-9 * abs(e0)
    for c in "xyz":
        a = run.invariants[f"runge_lenz_{c}"]
        assert np.ptp(a) < 1e-8 * MU * K
        assert np.ptp(run.invariants[f"angular_momentum_{c}"]) < 1e-10
    z = cm(run)[:, 2]
    np.testing.assert_allclose(z, -0.5 * G * run.t**2, rtol=1e-10)
    # total = CM part (each term ~1e7 J by the end, so round-off) + the relative part
    assert np.max(np.abs(run.total - run.total[0])) < 1e-10 * np.max(np.abs(run.potential))


def test_time_scale_and_elements() -> None:
    mod = model()
    el = mod.kepler_elements()
    v0 = np.array([0.0, 1.2, 0.4])
    E = 0.5 * MU * float(v0 @ v0) - K
    assert el["semi_major_axis"] == pytest.approx(K / (2 * abs(E)), rel=1e-14)
    # v₀ ⟂ r₀ below the circular speed √(GM/r₀) = √3: r₀ = 1 is the apocentre
    assert el["r_max"] == pytest.approx(1.0, rel=1e-12)
    assert el["r_min"] == pytest.approx(2 * el["semi_major_axis"] - 1.0, rel=1e-12)
    assert 0 < mod.time_scale() < 2 * math.pi * math.sqrt(el["semi_major_axis"] ** 3 * MU / K)


@pytest.mark.parametrize("kw,field", [
    ({"initial.x": 0.0}, "initial.x"),
    ({"initial_rate.y": 0.0, "initial_rate.z": 0.0, "initial_rate.x": 1.0}, "initial_rate.x"),
    ({"gravity": -1.0}, "gravity"), ({"mass_1": 0.0}, "mass_1")])
def test_parameter_validation(kw: dict, field: str) -> None:
    with pytest.raises(ParameterError) as err:
        model(**kw)
    assert err.value.field == field


def test_auto_on_the_long_fall() -> None:
    """auto at 1e-13 over 200 periods takes radau15, which must neither stop nor let the
    falling centre of mass (|R| ~ 8e5 m by the end) loosen its control of the orbit: the
    relative orbit ends on Kepler's (measured 4e-13; before the fix radau15 stopped with a
    step-size underflow, and with that fixed alone ended 2e-4 off), the fall on its parabola."""
    mod = model(**{"initial_rate.cm_z": 0.0})
    period = 2 * math.pi * math.sqrt(mod.kepler_elements()["semi_major_axis"] ** 3 * MU / K)
    run = mechsim.simulate(mod, 200 * period, period / 10, tolerance=1e-13)
    assert run.method == "radau15"
    r0, v0 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.2, 0.4])
    exact = kepler_orbit(r0, v0, K / MU, run.t[-20:])
    assert np.max(np.abs(relative(run)[-20:] - exact)) < 1e-10
    np.testing.assert_allclose(cm(run)[:, 2], -0.5 * G * run.t**2, rtol=1e-12)
