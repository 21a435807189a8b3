"""Benchmark problems: one initial-value problem per system, with a reference solution.

Each :class:`Problem` holds what every contestant needs: the system id and parameters (the
mechsim model is built from them), the horizon and sample times, a plain-numpy right-hand side
on the state ``[q, v]`` (written here by hand from the same physics, as a user of scipy would:
not through mechsim's kernels), the conserved quantity used for the invariant error, and the
reference solution at the sample times.

References: closed forms where the system module offers one (Kepler's equation for ``kepler``,
the transient + steady-state solution of ``driven_oscillator``, Jacobi elliptic functions for
the ``pendulum`` released from rest, the normal-mode solution of ``harmonic_oscillator``).
Systems without a closed form use a high-precision run of the hand-written RHS, checked
against independent ones: ``double_pendulum`` (chaotic, λ ≈ 1.9 /s, so a short horizon of
5 s) takes a fixed-step run of the DOP853 tableau in extended precision (``np.longdouble``,
80-bit on x86: ε ≈ 1.1e-19; steps of 1.25 ms and of 0.31 ms agree to 4e-15 at the end point
and 1.2e-14 over the run, relative to the state scale). Double precision cannot do this
well: scipy Radau and DOP853 at rtol = atol = 1e-14 agree with each other to 1e-12 at the
end point but are 2.7e-12 and 1.7e-12 away from the extended-precision run (7.5e-12 and
5.1e-12 over the run), i.e. round-off amplified by the chaos. The extended run uses the
same double-precision g and initial angles as every contestant. Where ``longdouble`` is plain
double, the reference falls back to Radau at 1e-14 (and says so in ``reference_kind``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.special import ellipj, ellipk

from mechsim.simulate import output_times

Array = np.ndarray


@dataclass
class Problem:
    """One IVP of one system; the state everywhere is ``y = [q, v]`` (no work terms)."""

    system: str
    params: dict[str, Any]
    t_end: float
    n_samples: int
    description: str
    rhs: Callable[[float, Array], Array]
    y0: Array
    reference: Callable[[Array], Array]  # times (m,) -> states (m, 2n)
    reference_kind: str
    conserved: Callable[[Array, Array], Array] | None = None  # (t, Y) -> quantity per row
    conserved_name: str | None = None
    peers: tuple[str, ...] = ("scipy",)
    extra: dict[str, Any] = field(default_factory=dict)
    _ref_cache: Array | None = None

    @property
    def n_q(self) -> int:
        return self.y0.size // 2

    def times(self) -> Array:
        return output_times(self.t_end, self.t_end / self.n_samples)

    def reference_states(self) -> Array:
        if self._ref_cache is None:
            self._ref_cache = self.reference(self.times())
        return self._ref_cache

    def state_scale(self) -> float:
        """Largest ‖y_ref(t)‖ over the samples: state errors are relative to it."""
        return float(np.max(np.linalg.norm(self.reference_states(), axis=1)))

    def errors(self, Y: Array) -> dict[str, float | None]:
        """End-point and max-over-run state error (relative to ``state_scale``) and the max
        relative drift of the conserved quantity (None if the system conserves none)."""
        ref = self.reference_states()
        if Y.shape != ref.shape or not np.all(np.isfinite(Y)):
            return {"end_error": math.inf, "max_error": math.inf,
                    "invariant_error": math.inf if self.conserved else None}
        d = np.linalg.norm(Y - ref, axis=1) / self.state_scale()
        out: dict[str, float | None] = {"end_error": float(d[-1]), "max_error": float(d.max()),
                                        "invariant_error": None}
        if self.conserved is not None:
            c = self.conserved(self.times(), Y)
            c_ref = self.conserved(self.times()[:1], ref[:1])[0]
            scale = float(self.extra.get("conserved_scale", abs(c_ref) or 1.0))
            out["invariant_error"] = float(np.max(np.abs(c - c_ref)) / scale)
        return out


# --- pendulum ---------------------------------------------------------------------------------
def pendulum(t_end: float = 100.0, n_samples: int = 200, angle: float = 1.0) -> Problem:
    m, R, g = 1.0, 1.0, 9.81
    w0 = math.sqrt(g / R)
    k = math.sin(angle / 2)
    K = float(ellipk(k * k))

    def rhs(t: float, y: Array) -> Array:
        return np.array([y[1], -(g / R) * math.sin(y[0])])

    def reference(t: Array) -> Array:
        # Released from rest at φ₀: sin(φ/2) = k sn(K − ω₀t | k²), φ̇ = −2kω₀ cn(K − ω₀t | k²).
        u = np.mod(K - w0 * t, 4 * K)
        sn, cn, _, _ = ellipj(u, k * k)
        return np.stack([2 * np.arcsin(k * sn), -2 * k * w0 * cn], axis=1)

    def energy(t: Array, Y: Array) -> Array:
        return 0.5 * m * R**2 * Y[:, 1] ** 2 + m * g * R * (1 - np.cos(Y[:, 0]))

    e0 = m * g * R * (1 - math.cos(angle))
    return Problem("pendulum", {"formulation": "reduced", "initial.angle": angle}, t_end,
                   n_samples, f"simple pendulum released from rest at φ₀ = {angle} rad, "
                   f"g = {g}, R = {R}; {t_end:g} s ≈ {t_end * w0 / (4 * K):.0f} periods",
                   rhs, np.array([angle, 0.0]), reference, "closed form (Jacobi sn, cn)",
                   energy, "energy", peers=("scipy", "mujoco", "drake"),
                   extra={"conserved_scale": e0, "m": m, "R": R, "g": g})


# --- kepler -----------------------------------------------------------------------------------
def kepler(orbits: float = 100.0, n_samples: int = 200, e: float = 0.5) -> Problem:
    GM, a = 1.0, 1.0
    period = 2 * math.pi * math.sqrt(a**3 / GM)
    n_mean = 2 * math.pi / period
    rp = a * (1 - e)

    def rhs(t: float, y: Array) -> Array:
        x, yy, vx, vy = y
        r3 = (x * x + yy * yy) ** 1.5
        return np.array([vx, vy, -GM * x / r3, -GM * yy / r3])

    def reference(t: Array) -> Array:
        M = np.mod(n_mean * np.asarray(t, dtype=float), 2 * math.pi)
        E = M + e * np.sin(M)
        for _ in range(60):
            dE = (E - e * np.sin(E) - M) / (1 - e * np.cos(E))
            E = E - dE
            if np.max(np.abs(dE)) < 1e-16:
                break
        b = a * math.sqrt(1 - e * e)
        Edot = n_mean / (1 - e * np.cos(E))
        return np.stack([a * (np.cos(E) - e), b * np.sin(E), -a * np.sin(E) * Edot,
                         b * np.cos(E) * Edot], axis=1)

    def energy(t: Array, Y: Array) -> Array:
        r = np.hypot(Y[:, 0], Y[:, 1])
        return 0.5 * (Y[:, 2] ** 2 + Y[:, 3] ** 2) - GM / r

    y0 = np.array([rp, 0.0, 0.0, math.sqrt(GM * (1 + e) / rp)])
    return Problem("kepler", {"eccentricity": e}, orbits * period, n_samples,
                   f"Kepler orbit e = {e}, a = 1, GM = 1, from pericentre; {orbits:g} orbits",
                   rhs, y0, reference, "closed form (Kepler's equation)", energy, "energy",
                   peers=("scipy", "rebound"),
                   extra={"conserved_scale": GM / (2 * a), "GM": GM, "orbits": orbits})


# --- driven_oscillator ----------------------------------------------------------------------
def driven_oscillator(t_end: float = 100.0, n_samples: int = 200) -> Problem:
    m, k, b, F0, w = 1.0, 4.0, 0.4, 1.0, 1.8
    w0 = math.sqrt(k / m)
    beta = b / (2 * m)
    A = F0 / m
    D = A / math.sqrt((w0**2 - w**2) ** 2 + 4 * w**2 * beta**2)
    delta = math.atan2(2 * w * beta, w0**2 - w**2)
    w1 = math.sqrt(w0**2 - beta**2)
    x0, v0 = 0.0, 0.0
    C = x0 - D * math.cos(delta)
    E = (v0 - D * w * math.sin(delta) + beta * C) / w1

    def rhs(t: float, y: Array) -> Array:
        return np.array([y[1], (F0 * math.cos(w * t) - b * y[1] - k * y[0]) / m])

    def reference(t: Array) -> Array:
        ex = np.exp(-beta * t)
        c1, s1 = np.cos(w1 * t), np.sin(w1 * t)
        x = D * np.cos(w * t - delta) + ex * (C * c1 + E * s1)
        v = (-D * w * np.sin(w * t - delta)
             + ex * ((-beta * C + w1 * E) * c1 + (-beta * E - w1 * C) * s1))
        return np.stack([x, v], axis=1)

    return Problem("driven_oscillator", {}, t_end, n_samples,
                   f"m = {m}, k = {k}, b = {b}, F₀ = {F0}, ω = {w}, from rest; {t_end:g} s",
                   rhs, np.array([x0, v0]), reference, "closed form (transient + steady state)",
                   None, None, peers=("scipy",))


# --- harmonic_oscillator --------------------------------------------------------------------
def harmonic_oscillator(t_end: float = 100.0, n_samples: int = 200) -> Problem:
    m, k, x0, v0 = 1.0, 4.0, 0.5, 0.0
    w0 = math.sqrt(k / m)

    def rhs(t: float, y: Array) -> Array:
        return np.array([y[1], -(k / m) * y[0]])

    def reference(t: Array) -> Array:
        c, s = np.cos(w0 * t), np.sin(w0 * t)
        return np.stack([x0 * c + v0 / w0 * s, -x0 * w0 * s + v0 * c], axis=1)

    def energy(t: Array, Y: Array) -> Array:
        return 0.5 * m * Y[:, 1] ** 2 + 0.5 * k * Y[:, 0] ** 2

    return Problem("harmonic_oscillator", {}, t_end, n_samples,
                   f"m = {m}, k = {k}, x₀ = {x0}; {t_end:g} s ≈ {t_end * w0 / 2 / math.pi:.0f} "
                   "periods", rhs, np.array([x0, v0]), reference, "closed form",
                   energy, "energy", peers=("scipy",), extra={"conserved_scale": 0.5 * k * x0**2})


def _fixed_dop853_longdouble(rhs: Callable[[float, Array], Array], y0: Array, t: Array,
                             h_max: float) -> Array:
    """States at ``t`` from a fixed-step run of the DOP853 tableau (autonomous ``rhs``, which
    must be written with numpy functions so that it keeps ``np.longdouble``) in extended
    precision; a whole number of steps of at most ``h_max`` between samples."""
    from scipy.integrate._ivp import dop853_coefficients as dc

    L = np.longdouble
    A, B = dc.A.astype(L), dc.B.astype(L)
    ns = dc.N_STAGES
    y = np.asarray(y0, dtype=L)
    K = np.empty((ns, y.size), dtype=L)
    out = np.empty((t.size, y.size))
    out[0] = y0
    for i in range(1, t.size):
        gap = L(t[i]) - L(t[i - 1])
        k = max(1, math.ceil(float(gap) / h_max))
        h = gap / k
        for _ in range(k):
            K[0] = rhs(0.0, y)
            for j in range(1, ns):
                K[j] = rhs(0.0, y + h * (A[j, :j] @ K[:j]))
            y = y + h * (B @ K)
        out[i] = y.astype(float)
    return out


# --- double_pendulum --------------------------------------------------------------------------
def double_pendulum(t_end: float = 5.0, n_samples: int = 200) -> Problem:
    # Defaults of load_system("double_pendulum") (angles form): absolute angles θ₁, θ₂ from
    # straight down, point masses on massless rods.
    m1, m2, l1, l2, g = 1.0, 1.0, 1.0, 1.0, 9.81
    th1, th2 = 2.0, 2.5

    def accel(y: Any, sin: Any, cos: Any) -> list[Any]:
        # Euler–Lagrange equations of L = T − V (derived independently with sympy from the
        # Cartesian bob positions): M(θ) θ̈ = f(θ, θ̇), M 2×2 solved by Cramer's rule.
        t1, t2, w1, w2 = y
        c, s = cos(t1 - t2), sin(t1 - t2)
        m11, m12, m22 = (m1 + m2) * l1 * l1, m2 * l1 * l2 * c, m2 * l2 * l2
        f1 = -m2 * l1 * l2 * w2 * w2 * s - (m1 + m2) * g * l1 * sin(t1)
        f2 = m2 * l1 * l2 * w1 * w1 * s - m2 * g * l2 * sin(t2)
        det = m11 * m22 - m12 * m12
        return [w1, w2, (m22 * f1 - m12 * f2) / det, (m11 * f2 - m12 * f1) / det]

    def rhs(t: float, y: Array) -> Array:  # what scipy users would write: math on floats
        return np.array(accel(y, math.sin, math.cos))

    def rhs_ext(t: float, y: Array) -> Array:  # the same in numpy, keeping np.longdouble
        return np.array(accel(y, np.sin, np.cos), dtype=y.dtype)

    y0 = np.array([th1, th2, 0.0, 0.0])

    extended = bool(np.finfo(np.longdouble).eps < 1e-18)

    def reference(t: Array) -> Array:
        if extended:
            return _fixed_dop853_longdouble(rhs_ext, y0, np.asarray(t, dtype=float), 1.25e-3)
        import warnings

        from scipy.integrate import solve_ivp

        with warnings.catch_warnings():  # rtol below 100 ε is raised to it: fine here
            warnings.simplefilter("ignore")
            sol = solve_ivp(rhs, (0.0, float(t[-1])), y0, method="Radau", t_eval=t,
                            rtol=1e-14, atol=1e-14)
        if not sol.success:
            raise RuntimeError(sol.message)
        return sol.y.T.copy()

    def energy(t: Array, Y: Array) -> Array:
        t1, t2, w1, w2 = Y.T
        T = 0.5 * m1 * l1**2 * w1**2 + 0.5 * m2 * (l1**2 * w1**2 + l2**2 * w2**2 + 2 * l1 * l2
                                                   * w1 * w2 * np.cos(t1 - t2))
        V = (m1 * g * (l1 + l2 - l1 * np.cos(t1))
             + m2 * g * (l1 + l2 - l1 * np.cos(t1) - l2 * np.cos(t2)))
        return T + V

    return Problem("double_pendulum", {}, t_end, n_samples,
                   f"double pendulum, m₁ = m₂ = {m1}, l₁ = l₂ = {l1}, g = {g}, from rest at "
                   f"θ₁ = {th1}, θ₂ = {th2} rad (chaotic, λ ≈ 1.9 /s); {t_end:g} s",
                   rhs, y0, reference,
                   "DOP853 tableau, fixed step 1.25 ms, long double (error ~1e-14)" if extended
                   else "scipy Radau @ rtol=atol=1e-14 (error ~3e-12: no long double here)",
                   energy, "energy", peers=("scipy", "mujoco", "drake"),
                   extra={"m1": m1, "m2": m2, "l1": l1, "l2": l2, "g": g})


BUILDERS: dict[str, Callable[..., Problem]] = {
    "pendulum": pendulum,
    "kepler": kepler,
    "driven_oscillator": driven_oscillator,
    "harmonic_oscillator": harmonic_oscillator,
    "double_pendulum": double_pendulum,
}

# Horizons of --quick (CI): a few periods.
QUICK: dict[str, dict[str, Any]] = {
    "pendulum": {"t_end": 5.0, "n_samples": 20},
    "kepler": {"orbits": 2.0, "n_samples": 20},
    "driven_oscillator": {"t_end": 5.0, "n_samples": 20},
    "harmonic_oscillator": {"t_end": 5.0, "n_samples": 20},
    "double_pendulum": {"t_end": 2.0, "n_samples": 20},
}


def problem(system: str, quick: bool = False) -> Problem:
    return BUILDERS[system](**(QUICK[system] if quick else {}))
