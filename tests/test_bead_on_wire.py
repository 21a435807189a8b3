"""Bead on a wire (“Dynamical Systems and Constraints: Part 2 – Bead on a Wire”): line and parabola
in the reduced, multiplier and the document's naive forms. Oracles computed here, independently of
the model: uniform acceleration on a line, the exact parabola period by mpmath quadrature of the
energy integral, and the document's own naive equations integrated with scipy (the catalog's
285.35 / 1133.9 figures)."""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import mechsim
from mechsim.errors import ParameterError

G, MASS = 9.81, 0.8


def _bead(**kw: object) -> mechsim.systems.base.Model:
    return mechsim.load_system("bead_on_wire", gravity=G, mass=MASS, **kw)


@pytest.mark.parametrize("form", ["reduced", "naive"])
def test_line_uniform_acceleration_and_chord_time(form: str) -> None:
    a = 0.7  # chord of a cycloid of radius a: from (0, 0) to (πa, −2a)
    s = -2 / math.pi
    m = _bead(formulation=form, shape="line", slope=s, **{"initial.x": 0.0})
    t_chord = math.sqrt((math.pi**2 + 4) * a / G)  # catalog 001 §2.12: √((π²+4)a/g)
    run = mechsim.simulate(m, t_chord, t_chord / 50, tolerance=1e-12, method="dop853")
    x = run.q[:, 0]
    np.testing.assert_allclose(x, -0.5 * G * s / (1 + s * s) * run.t**2, rtol=1e-11, atol=1e-13)
    assert abs(x[-1] - math.pi * a) < 1e-10
    assert t_chord > math.pi * math.sqrt(a / G)  # slower than the cycloid (brachistochrone)
    # On a straight wire even the naive form keeps the bead on the wire and conserves energy.
    assert np.max(np.abs(run.total - run.total[0])) < 1e-11 * MASS * G
    if form == "naive":
        assert np.max(np.abs(run.invariants["constraint_wire"])) < 1e-12


def _parabola_period(c: float, A: float) -> float:
    """4 ∫₀ᴬ √((1 + 4c²x²) / (2gc(A² − x²))) dx, from ½(1 + f′²)ẋ² + g f = g c A²;
    with x = A sin φ: 4 ∫₀^{π/2} √((1 + 4c²A² sin²φ) / (2gc)) dφ."""
    mpmath.mp.dps = 30
    f = lambda p: mpmath.sqrt((1 + 4 * c * c * A * A * mpmath.sin(p) ** 2) / (2 * G * c))  # noqa: E731
    return float(4 * mpmath.quad(f, [0, mpmath.pi / 2]))


@pytest.mark.parametrize("form", ["reduced", "multiplier"])
@pytest.mark.parametrize(("c", "A"), [(1.0, 1.0), (0.5, 2.0), (1.0, 1e-3)])
def test_parabola_exact_period(form: str, c: float, A: float) -> None:
    T = _parabola_period(c, A)
    if A < 0.01:
        assert abs(T - 2 * math.pi / math.sqrt(2 * G * c)) < 1e-5 * T  # small oscillations
    m = _bead(formulation=form, curvature=c, **{"initial.x": A})
    run = mechsim.simulate(m, T, T / 40, tolerance=1e-13)
    assert abs(run.q[-1, 0] - A) < 1e-9 * A
    assert abs(run.v[-1, 0]) < 1e-8 * A * math.sqrt(G * c)
    assert abs(run.q[20, 0] + A) < 1e-9 * A  # half a period: the other turning point


def test_formulations_agree_and_normal_force() -> None:
    kw = {"curvature": 0.8, "initial.x": 1.2, "initial_rate.x": -0.5}
    red = mechsim.simulate(_bead(formulation="reduced", **kw), 6.0, 0.02, tolerance=1e-12)
    mul = mechsim.simulate(_bead(formulation="multiplier", **kw), 6.0, 0.02, tolerance=1e-12)
    np.testing.assert_allclose(red.q[:, 0], mul.q[:, 0], atol=1e-8)
    np.testing.assert_allclose(red.v[:, 0], mul.v[:, 0], atol=1e-7)
    # The reduced form's closed-form normal force equals the multiplier's constraint force.
    np.testing.assert_allclose(red.observables["normal_force"], mul.observables["normal_force"],
                               rtol=1e-7)
    x, v = red.q[:, 0], red.v[:, 0]
    c = 0.8
    np.testing.assert_allclose(red.observables["normal_force"],
                               MASS * (G + 2 * c * v**2) / np.sqrt(1 + 4 * c * c * x * x),
                               rtol=1e-12)
    for r in (red, mul):
        assert np.max(np.abs(r.total - r.total[0])) < 1e-10 * MASS * G
        assert np.max(np.abs(r.balance_residual)) < 1e-10 * MASS * G
        assert np.max(np.abs(r.energy_function - r.total)) < 1e-10 * MASS * G
    assert np.max(np.abs(mul.invariants["constraint_wire"])) < 1e-13


def _document_form_a(t_end: float, rtol: float) -> tuple[np.ndarray, np.ndarray]:
    """The document's roller_coaster (L153–163) on y = x², from (1, 1) at rest, with scipy."""
    def rhs(t: float, s: np.ndarray) -> list[float]:
        x, y, vx, vy = s
        df = 2 * x
        tau = 1.0 / (1.0 + df**2)
        return [vx, vy, -G * tau * df, -G * tau * df**2]
    t = np.linspace(0.0, t_end, 1001)
    sol = solve_ivp(rhs, (0.0, t_end), [1.0, 1.0, 0.0, 0.0], method="DOP853", t_eval=t,
                    rtol=rtol, atol=1e-12)
    return sol.t, sol.y


def test_naive_form_violates_constraint_and_energy_by_design() -> None:
    m = _bead(formulation="naive", **{"initial.x": 1.0})
    keys = [law.key for law in m.laws()]
    assert "energy" in keys and "constraint:constraint_wire" in keys
    assert "energy_function" not in keys
    run = mechsim.simulate(m, 10.0, 0.01, tolerance=1e-12)
    t, ref = _document_form_a(10.0, 1e-12)
    # Same equations as the document: agree with scipy over the first second.
    early = run.t <= 1.0
    np.testing.assert_allclose(run.q[early], ref[:2, :101].T, atol=1e-8)
    off = run.invariants["constraint_wire"]
    de = (run.total - run.total[0]) / MASS
    # Catalog: max |y − x²| ≈ 285.35 and max |ΔE|/m ≈ 1133.9, independent of the tolerance.
    ref_off = ref[1] - ref[0] ** 2
    ref_de = 0.5 * (ref[2] ** 2 + ref[3] ** 2) + G * ref[1] - G
    for rtol in (1e-8,):
        _, ref2 = _document_form_a(10.0, rtol)
        assert abs(np.max(np.abs(ref2[1] - ref2[0] ** 2)) - np.max(np.abs(ref_off))) < 0.05
    assert abs(np.max(np.abs(off)) - np.max(np.abs(ref_off))) < 1e-3 * np.max(np.abs(ref_off))
    assert abs(np.max(np.abs(de)) - np.max(np.abs(ref_de))) < 1e-3 * np.max(np.abs(ref_de))
    assert abs(np.max(np.abs(off)) - 285.35) < 0.01 and abs(np.max(np.abs(de)) - 1133.9) < 0.1
    assert off[5] < 0 and off[50] < 0  # "dropping below" the wire (L182)
    # The diagnostics see it: both laws fail far beyond any threshold, the balance holds.
    scales = m.law_scales()
    assert np.max(np.abs(run.total - run.total[0])) / scales["energy"] > 10
    assert np.max(np.abs(off)) / scales["constraint:constraint_wire"] > 10
    assert np.max(np.abs(run.balance_residual)) < 1e-9 * scales["work_balance"]


def test_parameter_validation() -> None:
    with pytest.raises(ParameterError, match="^shape: must be one of"):
        _bead(shape="helix")
    with pytest.raises(ParameterError, match="^formulation: naive needs a wire"):
        _bead(shape="cycloid", formulation="naive")
    with pytest.raises(ParameterError, match="^initial.x: must be in"):
        _bead(shape="cycloid", **{"initial.x": -1.0})
    with pytest.raises(ParameterError, match="^initial.x: the multiplier form cannot start"):
        _bead(shape="cycloid", formulation="multiplier", **{"initial.x": 0.0})
    for bad, why in [("__import__('os')", "not allowed"), ("x.real", "not allowed"),
                     ("y + 1", "not allowed"), ("x +", "cannot read"), ("lambda: 1", "not "
                     "allowed"), ("sqrt(x - 5)", "not finite and real")]:
        with pytest.raises(ParameterError, match=f"^curve: .*{why}") as err:
            _bead(shape="custom", curve=bad)
        assert "\n" not in str(err.value)
