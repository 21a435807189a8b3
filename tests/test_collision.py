"""Elastic collision of two spheres (PHYS0500 §5.2): contact-event time, conservation across the
impulse, LAB/CM formulations, final velocities against an independent sympy solution of the
conservation laws, the document's angle and energy-sharing formulas derived again with sympy,
the maximum LAB angle by an impact-parameter sweep."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import mechsim
from mechsim.errors import ParameterError


def load(**kw: object) -> mechsim.systems.base.Model:
    return mechsim.load_system("collision", **kw)


def final_lab_velocities(r: mechsim.SimulationResult) -> tuple[np.ndarray, np.ndarray]:
    m1, m2 = r.model.value("mass_1"), r.model.value("mass_2")
    if r.model.formulation == "lab":
        return r.v[-1, 0:2], r.v[-1, 2:4]
    V, w = r.v[-1, 0:2], r.v[-1, 2:4]
    return V + m2 / (m1 + m2) * w, V - m1 / (m1 + m2) * w


@pytest.fixture(scope="module")
def runs() -> dict[str, mechsim.SimulationResult]:
    return {f: mechsim.simulate(load(formulation=f), 40.0, 0.01, tolerance=1e-12)
            for f in ("lab", "cm")}


def test_contact_event_and_laws_across_the_impulse(runs: dict) -> None:
    for r in runs.values():
        m = r.model
        assert [n for _, n in r.events] == ["contact"]
        assert abs(r.events[0][0] - m.contact_time()) < 1e-13 * m.contact_time()
        # no overlap at any sample, and the spheres separate after the contact
        gap = r.observables["gap"]
        assert gap.min() > -1e-12 and gap[-1] > 30.0
        T0 = 0.5 * m.value("mass_1") * m.value("initial.speed") ** 2
        assert np.max(np.abs(r.total - T0)) < 1e-14 * T0
        assert np.max(np.abs(r.balance_residual)) < 1e-14 * T0
        p0 = m.value("mass_1") * m.value("initial.speed")
        inv = r.invariants
        assert np.max(np.abs(inv["momentum_x"] - p0)) < 1e-14 * p0
        assert np.max(np.abs(inv["momentum_y"])) < 1e-14 * p0
        L0 = inv["angular_momentum"][0]
        assert abs(L0 + p0 * m.value("impact_parameter")) < 1e-14
        assert np.max(np.abs(inv["angular_momentum"] - L0)) < 1e-13  # |r||p| ~ 40 at the end
        mu = m.value("mass_1") * m.value("mass_2") / (m.value("mass_1") + m.value("mass_2"))
        Tcm = 0.5 * mu * m.value("initial.speed") ** 2  # T₀′ = ½μu₁² (line 1249 fixed)
        assert np.max(np.abs(inv["internal_kinetic_energy"] - Tcm)) < 1e-14 * Tcm
        # the CM frame moves uniformly at V = m₁u₁/M
        names = [f.child for f in m.frames]
        cm = r.outputs.frames[:, names.index("cm"), :2]
        V = m.value("mass_1") * m.value("initial.speed") / (m.value("mass_1") + m.value("mass_2"))
        np.testing.assert_allclose(cm[:, 0] - cm[0, 0], V * r.t, atol=1e-12)
        assert np.max(np.abs(cm[:, 1] - cm[0, 1])) < 1e-13
        # CM-frame velocities: u₁′ = v₁′ = m₂u₁/M, u₂′ = v₂′ = V (eq. 5.2, line 1130)
        o = r.observables
        np.testing.assert_allclose(np.hypot(o["cm_velocity_1_x"], o["cm_velocity_1_y"]),
                                   m.value("mass_2") / m.value("mass_1") * V, rtol=1e-13)
        np.testing.assert_allclose(np.hypot(o["cm_velocity_2_x"], o["cm_velocity_2_y"]), V,
                                   rtol=1e-13)


def test_formulations_agree(runs: dict) -> None:
    a, b = runs["lab"], runs["cm"]
    assert np.max(np.abs(a.outputs.frames - b.outputs.frames)) < 1e-12
    for k in a.observables:
        assert np.max(np.abs(a.observables[k] - b.observables[k])) < 1e-12, k


def sympy_final_velocities(m1: float, m2: float, u: float, b: float, a: float
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Independent: momentum (2), kinetic energy, and m₂'s velocity along the line of centres
    at contact (the only force on it is the normal push), solved by sympy."""
    v1x, v1y, v2x, v2y = sp.symbols("v1x v1y v2x v2y", real=True)
    M1, M2, U, B, A = (sp.Rational(str(z)) for z in (m1, m2, u, b, a))
    n = sp.Matrix([-sp.sqrt(A**2 - B**2), B]) / A  # from 2 to 1 at contact
    eqs = [M1 * v1x + M2 * v2x - M1 * U, M1 * v1y + M2 * v2y,
           M1 * (v1x**2 + v1y**2) + M2 * (v2x**2 + v2y**2) - M1 * U**2,
           v2x * n[1] - v2y * n[0]]
    sols = [s for s in sp.solve(eqs, [v1x, v1y, v2x, v2y], dict=True) if s[v2x] != 0]
    assert len(sols) == 1
    s = sols[0]
    return (np.array([float(s[v1x]), float(s[v1y])]), np.array([float(s[v2x]), float(s[v2y])]))


@pytest.mark.parametrize("m1, m2, b", [(2.0, 1.0, 0.15), (1.0, 3.0, 0.05), (1.0, 1.0, 0.2),
                                       (3.0, 1.0, 0.0)])
def test_final_velocities_and_document_formulas(m1: float, m2: float, b: float) -> None:
    m = load(formulation="lab", mass_1=m1, mass_2=m2, impact_parameter=b)
    r = mechsim.simulate(m, 3.0, 0.5, tolerance=1e-12)
    v1, v2 = final_lab_velocities(r)
    e1, e2 = sympy_final_velocities(m1, m2, 1.0, b, 0.25)
    np.testing.assert_allclose(v1, e1, atol=1e-13)
    np.testing.assert_allclose(v2, e2, atol=1e-13)
    o = {k: v[-1] for k, v in r.observables.items()}
    th, (psi, zeta) = m.cm_angle(), m.lab_angles()
    assert abs(o["cm_angle"] - th) < 1e-12
    assert abs(o["lab_angle_1"] - psi) < 1e-12
    assert abs(o["lab_angle_2"] - zeta) < 1e-12
    assert abs(o["energy_fraction_2"] - m.energy_shares()[1]) < 1e-13
    if m1 == m2:  # line 1188 and 1213
        assert abs(psi - th / 2) < 1e-13 and abs(psi + zeta - math.pi / 2) < 1e-13
    if b == 0.0:  # head-on: v₁ = (m₁ − m₂)u₁/M, v₂ = 2m₁u₁/M
        np.testing.assert_allclose([v1[0], v2[0]], [(m1 - m2) / (m1 + m2), 2 * m1 / (m1 + m2)],
                                   atol=1e-14)


def test_document_relations_derived_with_sympy() -> None:
    """Build the final state from the CM picture (v₁′ = m₂u₁/M rotated by θ, v₂′ = −m₁v₁′/m₂,
    plus V) and derive the LAB relations the document states."""
    m1, m2, u, th = sp.symbols("m1 m2 u theta", positive=True)
    M = m1 + m2
    e = sp.Matrix([sp.cos(th), sp.sin(th)])
    V = sp.Matrix([m1 * u / M, 0])
    v1 = V + m2 * u / M * e
    v2 = V - m1 * u / M * e
    # momentum and kinetic energy conserved for every θ
    assert sp.simplify(m1 * v1 + m2 * v2 - sp.Matrix([m1 * u, 0])) == sp.zeros(2, 1)
    T1, T2 = m1 * v1.dot(v1) / 2, m2 * v2.dot(v2) / 2
    assert sp.simplify(T1 + T2 - m1 * u**2 / 2) == 0
    # tan ψ = sin θ/(cos θ + m₁/m₂) (eq. 5.3–5.4)
    assert sp.simplify(v1[1] / v1[0] - sp.sin(th) / (sp.cos(th) + m1 / m2)) == 0
    # tan ζ = cot(θ/2) (line 1205; v₂ points below the axis, ζ = angle from +x)
    ph = sp.Symbol("phi", positive=True)
    assert sp.simplify(sp.expand_trig(((-v2[1] / v2[0]) - sp.cot(th / 2)).subs(th, 2 * ph))) == 0
    # T₂/T₀ = 2m₁m₂(1 − cos θ)/M²
    assert sp.simplify(T2 / (m1 * u**2 / 2) - 2 * m1 * m2 * (1 - sp.cos(th)) / M**2) == 0
    # maximum of ψ(θ) for x = m₁/m₂ > 1: d tanψ/dθ = 0 at cos θ = −1/x, there sin ψ = 1/x
    x = sp.Symbol("x", positive=True)
    tanpsi = sp.sin(th) / (sp.cos(th) + x)
    c = sp.Symbol("c", real=True)
    numer = sp.expand(sp.numer(sp.together(sp.diff(tanpsi, th))))
    crit = sp.solve(numer.subs(sp.sin(th) ** 2, 1 - sp.cos(th) ** 2).subs(sp.cos(th), c), c)
    assert crit == [-1 / x]
    tan2 = sp.simplify((tanpsi**2).subs(sp.sin(th) ** 2, 1 - sp.cos(th) ** 2)
                       .subs(sp.cos(th), -1 / x))
    assert sp.simplify(tan2 / (1 + tan2) - 1 / x**2) == 0  # sin²ψ = 1/x²
    # numeric point of the catalog: m₁ = 3, m₂ = 1, θ = 1 rad
    vals = {m1: 3, m2: 1, u: 1, th: 1}
    assert abs(float(sp.atan(v1[1] / v1[0]).subs(vals)) - 0.233353) < 1e-6
    assert abs(float((T1 / (m1 * u**2 / 2)).subs(vals)) - 0.827613) < 1e-6


def test_maximum_lab_angle_by_impact_parameter_sweep() -> None:
    """m₁ = 3 m₂: the LAB deflection never exceeds arcsin(m₂/m₁) and the sweep reaches it."""
    base = load(mass_1=3.0, mass_2=1.0, formulation="cm")
    a = 0.25
    psis, thetas = [], []
    for b in np.linspace(0.0, 0.999 * a, 121):
        r = mechsim.simulate(base.with_values(impact_parameter=float(b)), 3.0, 1.5)
        psis.append(r.observables["lab_angle_1"][-1])
        thetas.append(r.observables["cm_angle"][-1])
    psi_max = math.asin(1.0 / 3.0)
    assert abs(base.max_lab_angle() - psi_max) < 1e-15
    assert max(psis) <= psi_max + 1e-12
    assert psi_max - max(psis) < 2e-4
    # double-valued: each LAB angle below the maximum comes from two CM angles θ_f < θ_b
    i = int(np.argmax(psis))
    assert 0 < i < len(psis) - 1
    assert abs(math.cos(thetas[i]) + 1.0 / 3.0) < 0.03  # at cos θ = −m₂/m₁
    # m₁ < m₂: single valued, back-scattering up to ψ → π at b → 0
    light = load(mass_1=1.0, mass_2=3.0)
    r = mechsim.simulate(light.with_values(impact_parameter=0.0), 3.0, 1.5)
    assert abs(r.observables["lab_angle_1"][-1] - math.pi) < 1e-12


def test_miss_goes_straight() -> None:
    m = load(impact_parameter=0.3)
    r = mechsim.simulate(m, 3.0, 0.1)
    assert r.events == [] and math.isinf(m.contact_time())
    assert np.max(np.abs(r.observables["cm_angle"])) == 0.0
    assert np.max(np.abs(r.observables["kinetic_energy_2"])) == 0.0


def test_parameter_validation() -> None:
    with pytest.raises(ParameterError, match="^initial.distance: must be > radius_1"):
        load(**{"initial.distance": 0.2})
    with pytest.raises(ParameterError, match="^initial.distance: must be > impact_parameter"):
        load(impact_parameter=2.0)
    with pytest.raises(ParameterError, match="^radius_2: must be > 0"):
        load(radius_2=0.0)
    with pytest.raises(ParameterError, match="^impact_parameter: must be >= 0"):
        load(impact_parameter=-0.1)
    with pytest.raises(ParameterError, match="^formulation: must be one of lab, cm"):
        load(formulation="polar")
    with pytest.raises(ParameterError, match="^method: yoshida8 does not handle events"):
        mechsim.simulate(load(), 1.0, 0.1, method="yoshida8")
