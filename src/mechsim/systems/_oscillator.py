"""Linear oscillators, shared: the closed-form solution of ẍ + 2βẋ + ω₀²x = 0 (used by
harmonic_oscillator, damped_oscillator, planar_oscillator per axis and coupled_oscillators per
normal mode), the steady response to one drive tone, the ``LinearOscillator`` base of the 1-D
oscillators (harmonic, damped, driven, periodic drive) with their exact propagator (transient
plus the superposed tone responses), and quadrature for work terms. Not a system (leading
underscore).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from mechsim.systems.base import Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

if TYPE_CHECKING:
    from sympy import Expr


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


def free_modes(x0: float, v0: float, omega0: float, beta: float
               ) -> tuple[list[complex], list[complex], list[complex]] | None:
    """``free_solution`` as sums of modes, x(t) = Re Σ B_k e^{z_k t} and ẋ(t) = Re Σ A_k e^{z_k t},
    as (B, A, z): underdamped one mode, B = x₀ − i(v₀ + βx₀)/ω₁, A = v₀ + i s/ω₁,
    z = −β + iω₁ (s = ω₀²x₀ + βv₀); overdamped two, B = ½(x₀ ± (v₀ + βx₀)/ω₂),
    A = ½(v₀ ∓ s/ω₂), z = −β ± ω₂; None when critical (a polynomial times e^{−βt})."""
    kind = regime(omega0, beta)
    if kind == "critical":
        return None
    c = v0 + beta * x0
    s = omega0 * omega0 * x0 + beta * v0
    if kind == "underdamped":
        w = math.sqrt(omega0 * omega0 - beta * beta)
        return [complex(x0, -c / w)], [complex(v0, s / w)], [complex(-beta, w)]
    w = math.sqrt(beta * beta - omega0 * omega0)
    return ([complex(0.5 * (x0 + c / w)), complex(0.5 * (x0 - c / w))],
            [complex(0.5 * (v0 - s / w)), complex(0.5 * (v0 + s / w))],
            [complex(-beta + w), complex(-beta - w)])


def tone_response(force_over_mass: float, omega: float, omega0: float, beta: float
                  ) -> tuple[float, float]:
    """Amplitude D and phase lag δ ∈ [0, π] of the steady response x = D cos(ωt − δ) of
    ẍ + 2βẋ + ω₀²x = A cos ωt, A = ``force_over_mass``: D = A/√((ω₀² − ω²)² + 4ω²β²),
    tan δ = 2ωβ/(ω₀² − ω²) (PHYS0500 §1.4, eq. 1.2)."""
    D = force_over_mass / math.sqrt((omega0**2 - omega**2) ** 2 + 4 * omega**2 * beta**2)
    return D, math.atan2(2 * omega * beta, omega0**2 - omega**2)


def state_rows(y0: np.ndarray, columns: list[np.ndarray]) -> np.ndarray:
    """Rows of a propagated state: the given columns, then the rest of ``y0`` (work terms,
    modes) carried unchanged."""
    rows = np.repeat(np.asarray(y0, dtype=float)[None, :], len(columns[0]), axis=0)
    for j, col in enumerate(columns):
        rows[:, j] = col
    return rows


def normal_mode_rows(u: np.ndarray, w: np.ndarray, y0: np.ndarray, tau: np.ndarray
                     ) -> np.ndarray:
    """Rows [x, ẋ, rest of y0] at the times τ after y0 of a linear system whose normal modes
    are the orthonormal rows u_r of ``u`` at the angular frequencies ``w`` (PHYS0500 §8.4):
    each η_r = u_r·x a free oscillator, η_r(τ) = η_r cos ω_r τ + (η̇_r/ω_r) sin ω_r τ (uniform
    motion η_r + η̇_r τ for ω_r = 0), x = Σ η_r u_r, all modes and times at once. Nothing
    drives or dissipates: the work terms and modes of y0 are carried unchanged."""
    tau = np.asarray(tau, dtype=float)
    n = u.shape[0]
    eta0 = u @ np.asarray(y0[:n], dtype=float)
    deta0 = u @ np.asarray(y0[n:2 * n], dtype=float)
    wt = np.outer(tau, w)
    c, s = np.cos(wt), np.sin(wt)
    safe = np.where(w > 0, w, 1.0)
    moving = np.where(w > 0, (deta0 / safe) * s, deta0 * tau[:, None])
    rows = np.empty((tau.size, len(y0)))
    rows[:, :n] = (eta0 * c + moving) @ u
    rows[:, n:2 * n] = (deta0 * c - (eta0 * w) * s) @ u
    rows[:, 2 * n:] = np.asarray(y0, dtype=float)[2 * n:]
    return rows


_GL_X, _GL_W = np.polynomial.legendre.leggauss(16)
#: Quadrature nodes evaluated per block of ``cumulative_integral`` (bounds its memory).
_GL_BLOCK = 4096


def cumulative_integral(f: Callable[[np.ndarray], np.ndarray], t0: float, t: np.ndarray,
                        max_piece: float) -> np.ndarray:
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
        values = np.asarray(f(nodes.ravel()), dtype=np.float64).reshape(nodes.shape)
        pieces[k:k + _GL_BLOCK] = half * (values @ _GL_W)
    return np.cumsum(np.bincount(owner, weights=pieces, minlength=t.size))


#: No modes (``_modal_rows`` without the work integral).
_NO_MODES = np.zeros(0, dtype=np.complex128)


@njit(cache=True)
def _modal_rows(tau: np.ndarray, amp_x: np.ndarray, amp_v: np.ndarray, rates: np.ndarray,
                pair_amps: np.ndarray, pair_rates: np.ndarray, m: float, k: float, c: float,
                y0: np.ndarray, rows: np.ndarray) -> None:
    """Rows [x, ẋ, W_ext, W_d, rest of y0] at the times τ after the anchor, for
    x = Re Σ B_j e^{z_j τ}, ẋ = Re Σ A_j e^{z_j τ} (``amp_x`` B, ``amp_v`` A, ``rates`` z) and
    W_d = y0[3] + c ∫₀^τ ẋ² = y0[3] + c Re Σ C_l (e^{w_l τ} − 1)/w_l (``pair_amps`` C,
    ``pair_rates`` w; τ where w = 0), e^{wτ} − 1 = e^{a+ib} − 1 summed without cancellation
    for small |wτ| as expm1(a) cos b − 2 sin²(b/2) + i eᵃ sin b; W_ext closes the energy
    balance. One compiled pass: ``propagate`` of a driven oscillator."""
    e0 = 0.5 * m * y0[1] * y0[1] + 0.5 * k * y0[0] * y0[0]
    for i in range(tau.size):
        s = tau[i]
        x = 0.0
        v = 0.0
        for j in range(rates.size):
            e = np.exp(rates[j] * s)
            x += (amp_x[j] * e).real
            v += (amp_v[j] * e).real
        w_int = 0.0
        for j in range(pair_rates.size):
            w = pair_rates[j]
            if w == 0.0:
                w_int += pair_amps[j].real * s
                continue
            a, b = w.real * s, w.imag * s
            g = math.expm1(a) if a != 0.0 else 0.0
            if b == 0.0:
                num = complex(g, 0.0)
            else:  # cos b = 1 − 2 sin²(b/2), sin b = 2 sin(b/2) cos(b/2), eᵃ = 1 + g
                sh, ch = math.sin(0.5 * b), math.cos(0.5 * b)
                num = complex(g * (1.0 - 2.0 * sh * sh) - 2.0 * sh * sh,
                              (1.0 + g) * 2.0 * sh * ch)
            w_int += (pair_amps[j] * (num / w)).real
        w_diss = y0[3] + c * w_int
        rows[i, 0] = x
        rows[i, 1] = v
        rows[i, 2] = y0[2] + (0.5 * m * v * v + 0.5 * k * x * x - e0) + (w_diss - y0[3])
        rows[i, 3] = w_diss
        for j in range(4, y0.size):
            rows[i, j] = y0[j]


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
        series); ``propagate`` superposes the responses (PHYS0500 §1.6)."""
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

    def _drive_modes(self, t0: float, y0: np.ndarray
                     ) -> tuple[np.ndarray, ...] | None:
        """The arguments of ``_modal_rows`` for the motion from (t₀, y₀) under the drive: the
        transient's modes (``free_modes``) and one e^{iωτ} per tone (x_p = Σ D cos(ωt − φ − δ)
        = Re Σ D e^{i(ωt₀ − φ − δ)} e^{iωτ}), and the terms of ∫ẋ² over pairs of modes: with
        ẋ = Re Σ A_k e^{z_k τ}, ẋ² = ½ Σ_{k,l} Re(A_k A_l e^{(z_k+z_l)τ}
        + A_k Ā_l e^{(z_k+z̄_l)τ}). None at critical damping (no modal form) and at an
        undamped resonance (no periodic particular solution)."""
        m, w0, beta = self.value("mass"), self.natural_frequency(), self.beta()
        at_t0 = self.particular_solution(np.array([t0]))
        if at_t0 is None:
            return None
        xp0, vp0 = at_t0
        modes = free_modes(float(y0[0] - xp0[0]), float(y0[1] - vp0[0]), w0, beta)
        if modes is None:
            return None
        amp_x, amp_v, rates = modes
        for F, w, phi in self.drive_tones():
            D, delta = tone_response(F / m, w, w0, beta)
            B = D * complex(math.cos(w * t0 - phi - delta), math.sin(w * t0 - phi - delta))
            amp_x.append(B)
            amp_v.append(1j * w * B)
            rates.append(complex(0.0, w))
        pair_amps: list[complex] = []
        pair_rates: list[complex] = []
        for k in range(len(rates)):
            for j in range(k, len(rates)):
                f = 0.5 if j == k else 1.0  # ½ Σ_{k,l}: (k, j) and (j, k) alike
                pair_amps += [f * amp_v[k] * amp_v[j], f * amp_v[k] * np.conj(amp_v[j])]
                pair_rates += [rates[k] + rates[j], rates[k] + np.conj(rates[j])]
        return (np.array(amp_x), np.array(amp_v), np.array(rates), np.array(pair_amps),
                np.array(pair_rates))

    #: Anchors whose drive modes are kept (``propagate``), per model.
    MODE_CACHE_SIZE = 8

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray,
                  work_terms: bool = True) -> np.ndarray | None:
        """x = x_p + transient (free solution from the state at t₀), x_p the sum of the
        responses to the drive's tones. Work terms: without a drive W_d grows by E(t₀) − E(t);
        with one, W_d = ∫ b ẋ² dt of the exact ẋ in closed form (``_modal_rows``; by
        quadrature at critical damping), and W_ext closes the balance. A driven motion's modes
        are computed once per anchor (t₀, y₀) and parameter values, and kept on the model.
        ``work_terms=False``: a driven motion's work terms are NaN (∫ b ẋ² is most of the
        cost)."""
        t = np.asarray(t, dtype=float)
        if self.drive_tones():
            y0 = np.asarray(y0, dtype=float)
            key = (float(t0), y0.tobytes(), tuple(self.values.items()))
            cache = self.__dict__.setdefault("_drive_mode_cache", {})
            if key in cache:
                modes = cache.get(key)  # (None too: no modal form)
            else:
                modes = self._drive_modes(t0, y0)
                if len(cache) >= self.MODE_CACHE_SIZE:
                    cache.clear()
                cache[key] = modes
            if modes is not None:
                rows = np.empty((t.size, y0.size))
                if not work_terms:  # no pairs of modes: W_d not integrated, both work terms NaN
                    modes = (*modes[:3], _NO_MODES, _NO_MODES)
                _modal_rows(np.ascontiguousarray(t - t0), *modes, self.value("mass"),
                            self.value("spring_constant"), self._optional("damping"),
                            np.ascontiguousarray(y0), rows)
                if not work_terms:
                    rows[:, 2:4] = np.nan
                return rows
        return self._propagate_numpy(t0, y0, t)

    def _propagate_numpy(self, t0: float, y0: np.ndarray, t: np.ndarray) -> np.ndarray | None:
        """``propagate`` without a drive, at critical damping, or at an undamped resonance
        (None)."""
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

        # critical damping (the other driven cases go through ``_modal_rows``): quadrature of
        # the exact ẋ

        def power(s: np.ndarray) -> np.ndarray:
            xs, vs = particular(s)
            us, dus = free_solution(s - t0, y0[0] - xp0[0], y0[1] - vp0[0], w0, beta)
            return c * (vs + dus) ** 2

        piece = 0.05 * 2 * math.pi / max(w0, *(w for _, w, _ in tones))
        w_diss = y0[3] + cumulative_integral(power, t0, t, piece)
        w_ext = y0[2] + (energy(x, v) - e0) + (w_diss - y0[3])
        return state_rows(y0, [x, v, w_ext, w_diss])
