"""Linear oscillators, shared: the closed-form solution of ẍ + 2βẋ + ω₀²x = 0 (used by
harmonic_oscillator, damped_oscillator, planar_oscillator per axis and coupled_oscillators per
normal mode), the steady response to one drive tone, the ``LinearOscillator`` base of the 1-D
oscillators (harmonic, damped, driven, periodic drive) with their exact propagator (transient
plus the superposed tone responses), and quadrature for work terms. Not a system (leading
underscore).
"""

from __future__ import annotations

import math

import numpy as np
import sympy as sp

from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

Expr = sp.Expr


def regime(omega0: float, beta: float, rtol: float = 1e-12) -> str:
    """"underdamped" (β < ω₀, includes β = 0), "critical" (β = ω₀) or "overdamped"."""
    if abs(beta - omega0) <= rtol * max(omega0, beta):
        return "critical"
    return "underdamped" if beta < omega0 else "overdamped"


def free_solution(t: np.ndarray, x0: float, v0: float, omega0: float,
                  beta: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """x(t), ẋ(t) of ẍ + 2βẋ + ω₀²x = 0 with x(0) = x₀, ẋ(0) = v₀.

    Underdamped (ω₁ = √(ω₀² − β²)): x = e^{−βt}[x₀ cos ω₁t + (v₀ + βx₀)/ω₁ sin ω₁t];
    critical: x = e^{−βt}[x₀ + (v₀ + βx₀)t]; overdamped (ω₂ = √(β² − ω₀²)): cosh/sinh.
    """
    t = np.asarray(t, dtype=float)
    decay = np.exp(-beta * t)
    c = v0 + beta * x0
    kind = regime(omega0, beta)
    if kind == "critical":
        return decay * (x0 + c * t), decay * (v0 - beta * c * t)
    s = omega0 * omega0 * x0 + beta * v0
    if kind == "underdamped":
        w = math.sqrt(omega0 * omega0 - beta * beta)
        cs, sn = np.cos(w * t), np.sin(w * t)
        return decay * (x0 * cs + c / w * sn), decay * (v0 * cs - s / w * sn)
    w = math.sqrt(beta * beta - omega0 * omega0)
    ch, sh = np.cosh(w * t), np.sinh(w * t)
    return decay * (x0 * ch + c / w * sh), decay * (v0 * ch - s / w * sh)


def free_velocity_modes(x0: float, v0: float, omega0: float, beta: float
                        ) -> tuple[list[complex], list[complex]] | None:
    """ẋ(t) of ``free_solution`` as Re Σ A_k e^{z_k t}, as (A, z): underdamped
    (v₀ + i s/ω₁) e^{(−β + iω₁)t}, s = ω₀²x₀ + βv₀; overdamped ½(v₀ ∓ s/ω₂) e^{(−β ± ω₂)t};
    None when critical (a polynomial times e^{−βt})."""
    kind = regime(omega0, beta)
    if kind == "critical":
        return None
    s = omega0 * omega0 * x0 + beta * v0
    if kind == "underdamped":
        w = math.sqrt(omega0 * omega0 - beta * beta)
        return [complex(v0, s / w)], [complex(-beta, w)]
    w = math.sqrt(beta * beta - omega0 * omega0)
    return ([complex(0.5 * (v0 - s / w)), complex(0.5 * (v0 + s / w))],
            [complex(-beta + w), complex(-beta - w)])


def tone_response(force_over_mass: float, omega: float, omega0: float, beta: float
                  ) -> tuple[float, float]:
    """Amplitude D and phase lag δ ∈ [0, π] of the steady response x = D cos(ωt − δ) of
    ẍ + 2βẋ + ω₀²x = A cos ωt, A = ``force_over_mass``: D = A/√((ω₀² − ω²)² + 4ω²β²),
    tan δ = 2ωβ/(ω₀² − ω²) (seed 003 §1.4, eq. 1.2)."""
    D = force_over_mass / math.sqrt((omega0**2 - omega**2) ** 2 + 4 * omega**2 * beta**2)
    return D, math.atan2(2 * omega * beta, omega0**2 - omega**2)


def state_rows(y0: np.ndarray, columns: list[np.ndarray]) -> np.ndarray:
    """Rows of a propagated state: the given columns, then the rest of ``y0`` (work terms,
    modes) carried unchanged."""
    rows = np.repeat(np.asarray(y0, dtype=float)[None, :], len(columns[0]), axis=0)
    for j, col in enumerate(columns):
        rows[:, j] = col
    return rows


_GL_X, _GL_W = np.polynomial.legendre.leggauss(16)
#: Quadrature nodes evaluated per block of ``cumulative_integral`` (bounds its memory).
_GL_BLOCK = 4096


def cumulative_integral(f: object, t0: float, t: np.ndarray, max_piece: float) -> np.ndarray:
    """∫_{t₀}^{t_k} f(s) ds for increasing t_k ≥ t₀: 16-point Gauss–Legendre on pieces no
    longer than ``max_piece`` (exact to round-off for smooth f over a fraction of its period);
    f takes an array of times, and is called on blocks of pieces at once."""
    t = np.asarray(t, dtype=float)
    if t.size == 0:
        return np.empty(0)
    start = np.concatenate(([t0], t[:-1]))
    span = t - start
    n = np.where(span > 0.0, np.maximum(1.0, np.ceil(span / max_piece)), 0.0).astype(np.int64)
    owner = np.repeat(np.arange(t.size), n)  # the sample each piece ends in
    first = np.repeat(np.cumsum(n) - n, n)
    h = span[owner] / n[owner]
    lo = start[owner] + (np.arange(owner.size) - first) * h
    pieces = np.empty(owner.size)
    for k in range(0, owner.size, _GL_BLOCK):
        half = 0.5 * h[k:k + _GL_BLOCK]
        nodes = (lo[k:k + _GL_BLOCK] + half)[:, None] + half[:, None] * _GL_X
        values = np.asarray(f(nodes.ravel()), dtype=float).reshape(nodes.shape)  # type: ignore[operator]
        pieces[k:k + _GL_BLOCK] = half * (values @ _GL_W)
    return np.cumsum(np.bincount(owner, weights=pieces, minlength=t.size))


def _expm1_over(w: complex, tau: np.ndarray) -> np.ndarray:
    """∫₀^τ e^{w s} ds = (e^{wτ} − 1)/w (τ at w = 0), without cancellation for small |wτ|:
    e^{x+iy} − 1 = expm1(x) cos y − 2 sin²(y/2) + i eˣ sin y."""
    if w == 0:
        return tau.astype(complex)
    x, y = w.real * tau, w.imag * tau
    num = (np.expm1(x) * np.cos(y) - 2.0 * np.sin(0.5 * y) ** 2) + 1j * (np.exp(x) * np.sin(y))
    return num / w


def square_integral(amps: list[complex], rates: list[complex], tau: np.ndarray) -> np.ndarray:
    """∫₀^τ v(s)² ds for v(s) = Re Σ_k A_k e^{z_k s} (``amps`` A, ``rates`` z), in closed form:
    v² = ½ Σ_{k,l} Re(A_k A_l e^{(z_k+z_l)s} + A_k Ā_l e^{(z_k+z̄_l)s})."""
    total = np.zeros(tau.size)
    for k in range(len(amps)):
        for j in range(k, len(amps)):
            pair = (amps[k] * amps[j] * _expm1_over(rates[k] + rates[j], tau)
                    + amps[k] * np.conj(amps[j])
                    * _expm1_over(rates[k] + np.conj(rates[j]), tau)).real
            total += pair if j == k else 2.0 * pair  # (k, j) and (j, k)
    return 0.5 * total


class LinearOscillator(LagrangianModel):
    """Shared shape of the 1-D oscillators m ẍ + b ẋ + k x = F₀ cos ωt (harmonic, damped,
    driven): the coordinate x along the ``anchor`` frame's x axis, the spring, the frames and
    visuals, ω₀ and β, and the closed-form propagator. Parameters ``damping``,
    ``drive_amplitude`` and ``drive_frequency`` are optional (0 when a system lacks them)."""

    def spring(self, b: LagrangianBuilder) -> tuple[Expr, Expr, Expr, Expr]:
        """Declare x, T = ½mẋ², V = ½kx² and the frames; returns (x, ẋ, m, k)."""
        x, dx = b.coordinate("x", "m")
        m, k = b.param("mass"), b.param("spring_constant")
        b.kinetic = m * dx**2 / 2
        b.potential = k * x**2 / 2
        b.frame("anchor", "world", (0, 0, 0))
        b.frame("mass", "anchor", (x, 0, 0))
        return x, dx, m, k

    def visuals(self) -> tuple[Visual, ...]:
        return (Visual("box", "anchor", size=(0.02, 0.3, 0.3), color=(150, 150, 150)),
                Visual("link", "anchor", to_frame="mass", radius=0.01, color=(200, 200, 90)),
                Visual("sphere", "mass", radius=0.08),
                Visual("trail", "mass", color=(120, 170, 255)))

    def _optional(self, name: str) -> float:
        return self.value(name) if name in self.values else 0.0

    def natural_frequency(self) -> float:
        """ω₀ = √(k/m)."""
        return math.sqrt(self.value("spring_constant") / self.value("mass"))

    def beta(self) -> float:
        """β = b / 2m."""
        return self._optional("damping") / (2 * self.value("mass"))

    def time_scale(self) -> float:
        return 2 * math.pi / self.natural_frequency()

    def drive_tones(self) -> list[tuple[float, float, float]]:
        """The drive as a sum of tones F(t) = Σ Fₙ cos(ωₙt − φₙ), as (Fₙ, ωₙ, φₙ): here the one
        tone F₀ cos ωt, none without a drive. A periodic drive overrides this (its Fourier
        series); ``propagate`` superposes the responses (seed 003 §1.6)."""
        F0 = self._optional("drive_amplitude")
        return [(F0, self._optional("drive_frequency"), 0.0)] if F0 != 0.0 else []

    def particular_solution(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """x_p(t), ẋ_p(t): the sum of the steady responses to the drive's tones (zero without
        a drive); None at an undamped resonance, where no periodic solution exists."""
        w0, beta, m = self.natural_frequency(), self.beta(), self.value("mass")
        tones = self.drive_tones()
        if beta == 0.0 and any(abs(w - w0) <= 1e-12 * w0 for _, w, _ in tones):
            return None  # undamped resonance: secular growth
        t = np.asarray(t, dtype=float)
        x, v = np.zeros(t.shape), np.zeros(t.shape)
        for F, w, phi in tones:
            D, delta = tone_response(F / m, w, w0, beta)
            x = x + D * np.cos(w * t - phi - delta)
            v = v - D * w * np.sin(w * t - phi - delta)
        return x, v

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray) -> np.ndarray | None:
        """x = x_p + transient (free solution from the state at t₀), x_p the sum of the
        responses to the drive's tones. Work terms: without a drive W_d grows by E(t₀) − E(t);
        with one, W_d = ∫ b ẋ² dt of the exact ẋ in closed form (``square_integral``; by
        quadrature at critical damping), and W_ext closes the balance."""
        t = np.asarray(t, dtype=float)
        m, k, c = self.value("mass"), self.value("spring_constant"), self._optional("damping")
        w0, beta = self.natural_frequency(), self.beta()
        tones = self.drive_tones()
        driven = bool(tones)

        def energy(x_: np.ndarray, v_: np.ndarray) -> np.ndarray:
            return 0.5 * m * v_**2 + 0.5 * k * x_**2

        e0 = 0.5 * m * float(y0[1]) ** 2 + 0.5 * k * float(y0[0]) ** 2
        if not driven:  # the free solution alone (no particular one to add)
            x, v = free_solution(t - t0, y0[0], y0[1], w0, beta)
            return state_rows(y0, [x, v, np.full(t.size, y0[2]), y0[3] + e0 - energy(x, v)])
        at_t0 = self.particular_solution(np.array([t0]))
        if at_t0 is None:
            return None  # undamped resonance: secular growth, not this form

        def particular(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            out = self.particular_solution(s)
            assert out is not None
            return out

        xp0, vp0 = at_t0
        u, du = free_solution(t - t0, y0[0] - xp0[0], y0[1] - vp0[0], w0, beta)
        xp, vp = particular(t)
        x, v = xp + u, vp + du

        # W_d = ∫ b ẋ² dt with ẋ = Re Σ A e^{z τ} (transient modes and one e^{iωτ} per tone:
        # −Dω sin(ωt − φ − δ) = Re(iDω e^{i(ωt₀ − φ − δ)} e^{iωτ})), in closed form
        modes = free_velocity_modes(y0[0] - xp0[0], y0[1] - vp0[0], w0, beta)
        if modes is not None:
            amps, rates = modes
            for F, w, phi in tones:
                D, delta = tone_response(F / m, w, w0, beta)
                amps.append(1j * D * w * complex(math.cos(w * t0 - phi - delta),
                                                 math.sin(w * t0 - phi - delta)))
                rates.append(complex(0.0, w))
            w_diss = y0[3] + c * square_integral(amps, rates, t - t0)
        else:  # critical damping: quadrature of the exact ẋ

            def power(s: np.ndarray) -> np.ndarray:
                xs, vs = particular(s)
                us, dus = free_solution(s - t0, y0[0] - xp0[0], y0[1] - vp0[0], w0, beta)
                return c * (vs + dus) ** 2

            piece = 0.05 * 2 * math.pi / max(w0, *(w for _, w, _ in tones))
            w_diss = y0[3] + cumulative_integral(power, t0, t, piece)
        w_ext = y0[2] + (energy(x, v) - e0) + (w_diss - y0[3])
        return state_rows(y0, [x, v, w_ext, w_diss])
