"""The machine-precision method ``radau15`` (adaptive 15th-order Gauss–Radau predictor–
corrector, the IAS15 scheme generalised to q̈ = f(t, q, q̇)): its nodes are the Gauss–Radau
nodes, it reaches round-off on Kepler's problem (against Kepler's equation in 40-digit
arithmetic) and on the CR3BP (against an independent 24-digit Taylor-series integration),
it handles velocity-dependent forces and the work terms (damped oscillator, closed form), and
its energy error grows like √N (Brouwer's law), not like N."""

from __future__ import annotations

import math

import mpmath as mp
import numpy as np
import pytest

import mechsim
from mechsim.integrators import Radau15, loops, make_stepper


def test_nodes_are_gauss_radau() -> None:
    """Eight nodes with the left end fixed integrate every polynomial of degree ≤ 14 exactly
    (weights from the first eight moments), and no set of eight nodes does better."""
    h = loops()._RADAU_NODES
    assert h[0] == 0.0 and np.all(np.diff(h) > 0) and h[-1] < 1.0
    V = np.vander(h, 8, increasing=True).T  # V[k, i] = h_i^k
    w = np.linalg.solve(V, 1.0 / np.arange(1, 9))
    for k in range(8, 15):
        assert w @ h**k == pytest.approx(1.0 / (k + 1), abs=1e-13), k
    assert abs(w @ h**15 - 1.0 / 16) > 1e-10


def _kepler_exact(t: float, e: float) -> np.ndarray:
    """State on the orbit a = GM = 1 through pericentre at t = 0 (Kepler's equation, 40 digits)."""
    mp.mp.dps = 40
    E = mp.findroot(lambda E: E - e * mp.sin(E) - mp.mpf(t), mp.mpf(t))
    b, rate = mp.sqrt(1 - e * e), 1 / (1 - e * mp.cos(E))
    return np.array([float(x) for x in (mp.cos(E) - e, b * mp.sin(E), -mp.sin(E) * rate,
                                        b * mp.cos(E) * rate)])


def test_kepler_100_orbits_at_round_off() -> None:
    """e = 0.5 … 0.515, 100 orbits: the end error is the random walk of round-off (the force is
    evaluated to a few ulps each time: Brouwer's law), a few 1e-12 for a = 1 — what IAS15
    reaches in double precision (REBOUND's IAS15 ends this problem 1.9e-12 … 1.3e-11 off,
    ``mechsim bench kepler``) — and never the truncation error (which would be 1e-10 … 1e-8
    at a tenth of the steps). A random walk scatters: measured on 64 orbits, e = 0.45 … 0.56,
    the median is 2e-12 … 2.5e-12 and the largest 7e-12 … 1e-11, so the median of 16 is
    judged, and the largest."""
    T = 100 * 2 * math.pi
    errors = []
    for i in range(16):
        e = 0.5 + 0.001 * i
        st = make_stepper(mechsim.load_system("kepler", eccentricity=e), "radau15", 1e-14)
        y = st.advance(np.array([T]))[0]
        errors.append(np.max(np.abs(y[:4] - _kepler_exact(T, e))))
        assert st.n_steps < 100 * 100  # ~60 an orbit
    assert np.median(errors) <= 5e-12 and max(errors) <= 2e-11, errors


#: The CR3BP of ``cr3bp``'s defaults in the synodic frame (ξ, η, ξ̇, η̇) at t = 5 and 10, from
#: mpmath's Taylor-series integrator (``mp.odefun``, 24 digits, tol 1e-20, degree 30) applied to
#: ξ̈ = 2η̇ + ξ − Gm₁(ξ − x₁)/r₁³ − Gm₂(ξ − x₂)/r₂³, η̈ = −2ξ̇ + η − Gm₁η/r₁³ − Gm₂η/r₂³
#: (ω = 1, x₁ = 0.1, x₂ = −0.9) from (0.5, 0, 0, 0.4).
_CR3BP = {5.0: (0.31148082724831824898, 0.20984717060921674642, 0.13555009829527978238,
                1.262638667278786942),
          10.0: (-0.042737015543874088867, -0.09698504071596258441, 2.4064073221489670269,
                 -0.38733697625408367298)}


def _inertial(u: tuple[float, ...], t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    x, y = c * u[0] - s * u[1], s * u[0] + c * u[1]
    return np.array([x, y, c * u[2] - s * u[3] - y, s * u[2] + c * u[3] + x])


@pytest.mark.parametrize("formulation", ["synodic", "inertial"])
def test_cr3bp_at_round_off(formulation: str) -> None:
    model = mechsim.load_system("cr3bp", formulation=formulation)
    times = np.array(sorted(_CR3BP))
    Y = make_stepper(model, "radau15", 1e-14).advance(times)[:, :4]
    # at 100 Hz, t = 5 falls inside a step: from its expansion, or from a step of its own
    Y100 = make_stepper(model, "radau15", 1e-14).advance(np.arange(1, 1001) / 100.0)
    for rows in (Y, Y100[[499, 999], :4]):
        for row, t in zip(rows, times, strict=True):
            ref = np.array(_CR3BP[t]) if formulation == "synodic" else _inertial(_CR3BP[t], t)
            assert np.max(np.abs(row - ref)) <= 1e-12, (t, row - ref)


def test_velocity_dependent_force_and_work_terms() -> None:
    """Damped oscillator: the damping force depends on q̇, the dissipated work is integrated
    alongside; both agree with the closed form to a few hundred ulps."""
    model = mechsim.load_system("damped_oscillator")
    t = np.linspace(0.0, 20.0, 41)
    Y = make_stepper(model, "radau15", 1e-14).advance(t)
    exact = model.propagate(0.0, model.initial_y(), t)
    assert exact is not None
    assert np.max(np.abs(Y[:, :2] - exact[:, :2])) < 3e-13
    assert np.max(np.abs(Y[:, 3] - exact[:, 3])) < 3e-13  # work_dissipated


def test_events_located_on_the_expansion() -> None:
    """A bead released at rest near the top of a sphere leaves it where cos θ = (2/3) cos θ₀
    (energy conservation and N = 0); radau15 finds the event there and continues in flight."""
    th0 = 0.3
    m = mechsim.load_system("sphere_slide", formulation="polar",
                            **{"initial.angle": th0, "initial_rate.angle": 0.0})
    st = make_stepper(m, "radau15", 1e-12)
    st.advance(np.array([3.0]))
    assert [name for _, name in st.events] == ["departure"]
    t_ev = st.events[0][0]
    y = make_stepper(m, "radau15", 1e-12).advance(np.array([t_ev]))[0]
    assert abs(math.cos(y[1]) - 2 * math.cos(th0) / 3) < 1e-10


def _relative(Y: np.ndarray, R: np.ndarray, n: int) -> float:
    """The larger error of q and of q̇, each relative to the reference's largest |q|, |q̇|."""
    return max(float(np.max(np.abs(Y[:, :n] - R[:, :n])) / np.max(np.abs(R[:, :n]))),
               float(np.max(np.abs(Y[:, n:2 * n] - R[:, n:2 * n])) / np.max(np.abs(R[:, n:2 * n]))))


@pytest.mark.parametrize(("system", "params"), [
    ("kepler", {"eccentricity": 0.5}), ("double_pendulum", {}), ("spherical_pendulum", {}),
    ("bead_on_wire", {})])
@pytest.mark.parametrize("tolerance", [1e-10, 1e-12])
def test_outputs_inside_steps_meet_the_tolerance(system: str, params: dict,
                                                 tolerance: float) -> None:
    """100 Hz outputs, asked for in blocks as a node does, over two orbits (Kepler) or two
    time scales (the double pendulum is chaotic): radau15 takes its own steps and gives the
    outputs inside them from each step's expansion (or from a step of their own where its
    error estimate is too large); against Kepler's equation, or DOP853 at 1e-14, they are
    within the tolerance of the state scale."""
    model = mechsim.load_system(system, **params)
    n = len(model.coordinates)
    span = 4 * math.pi if system == "kepler" else 2 * model.time_scale()
    t = np.arange(1, int(span * 100) + 1) / 100.0
    reference = make_stepper(model, "exact" if system == "kepler" else "dop853", 1e-14)
    R = reference.advance(t)
    st = make_stepper(model, "radau15", tolerance)
    Y = np.vstack([st.advance(t[i:i + 100]) for i in range(0, t.size, 100)])
    assert _relative(Y, R, n) <= tolerance
    if system == "kepler":
        assert st.n_steps < t.size / 5  # not a step per output


def test_outputs_the_expansion_cannot_give_take_steps_of_their_own() -> None:
    """Kepler (e = 0.5) at tolerance 1e-3 takes ~22 steps an orbit, whose expansions are off
    by up to ~7e-10 between the nodes; with outputs asked for within 1e-10, the outputs the
    step's error estimate does not clear take a step of their own from the step's start (as
    landing there would), and all are within 1e-10 of Kepler's equation — over the same
    steps as the run that takes every output from the expansions."""
    model = mechsim.load_system("kepler", eccentricity=0.5)
    t = np.arange(1, 1257) / 100.0
    R = make_stepper(model, "exact").advance(t)
    loose = make_stepper(model, "radau15", 1e-3)
    assert _relative(loose.advance(t), R, 2) > 1e-10  # the expansions alone would not do
    st = Radau15(model, model.initial_y(), 0.0, 1e-3, dense_tolerance=1e-10)
    Y = st.advance(t)
    assert _relative(Y, R, 2) <= 1e-10
    assert 0 < st.n_side < t.size  # both ways taken
    assert st.n_steps == loose.n_steps and np.array_equal(Y[-1], loose.advance(t[-1:])[0])


@pytest.mark.parametrize("system", ["gas_in_box", "sphere_slide", "collision"])
def test_events_match_dop853(system: str) -> None:
    """Events inside steps that also hold outputs: the same events at the same times (to
    1e-10 s) as DOP853 at 1e-14, and the outputs around them within 1e-10 of the state
    scale (radau15 at 1e-12, 100 Hz asked for in blocks)."""
    model = mechsim.load_system(system)
    n = len(model.coordinates)
    t = np.arange(1, 501) / 100.0
    reference = make_stepper(model, "dop853", 1e-14)
    R = reference.advance(t)
    st = make_stepper(model, "radau15", 1e-12)
    Y = np.vstack([st.advance(t[i:i + 100]) for i in range(0, t.size, 100)])
    assert [name for _, name in st.events] == [name for _, name in reference.events]
    assert st.events
    assert np.max(np.abs(np.array(st.events)[:, 0].astype(float)
                         - np.array(reference.events)[:, 0].astype(float))) <= 1e-10
    assert _relative(Y, R, n) <= 1e-10


def test_events_located_on_steps_of_their_own() -> None:
    """With every state inside a step taken by a step of its own (no trust in the expansion:
    ``dense_tolerance`` 0), the event search runs on those too: the bead still leaves the
    sphere where cos θ = (2/3) cos θ₀."""
    th0 = 0.3
    m = mechsim.load_system("sphere_slide", formulation="polar",
                            **{"initial.angle": th0, "initial_rate.angle": 0.0})
    st = Radau15(m, m.initial_y(), 0.0, 1e-12, dense_tolerance=0.0)
    st.advance(np.arange(1, 301) / 100.0)
    assert [name for _, name in st.events] == ["departure"] and st.n_side > 0
    y = make_stepper(m, "radau15", 1e-12).advance(np.array([st.events[0][0]]))[0]
    assert abs(math.cos(y[1]) - 2 * math.cos(th0) / 3) < 1e-10
