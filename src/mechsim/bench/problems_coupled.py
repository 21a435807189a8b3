"""The benchmark's coupled-oscillator problems: N masses on anchor springs κ joined by springs
κ₁₂, against the closed form of their normal modes (PHYS0500 – Advanced Classical Mechanics,
ch. 8 "Coupled Oscillations", §8.1–8.4; the system is ``mechsim.systems.coupled_oscillators``)."""

from __future__ import annotations

import math

import numpy as np

from mechsim.bench.problem import Array, Problem


# --- coupled_oscillators (N masses, anchors κ, neighbours κ₁₂) --------------------------------
def _coupled_accel(t: float, q: Array, p: Array, a: Array) -> None:
    # p = [κ/m, κ₁₂/m]
    n = q.size
    for j in range(n):
        f = -p[0] * q[j]
        if j > 0:
            f -= p[1] * (q[j] - q[j - 1])
        if j < n - 1:
            f -= p[1] * (q[j] - q[j + 1])
        a[j] = f


def _coupled_deriv(t: float, y: Array, p: Array, dy: Array) -> None:
    n = y.size // 2
    for j in range(n):
        f = -p[0] * y[j]
        if j > 0:
            f -= p[1] * (y[j] - y[j - 1])
        if j < n - 1:
            f -= p[1] * (y[j] - y[j + 1])
        dy[j] = y[n + j]
        dy[n + j] = f


def coupled_oscillators(count: int = 2, t_end: float = 100.0, n_samples: int = 200) -> Problem:
    m, k, kc, D = 1.0, 4.0, 0.4, 0.2
    n = count
    j = np.arange(1, n + 1)
    r = np.arange(n)
    U = np.cos(np.outer(r, j - 0.5) * math.pi / n)  # mode r (rows), mass j
    U /= np.linalg.norm(U, axis=1)[:, None]
    w = np.sqrt((k + 4 * kc * np.sin(r * math.pi / (2 * n)) ** 2) / m)
    x0 = np.zeros(n)
    x0[0] = D  # mechsim's initial.mode 0: only mass 1 displaced
    y0 = np.concatenate([x0, np.zeros(n)])
    lap = np.zeros((n, n))  # path-graph Laplacian: one coupling spring per neighbour pair
    for i in range(n - 1):
        lap[i:i + 2, i:i + 2] += np.array([[1.0, -1.0], [-1.0, 1.0]])
    Kmat = k * np.eye(n) + kc * lap
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Kmat / m, np.zeros((n, n))]])

    def reference(t: Array) -> Array:
        t = np.asarray(t, dtype=float)
        eta0, deta0 = U @ x0, U @ y0[n:]
        c, s = np.cos(np.outer(t, w)), np.sin(np.outer(t, w))
        eta = eta0 * c + deta0 / w * s
        deta = -eta0 * w * s + deta0 * c
        return np.concatenate([eta @ U, deta @ U], axis=1)

    def energy(t: Array, Y: Array) -> Array:
        x, v = Y[:, :n], Y[:, n:]
        return 0.5 * m * np.sum(v * v, axis=1) + 0.5 * np.einsum("ij,jk,ik->i", x, Kmat, x)

    return Problem(f"coupled_oscillators_{n}", "coupled_oscillators",
                   {"count": n, "mass": m, "spring_constant": k, "coupling_constant": kc,
                    "initial.mode": 0, "initial.amplitude": D}, t_end, n_samples,
                   f"{n} coupled oscillators, m = {m}, κ = {k}, κ₁₂ = {kc}, mass 1 displaced "
                   f"by {D} m; {t_end:g} s", _coupled_deriv, np.array([k / m, kc / m]), y0,
                   reference, "closed form (normal modes)", 2 * math.pi / float(w.max()),
                   energy, "energy", peers=("scipy", "handwritten", "expm"),
                   accel=_coupled_accel, linear=A,
                   extra={"conserved_scale": 0.5 * k * D * D})


def coupled_oscillators_2(t_end: float = 100.0, n_samples: int = 200) -> Problem:
    return coupled_oscillators(2, t_end, n_samples)


def coupled_oscillators_12(t_end: float = 100.0, n_samples: int = 200) -> Problem:
    return coupled_oscillators(12, t_end, n_samples)
