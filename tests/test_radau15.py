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
from mechsim.integrators import loops, make_stepper


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
    """e = 0.5 … 0.503, 100 orbits: the end error is the random walk of round-off (the force is
    evaluated to a few ulps each time: Brouwer's law), about 1e-12 for a = 1 — what IAS15
    reaches in double precision — and never the truncation error (which would be 1e-10 …
    1e-8 at a tenth of the steps)."""
    T = 100 * 2 * math.pi
    errors = []
    for e in (0.5, 0.501, 0.502, 0.503):
        st = make_stepper(mechsim.load_system("kepler", eccentricity=e), "radau15", 1e-14)
        y = st.advance(np.array([T]))[0]
        errors.append(np.max(np.abs(y[:4] - _kepler_exact(T, e))))
        assert st.n_steps < 100 * 100  # ~60 an orbit
    assert np.median(errors) <= 2e-12 and max(errors) <= 1e-11, errors


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
    for row, t in zip(Y, times, strict=True):
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
