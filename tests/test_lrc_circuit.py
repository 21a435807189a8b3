"""Series LRC circuit (PHYS0500 §1.7): oracles from circuit theory written here (sympy's
solution of Kirchhoff's law, the complex impedance, half-power points), the Joule heat as the
dissipated work, and the same trajectory as the mechanical analogue under the table's mapping
(both integrated from their own declarations)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import cumulative_simpson

import mechsim
from mechsim.errors import ParameterError

L, R, C = 1.0, 0.4, 0.25  # defaults: ω₀ = 2 rad/s, β = 0.2 /s, Q = 5


def circuit(**kw):
    return mechsim.load_system("lrc_circuit", **kw)


def steady_current(omega: float, periods: float = 80.0) -> tuple[float, float]:
    """(amplitude, phase) of the late current, by a least-squares fit of a cos ωt + b sin ωt."""
    t_end = max(120.0, periods * 2 * math.pi / omega)
    run = mechsim.simulate(circuit(emf_frequency=omega), t_end, 0.01, tolerance=1e-12)
    late = run.t > t_end - 20.0  # transient e^{−βt}: below 1e-8 after 100 s
    t, i = run.t[late], run.observables["current"][late]
    A = np.stack([np.cos(omega * t), np.sin(omega * t)], axis=1)
    (a, b), *_ = np.linalg.lstsq(A, i, rcond=None)
    return math.hypot(a, b), math.atan2(-b, a)  # I = |I| cos(ωt + φ)


def test_units_and_names() -> None:
    d = circuit().describe()
    units = {p["name"]: p["unit"] for p in d["parameters"]}
    assert units == {"inductance": "H", "resistance": "Ω", "capacitance": "F",
                     "emf_amplitude": "V", "emf_frequency": "rad/s", "initial.q": "C",
                     "initial_rate.q": "A"}
    assert d["coordinates"] == [{"name": "q", "unit": "C"}]
    obs = {o["name"]: o["unit"] for o in d["observables"]}
    assert obs == {"current": "A", "magnetic_energy": "J", "electric_energy": "J",
                   "capacitor_voltage": "V", "resistor_voltage": "V", "emf": "V",
                   "power_in": "W", "joule_power": "W"}
    assert d["frames"] == []


def test_free_discharge_matches_sympy_solution() -> None:
    """No emf, charged capacitor: sympy's solution of L q̈ + R q̇ + q/C = 0 (underdamped)."""
    t = sp.Symbol("t", real=True)
    q = sp.Function("q")
    q0 = 0.3
    sol = sp.dsolve(sp.Eq(sp.Rational(1) * q(t).diff(t, 2) + sp.Rational(2, 5) * q(t).diff(t)
                          + 4 * q(t), 0), q(t), ics={q(0): sp.Rational(3, 10),
                                                      q(t).diff(t).subs(t, 0): 0})
    exact = sp.lambdify(t, sol.rhs, "numpy")
    run = mechsim.simulate(circuit(emf_amplitude=0.0, **{"initial.q": q0}), 20.0, 0.01,
                           tolerance=1e-12)
    np.testing.assert_allclose(run.q[:, 0], exact(run.t), atol=1e-10)
    # energy leaves only as Joule heat
    joule = cumulative_simpson(R * run.observables["current"] ** 2, x=run.t, initial=0.0)
    np.testing.assert_allclose(run.work_dissipated, joule, atol=1e-7)
    np.testing.assert_allclose(run.total, q0**2 / (2 * C) - run.work_dissipated, atol=1e-10)
    assert np.max(np.abs(run.work_external)) < 1e-15  # no source: round-off only


def test_natural_frequency_from_the_characteristic_equation() -> None:
    s = sp.Symbol("s")
    Ls, Cs = sp.symbols("L C", positive=True)
    roots = sp.solve(Ls * s**2 + 1 / Cs, s)
    assert {sp.simplify(r) for r in roots} == {sp.I / sp.sqrt(Ls * Cs), -sp.I / sp.sqrt(Ls * Cs)}
    mod = circuit(inductance=0.02, capacitance=5e-6)
    assert mod.natural_frequency() == pytest.approx(1 / math.sqrt(0.02 * 5e-6), rel=1e-15)
    # an LC circuit oscillates at ω₀: after one period q returns, energies slosh between L and C
    mod = circuit(resistance=0.0, emf_amplitude=0.0, **{"initial.q": 0.1})
    T = 2 * math.pi * math.sqrt(L * C)
    run = mechsim.simulate(mod, T, T / 400, tolerance=1e-13)
    assert run.q[-1, 0] == pytest.approx(0.1, abs=1e-11)
    assert run.q[200, 0] == pytest.approx(-0.1, abs=1e-11)  # half a period: reversed
    mag, ele = run.observables["magnetic_energy"], run.observables["electric_energy"]
    assert mag.max() == pytest.approx(ele.max(), rel=1e-9)
    np.testing.assert_allclose(mag + ele, 0.1**2 / (2 * C), rtol=1e-11)
    assert mag[100] == pytest.approx(0.1**2 / (2 * C), rel=1e-9)  # quarter period: all in L


def test_steady_current_is_emf_over_impedance() -> None:
    omega = 1.3
    amp, phase = steady_current(omega)
    Z = complex(R, omega * L - 1 / (omega * C))
    assert amp == pytest.approx(1.0 / abs(Z), rel=1e-7)
    assert phase == pytest.approx(-math.atan2(Z.imag, Z.real), abs=1e-7)  # capacitive: leads
    assert circuit(emf_frequency=omega).current_amplitude() == pytest.approx(1 / abs(Z),
                                                                             rel=1e-14)


def test_resonance_and_quality_factor() -> None:
    """The current peaks at ω₀ with amplitude ℰ₀/R; it is 1/√2 of that at the half-power points
    ω± = √(ω₀² + β²) ± β, so the bandwidth is R/L and Q = ω₀/(ω₊ − ω₋) = ω₀L/R."""
    w0, beta = 1 / math.sqrt(L * C), R / (2 * L)
    peak, _ = steady_current(w0)
    assert peak == pytest.approx(1.0 / R, rel=1e-7)
    for w in (w0 * 0.99, w0 * 1.01):
        assert steady_current(w)[0] < peak
    half = [math.sqrt(w0**2 + beta**2) + s * beta for s in (-1, 1)]
    for w in half:
        assert steady_current(w)[0] == pytest.approx(peak / math.sqrt(2), rel=1e-7)
    mod = circuit()
    assert mod.quality_factor() == pytest.approx(w0 / (half[1] - half[0]), rel=1e-13)
    assert mod.quality_factor() == pytest.approx(math.sqrt(L / C) / R, rel=1e-14)
    # the charge amplitude peaks lower, at ω_R = √(ω₀² − 2β²) (PHYS0500 §1.5)
    assert mod.charge_resonance_frequency() == pytest.approx(math.sqrt(w0**2 - 2 * beta**2),
                                                             rel=1e-14)
    assert mod.document_quality_factor() == pytest.approx(
        math.sqrt(w0**2 - 2 * beta**2) / (2 * beta), rel=1e-14)


def test_same_trajectory_as_the_mechanical_analogue() -> None:
    """Table of §1.7: x ↔ q, m ↔ L, b ↔ R, 1/k ↔ C, F ↔ ℰ; energies T ↔ ½LI², V ↔ q²/2C."""
    kw = {"inductance": 0.7, "resistance": 0.3, "capacitance": 0.5, "emf_amplitude": 1.5,
          "emf_frequency": 2.1, "initial.q": 0.2, "initial_rate.q": -0.1}
    e = mechsim.simulate(circuit(**kw), 30.0, 0.05, tolerance=1e-12)
    mech = mechsim.load_system("driven_oscillator", mass=0.7, damping=0.3, spring_constant=2.0,
                               drive_amplitude=1.5, drive_frequency=2.1,
                               **{"initial.x": 0.2, "initial_rate.x": -0.1})
    m = mechsim.simulate(mech, 30.0, 0.05, tolerance=1e-12)
    np.testing.assert_allclose(e.q, m.q, atol=1e-10)
    np.testing.assert_allclose(e.v, m.v, atol=1e-10)
    np.testing.assert_allclose(e.observables["magnetic_energy"], m.kinetic, atol=1e-10)
    np.testing.assert_allclose(e.observables["electric_energy"], m.potential, atol=1e-10)
    np.testing.assert_allclose(e.work_dissipated, m.work_dissipated, atol=1e-10)
    np.testing.assert_allclose(e.work_external, m.work_external, atol=1e-10)
    # the closed form is the analogue's: exact propagation agrees with the integration
    x = mechsim.simulate(circuit(**kw), 30.0, 0.05, method="exact")
    np.testing.assert_allclose(x.q, e.q, atol=1e-9)


def test_joule_heat_and_source_work() -> None:
    run = mechsim.simulate(circuit(), 40.0, 0.01, tolerance=1e-12)
    I = run.observables["current"]
    joule = cumulative_simpson(R * I**2, x=run.t, initial=0.0)
    source = cumulative_simpson(run.observables["emf"] * I, x=run.t, initial=0.0)
    scale = float(np.max(run.total))
    np.testing.assert_allclose(run.work_dissipated, joule, atol=1e-7 * scale)
    np.testing.assert_allclose(run.work_external, source, atol=1e-7 * scale)
    # Kirchhoff: the voltages around the loop add up (L dI/dt from a centred difference)
    dI = np.gradient(I, run.t)
    vl = L * dI
    kvl = run.observables["emf"] - run.observables["resistor_voltage"] \
        - run.observables["capacitor_voltage"] - vl
    assert np.max(np.abs(kvl[5:-5])) < 1e-3


def test_long_run_energy() -> None:
    """LC (no resistance, no emf) for 1000 periods: the energy stays put; driven and damped:
    the work balance closes."""
    run = mechsim.simulate(circuit(resistance=0.0, emf_amplitude=0.0, **{"initial.q": 0.1}),
                           3000.0, 0.5, tolerance=1e-13)
    e0 = 0.1**2 / (2 * C)
    assert np.max(np.abs(run.total - e0)) < 1e-9 * e0
    run = mechsim.simulate(circuit(), 3000.0, 0.5, tolerance=1e-12)
    assert np.max(np.abs(run.balance_residual)) < 1e-9 * float(np.max(run.total))


@pytest.mark.parametrize("kw,field", [({"capacitance": 0.0}, "capacitance"),
                                      ({"inductance": -1.0}, "inductance"),
                                      ({"resistance": -0.1}, "resistance")])
def test_parameter_validation(kw: dict, field: str) -> None:
    with pytest.raises(ParameterError) as err:
        circuit(**kw)
    assert err.value.field == field
