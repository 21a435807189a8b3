"""Periodic drive by superposition (PHYS0500 §1.6): the steady state is the sum of the harmonic
responses. Oracles written here independently of the code: Fourier coefficients by quadrature
of the discontinuous waveforms, phasor responses F̂ₙ/(k − mn²ω² + ibnω), the exact periodic
response to the discontinuous wave from the period map of solve_ivp, and the free transient."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest
from scipy.integrate import cumulative_simpson, quad, solve_ivp

import mechsim
from mechsim.errors import ParameterError

M, K, B = 1.0, 4.0, 0.4  # defaults: ω₀ = 2, β = 0.2


def square(t: float, w: float) -> float:
    return 1.0 if math.sin(w * t) > 0 else (-1.0 if math.sin(w * t) < 0 else 0.0)


def sawtooth(t: float, w: float) -> float:
    phase = (w * t + math.pi) % (2 * math.pi) - math.pi  # in [−π, π)
    return phase / math.pi


def coefficients_by_quadrature(f: Callable[[float, float], float], w: float, n_max: int
                               ) -> list[tuple[int, float, float]]:
    """aₙ = (1/π)∫ f cos(nθ) dθ, bₙ = (1/π)∫ f sin(nθ) dθ over one period, a₀ the mean."""
    def project(n: int, basis: Callable[[float], float]) -> float:
        return quad(lambda th: f(th / w, w) * basis(n * th), -math.pi, math.pi, points=[0.0],
                    limit=200, epsabs=1e-13)[0] / math.pi

    out = []
    for n in range(n_max + 1):
        a, b = project(n, math.cos), project(n, math.sin)
        out.append((n, a / 2 if n == 0 else a, b))
    return out


def phasor_steady_state(t: np.ndarray, coeffs: list[tuple[int, float, float]], F0: float,
                        w: float, m: float = M, k: float = K, b: float = B) -> np.ndarray:
    """x_ss = Re Σ F₀(aₙ − ibₙ) e^{inωt} / (k − m n²ω² + i b nω)."""
    x = np.zeros_like(t, dtype=complex)
    for n, an, bn in coeffs:
        x += F0 * (an - 1j * bn) * np.exp(1j * n * w * t) / (k - m * (n * w) ** 2
                                                               + 1j * b * n * w)
    return x.real


def periodic_response(f: Callable[[float], float], period: float, cuts: list[float],
                      t: np.ndarray) -> np.ndarray:
    """Exact periodic solution of m ẍ + b ẋ + k x = f(t) for a piecewise-smooth f: the period
    map s ↦ Φs + c from solve_ivp (split at the discontinuities ``cuts`` in (0, period)),
    its fixed point s* = (I − Φ)⁻¹c, then x(t) from s* (t reduced to one period)."""
    def flow(s0: np.ndarray, forced: bool, t_end: float) -> np.ndarray:
        s = np.array(s0, dtype=float)
        edges = [0.0] + [c for c in cuts if 0.0 < c < t_end] + [t_end]
        for lo, hi in zip(edges[:-1], edges[1:], strict=True):
            if hi <= lo:
                continue
            sol = solve_ivp(lambda tt, y: [y[1], ((f(tt) if forced else 0.0)
                                                  - B * y[1] - K * y[0]) / M],
                            (lo, hi), s, method="DOP853", rtol=1e-13, atol=1e-14)
            s = sol.y[:, -1]
        return s

    c = flow(np.zeros(2), True, period)
    phi = np.stack([flow(e, False, period) for e in np.eye(2)], axis=1)
    s_star = np.linalg.solve(np.eye(2) - phi, c)
    return np.array([flow(s_star, True, float(tt % period))[0] for tt in t])


def model(**kw):
    return mechsim.load_system("periodic_drive", **kw)


def test_fourier_coefficients_by_quadrature() -> None:
    w = 0.7
    for name, f, N in (("square", square, 15), ("sawtooth", sawtooth, 9)):
        mod = model(waveform=name, harmonics=N, drive_frequency=w)
        ref = {n: (a, b) for n, a, b in coefficients_by_quadrature(f, w, N)}
        got = {n: (a, b) for n, a, b in mod.fourier_coefficients()}
        for n, (a, b) in ref.items():
            ga, gb = got.get(n, (0.0, 0.0))
            assert ga == pytest.approx(a, abs=1e-10), (name, n)
            assert gb == pytest.approx(b, abs=1e-10), (name, n)


def test_steady_state_is_sum_of_harmonic_responses() -> None:
    """Default square wave at ω = 0.7 (third harmonic near ω₀ = 2): after the transient
    (e^{−βt}, β = 0.2: e^{−20} by t = 100) the motion is the phasor sum."""
    mod = model()
    w, F0 = mod.value("drive_frequency"), mod.value("drive_amplitude")
    run = mechsim.simulate(mod, 130.0, 0.05, tolerance=1e-12)
    coeffs = coefficients_by_quadrature(square, w, 15)
    late = run.t > 100.0
    ref = phasor_steady_state(run.t[late], coeffs, F0, w)
    assert np.max(np.abs(run.q[late, 0] - ref)) < 1e-8 * np.max(np.abs(ref))
    # the drive the kernel integrates is the partial sum of the same coefficients
    partial_sum = sum(F0 * (a * np.cos(n * w * run.t) + b * np.sin(n * w * run.t))
                      for n, a, b in coeffs)
    np.testing.assert_allclose(run.observables["drive_force"], partial_sum, atol=1e-9)
    # the model's own steady state, and the sum of its per-tone responses, agree with it
    np.testing.assert_allclose(mod.steady_state(run.t[late])[0], ref, atol=1e-12)
    tones = sum(D * np.cos(wn * run.t[late] - phi - delta)
                for wn, D, phi, delta in mod.harmonic_responses())
    np.testing.assert_allclose(tones, ref, atol=1e-12)


@pytest.mark.parametrize("name,f", [("square", square), ("sawtooth", sawtooth)])
def test_converges_to_response_to_the_discontinuous_wave(name: str, f: Callable) -> None:
    """The superposed responses of the first N harmonics converge to the periodic response
    to the discontinuous waveform itself (computed here by the period map); the tail of the
    responses is O(1/N²) for the square and sawtooth."""
    w, F0 = 0.7, 1.0
    period = 2 * math.pi / w
    t = np.linspace(0.0, period, 23)[:-1] + 0.013
    # within a period [0, T) both waves jump at T/2 (sgn(sin ωt) at ωt = π, the sawtooth too)
    exact = periodic_response(lambda tt: F0 * f(tt, w), period, [period / 2], t)
    errors = []
    for N in (5, 25, 99):
        x, _ = model(waveform=name, harmonics=N, drive_frequency=w).steady_state(t)
        errors.append(np.max(np.abs(x - exact)))
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 2e-4 * np.max(np.abs(exact))


def test_user_series_full_solution_and_work_balance() -> None:
    """User coefficients with a constant term, a nonzero start: x = x_ss + the free transient
    e^{−βt}(C cos ω₁t + D sin ω₁t) fitted to the initial state."""
    kw = {"waveform": "user", "harmonics": 3, "drive_amplitude": 0.8, "drive_frequency": 1.1,
          "fourier.a_0": 0.3, "fourier.b_1": 1.0, "fourier.a_2": 0.5, "fourier.b_3": -0.2,
          "initial.x": 0.4, "initial_rate.x": -0.3}
    mod = model(**kw)
    run = mechsim.simulate(mod, 40.0, 0.02, tolerance=1e-12)
    w = 1.1
    coeffs = [(0, 0.3, 0.0), (1, 0.0, 1.0), (2, 0.5, 0.0), (3, 0.0, -0.2)]
    xss = phasor_steady_state(run.t, coeffs, 0.8, w)
    h = 1e-6
    vss0 = (phasor_steady_state(np.array([h]), coeffs, 0.8, w)[0]
            - phasor_steady_state(np.array([-h]), coeffs, 0.8, w)[0]) / (2 * h)
    beta, w1 = B / (2 * M), math.sqrt(K / M - (B / (2 * M)) ** 2)
    C = 0.4 - xss[0]
    Dc = (-0.3 - vss0 + beta * C) / w1
    x = xss + np.exp(-beta * run.t) * (C * np.cos(w1 * run.t) + Dc * np.sin(w1 * run.t))
    assert np.max(np.abs(run.q[:, 0] - x)) < 1e-8
    # the constant term shifts the mean: over whole periods ⟨x_ss⟩ = F₀a₀/k
    one = np.linspace(0.0, 2 * math.pi / w, 4001)
    assert np.trapezoid(phasor_steady_state(one, coeffs, 0.8, w), one) / one[-1] == \
        pytest.approx(0.8 * 0.3 / K, rel=1e-6)
    scale = 0.5 * K * np.max(run.q[:, 0] ** 2)
    assert np.max(np.abs(run.balance_residual)) < 1e-9 * scale
    # W_d = ∫ b ẋ² dt (Simpson on the samples) and W_ext = ∫ F ẋ dt
    wd = cumulative_simpson(run.observables["power_dissipated"], x=run.t, initial=0.0)
    we = cumulative_simpson(run.observables["power_in"], x=run.t, initial=0.0)
    np.testing.assert_allclose(run.work_dissipated, wd, atol=1e-6 * scale)
    np.testing.assert_allclose(run.work_external, we, atol=1e-6 * scale)


def test_power_balance_over_a_period_in_steady_state() -> None:
    mod = model()
    w = mod.value("drive_frequency")
    period = 2 * math.pi / w
    run = mechsim.simulate(mod, 13 * period, period / 2000, tolerance=1e-12)
    late = np.arange(run.t.size) >= run.t.size - 2001  # the last whole period
    p_in = np.trapezoid(run.observables["power_in"][late], run.t[late]) / period
    p_d = np.trapezoid(run.observables["power_dissipated"][late], run.t[late]) / period
    assert p_in > 0
    assert p_in == pytest.approx(p_d, rel=1e-5)


def test_closed_form_propagation() -> None:
    """``exact`` (superposition + transient, work terms by quadrature) equals the integration."""
    mod = model(**{"initial.x": 0.2})
    a = mechsim.simulate(mod, 30.0, 0.1, tolerance=1e-12)
    b = mechsim.simulate(mod, 30.0, 0.1, method="exact")
    np.testing.assert_allclose(b.q, a.q, atol=1e-9)
    np.testing.assert_allclose(b.work_dissipated, a.work_dissipated, atol=1e-9)
    np.testing.assert_allclose(b.work_external, a.work_external, atol=1e-9)


def test_long_run_work_balance_and_phase() -> None:
    mod = model()
    run = mechsim.simulate(mod, 3000.0, 0.5, tolerance=1e-12)
    scale = mod.energy_scale() + float(np.max(run.total))
    assert np.max(np.abs(run.balance_residual)) < 1e-8 * scale
    late = run.t > 2900.0
    coeffs = coefficients_by_quadrature(square, mod.value("drive_frequency"), 15)
    ref = phasor_steady_state(run.t[late], coeffs, 1.0, mod.value("drive_frequency"))
    assert np.max(np.abs(run.q[late, 0] - ref)) < 1e-7


def test_laws() -> None:
    assert [law.key for law in model().laws()] == ["work_balance"]


@pytest.mark.parametrize("kw,field", [
    ({"fourier.a_1": 0.5}, "fourier.a_1"),  # square waveform: user coefficients unused
    ({"waveform": "user", "harmonics": 2, "fourier.b_3": 1.0}, "fourier.b_3"),
    ({"harmonics": 0}, "harmonics"), ({"harmonics": 101}, "harmonics"),
    ({"waveform": "triangle"}, "waveform"), ({"drive_frequency": 0.0}, "drive_frequency")])
def test_parameter_validation(kw: dict, field: str) -> None:
    with pytest.raises(ParameterError) as err:
        model(**kw)
    assert err.value.field == field
