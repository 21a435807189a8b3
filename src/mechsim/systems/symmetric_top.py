"""Symmetric top: torque-free (gravity 0) and heavy (Lagrange's top), with one point fixed.

Sources: PHYS0500 §7.6 (Euler angles), §7.8 (torque-free symmetric top), §7.8.1–7.8.2 (heavy
symmetric top, steady precession, nutation); Lecture 10 (eqs. 10.37–10.46:
Lagrange's top, Ω± from I₁cosθ Ω² − I₃ω₃Ω + MgR = 0, reality condition, slow/fast limits,
the suspended top as a conical compound pendulum).

Conventions:
- The support point is the world origin; the centre of mass sits at distance R
  (``cm_distance``) along the body symmetry axis x₃. θ is the angle of x₃ from the **upward**
  vertical (V = MgR cos θ, as both documents have it): θ < π/2 is a top standing on its tip,
  θ > π/2 a top suspended from it (conical pendulum). Gravity 0 gives the torque-free top of
  §7.8 (about the fixed point, which the free top's formulas treat alike).
- I₁ = I₂ (``transverse_inertia``) is about a perpendicular axis through the support point,
  I₃ (``axial_inertia``) about the symmetry axis.
- Euler angles z-x-z as in PHYS0500 §7.6: the passive λ = λ_ψ λ_θ λ_φ maps world to body
  components, so the published body frame is world_R_body = λᵀ = R_z(φ) R_x(θ) R_z(ψ)
  (quaternion q_z(φ) ⊗ q_x(θ) ⊗ q_z(ψ)); body ω₁ = φ̇ sinθ sinψ + θ̇ cosψ,
  ω₂ = φ̇ sinθ cosψ − θ̇ sinψ, ω₃ = φ̇ cosθ + ψ̇; symmetry axis in space
  (sinθ sinφ, −sinθ cosφ, cosθ). ``nodes`` is the line-of-nodes frame R_z(φ) R_x(θ).

Formulations:
- ``quaternion`` (default): Euler's equations about the support point with the attitude as a
  unit quaternion (``_rigid.QuaternionRigidBody``); gravity acts as the torque R x̂₃ × (−Mg ẑ).
  Nothing is singular at θ = 0 (sleeping top). Euler angles and their rates are observables;
  exactly at θ = 0 only φ + ψ is defined: φ̇ = 0 and ψ̇ = ω₃ are published there. Method
  ``exact``: with gravity 0 uniform precession (``_free_rotation.free_rotation``); with gravity
  Lagrange's top in elliptic functions (``lagrange_motion``: u = cos θ between the roots of
  f(u), catalog 003 §7.8.1 [SUPPLEMENT, not in the seeds; Goldstein §5.7]; φ, ψ by
  quadrature of their rates as Fourier series), except near the vertical.
- ``euler_angles``: the Lagrangian L = ½I₁(θ̇² + φ̇² sin²θ) + ½I₃(ψ̇ + φ̇ cosθ)² − MgR cosθ
  (PHYS0500 line 1874, Lecture 10, eq. 10.38) given to the engine; singular at sin θ = 0, so it
  refuses initial θ within 0.01 rad of 0 or π. Both publish the same invariants p_φ, p_ψ and
  observables, for comparison.

Document typos corrected (catalog 003 §7.8, 002 §7): Ω ≡ ω₃(I₃ − I₁)/I₁ includes ω₃ (003 line
1805); L has φ̇² sin²θ + θ̇² (003 lines 1870, 1874); I₃ (not I₂) in ψ̇ = (p_ψ − I₃φ̇ cosθ)/I₃
(1886), I₃ω₃² = p_ψ²/I₃ (1908), the reality condition ω₃ ≥ (2/I₃)√(MghI₁cosθ₀) (1954) and the
slow precession Mgh/(I₃ω₃) (1964); φ̇₀ (not ψ̇₀) = β/(I₁ sin²θ₀) from (7.5) (1960); θ₁, θ₂ are
the roots of E′ = V(θ), not asymptotes of V (§7.8.2).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numba import njit

from mechsim.errors import ParameterError
from mechsim.params import Parameter, nonnegative, number, positive
from mechsim.systems._elliptic import _amplitudes, agm_ratios, carlson_rf, elliptic_f
from mechsim.systems._free_rotation import _clenshaw, _cos_sin, _qmul, period_spectra
from mechsim.systems._rigid import (
    RB_SIZE,
    RIGID_KERNELS,
    QuaternionRigidBody,
    RigidData,
    rb_momentum,
    rb_omega,
    rb_unit,
)
from mechsim.systems._rotation import euler_zxz_angles, euler_zxz_quat, quat_from_euler_zxz, rotate
from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.base import FrameSpec, Model, Quantity, Visual
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

if TYPE_CHECKING:
    from mechsim.systems.curves import Curve

# --- quaternion-formulation kernels -----------------------------------------------------------
# Index of cm_distance in p (the third numeric parameter, after the rigid-body block); the
# kernel module generates the same value, which ``DirectModel`` checks.
P_CM_DISTANCE = RB_SIZE + 2


def invariants(t, y, p, out):
    L = rb_momentum(y, p)
    out[0] = L[5]
    out[1] = L[2]
    out[2] = math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3]) - 1.0


def top_euler(y):
    """Euler angles (φ, θ, ψ) and their rates (φ̇, θ̇, ψ̇) from the state, as one tuple."""
    ang = euler_zxz_angles(rb_unit(y))
    w = rb_omega(y)
    s, c = math.sin(ang[1]), math.cos(ang[1])
    sp_, cp = math.sin(ang[2]), math.cos(ang[2])
    dphi = (w[0] * sp_ + w[1] * cp) / s if abs(s) > 1e-12 else 0.0
    return (ang[0], ang[1], ang[2], dphi, w[0] * cp - w[1] * sp_, w[2] - dphi * c)


def observables(t, y, p, out):
    e = top_euler(y)
    w = rb_omega(y)
    a = rotate(rb_unit(y), (0.0, 0.0, 1.0))
    for i in range(6):
        out[i] = e[i]
    for i in range(3):
        out[6 + i] = w[i]
        out[9 + i] = a[i]


def frames(t, y, p, out):
    q = rb_unit(y)
    ang = euler_zxz_angles(q)
    nodes = euler_zxz_quat(ang[0], ang[1], 0.0)
    for k in range(3):
        out[0, k] = 0.0
        out[1, k] = 0.0
        out[2, k] = 0.0
    out[2, 2] = p[P_CM_DISTANCE]
    for k in range(4):
        out[0, 3 + k] = q[k]
        out[1, 3 + k] = nodes[k]
        out[2, 3 + k] = 0.0
    out[2, 6] = 1.0


# --- Lagrange's top in closed form ------------------------------------------------------------
# With u = cos θ, energy and the two momenta give u̇² = f(u) = (1 − u²)(α − βu) − (b − au)²,
# a = p_ψ/I₁, b = p_φ/I₁, β = 2MgR/I₁ (catalog 003 §7.8.1; Goldstein §5.7), whose roots
# −1 ≤ u₁ ≤ u₀ ≤ u₂ ≤ 1 ≤ u₃ bound the nutation: u = u₁ + (u₂ − u₁) sn²(κt + c | m),
# m = (u₂ − u₁)/(u₃ − u₁), κ = √(β(u₃ − u₁))/2. φ̇ = (b − au)/(1 − u²) and ψ̇ = ω₃ − uφ̇ are
# periodic in t with u, so φ and ψ are their means times t plus integrated Fourier series.

#: The rows of ``_lagrange_top_rows``'s scratch: times after t₀, the phase x = π(κτ + c)/K, its
#: cosine, sine and 2 cos, Clenshaw's two sums, sn², u̇, φ/2, ψ/2 and their cosines and sines.
(_T_TAU, _T_X, _T_COS, _T_SIN, _T_2COS, _T_B1, _T_B2, _T_SN2, _T_UDOT, _T_HPHI, _T_HPSI,
 _T_CPHI, _T_SPHI, _T_CPSI, _T_SPSI) = range(15)
_T_ROWS = 15
#: Samples evaluated together (the scratch rows stay in cache).
_T_BLOCK = 256


@njit(cache=True, fastmath={"contract"}, error_model="numpy")
def _lagrange_top_rows(t: np.ndarray, t0: float, c: np.ndarray, coefs: np.ndarray,
                       terms: np.ndarray, y0: np.ndarray, rows: np.ndarray) -> None:
    """Rows [q, q̇ = ½ q ⊗ (ω, 0), y0[8:]] of Lagrange's top at each time t from the anchor
    t₀ (``LagrangeMotion``): u, u̇, φ and ψ from their Fourier series in the phase (one
    Clenshaw pass each over a block of samples), then θ's half angles from u, the attitude
    q = ±q_z(φ) ⊗ q_x(θ) ⊗ q_z(ψ) and the body ω from the Euler rates."""
    kappa, v0, rate, below, above, du, mean = c[0], c[1], c[2], c[3], c[4], c[5], c[6]
    a, b_u1, w3, phi0, dphibar, psi0, dpsibar = c[7], c[8], c[9], c[10], c[11], c[12], c[13]
    phi_off, psi_off, sign = c[14], c[15], c[16]
    n = t.size
    work = np.empty((_T_ROWS, min(n, _T_BLOCK)))
    tau, x, cx, sx, x2 = work[_T_TAU], work[_T_X], work[_T_COS], work[_T_SIN], work[_T_2COS]
    b1, b2, sn2, udot = work[_T_B1], work[_T_B2], work[_T_SN2], work[_T_UDOT]
    hphi, hpsi = work[_T_HPHI], work[_T_HPSI]
    for start in range(0, n, _T_BLOCK):
        m = min(n - start, _T_BLOCK)
        for k in range(m):
            tau[k] = t[start + k] - t0
            x[k] = rate * (kappa * tau[k] + v0)
        _cos_sin(x[:m], cx, sx)
        for k in range(m):
            x2[k] = 2.0 * cx[k]
        for r in range(4):  # one call of ``_clenshaw``: compiled once
            _clenshaw(coefs[r], terms[r], x2[:m], b1, b2)
            if r == 0:
                for k in range(m):
                    sn2[k] = mean + (b1[k] * cx[k] - b2[k])
            elif r == 1:
                for k in range(m):
                    udot[k] = b1[k] * sx[k]
            elif r == 2:
                for k in range(m):
                    hphi[k] = 0.5 * (phi0 + dphibar * tau[k] + (b1[k] * sx[k] - phi_off))
            else:
                for k in range(m):
                    hpsi[k] = 0.5 * (psi0 + dpsibar * tau[k] - (b1[k] * sx[k] - psi_off))
        _cos_sin(hphi[:m], work[_T_CPHI], work[_T_SPHI])
        _cos_sin(hpsi[:m], work[_T_CPSI], work[_T_SPSI])
        for k in range(m):
            rise = du * sn2[k]  # u − u₁
            ch = math.sqrt(max(0.5 * (above + rise), 0.0))  # cos θ/2 = √((1 + u)/2)
            sh = math.sqrt(max(0.5 * (below - rise), 0.0))  # sin θ/2 = √((1 − u)/2)
            s = 2.0 * sh * ch  # sin θ
            dphi = (b_u1 - a * rise) / (s * s)  # (b − au)/sin²θ
            dth = -udot[k] / s
            cf, sf = work[_T_CPHI, k], work[_T_SPHI, k]
            cp, sp_ = work[_T_CPSI, k], work[_T_SPSI, k]
            spsi, cpsi = 2.0 * sp_ * cp, cp * cp - sp_ * sp_
            wx = dphi * s * spsi + dth * cpsi
            wy = dphi * s * cpsi - dth * spsi
            cd, sd = cf * cp + sf * sp_, sf * cp - cf * sp_  # (φ − ψ)/2
            cs, ss = cf * cp - sf * sp_, sf * cp + cf * sp_  # (φ + ψ)/2
            qx, qy, qz, qw = sign * sh * cd, sign * sh * sd, sign * ch * ss, sign * ch * cs
            qd = _qmul(qx, qy, qz, qw, wx, wy, w3, 0.0)
            row = start + k
            rows[row, 0], rows[row, 1], rows[row, 2], rows[row, 3] = qx, qy, qz, qw
            for r in range(4):
                rows[row, 4 + r] = 0.5 * qd[r]
            for r in range(8, rows.shape[1]):
                rows[row, r] = y0[r]


class LagrangeMotion(NamedTuple):
    """The constants of ``_lagrange_top_rows`` for one initial state."""

    #: (κ, c, π/K, 1 − u₁, 1 + u₁, u₂ − u₁, mean of sn², a, b − au₁, ω₃, φ₀, mean φ̇, ψ₀,
    #: mean ψ̇, the φ and ψ series at the anchor, the sign of q)
    consts: np.ndarray
    #: (4, n): cosine coefficients of sn², sine coefficients of u̇, of φ's and of ψ's
    #: periodic parts
    coefs: np.ndarray
    #: the number of coefficients each series uses
    terms: np.ndarray


#: The motion must stay this far from the vertical (u = ±1), where the Euler angles are
#: singular; otherwise there is no closed form here (``propagate`` returns None).
VERTICAL_MARGIN = 1e-6


def _nutation_roots(beta: float, F2: float, F1: float, F0: float) -> tuple[float, float, float]:
    """The roots x_lo ≤ 0 ≤ x_hi < x_big of βx³ + F₂x² + F₁x + F₀ (f(u₀ + x), F₀ ≥ 0): the
    largest from numpy, the small pair from their sum and product (so that they keep their
    digits when close together, near steady precession), each polished by Newton's method."""
    roots = np.roots([beta, F2, F1, F0])
    big = float(max(r.real for r in roots))

    def poly(x: float) -> tuple[float, float]:
        return ((beta * x + F2) * x + F1) * x + F0, (3.0 * beta * x + 2.0 * F2) * x + F1

    total, product = -F2 / beta - big, -F0 / (beta * big)
    disc = max(total * total - 4.0 * product, 0.0)
    first = 0.5 * (total + math.copysign(math.sqrt(disc), total))
    pair = sorted((first, product / first) if first != 0.0 else (0.0, 0.0))
    polished = []
    for x in (pair[0], pair[1], big):
        for _ in range(3):
            f, df = poly(x)
            if df == 0.0:
                break
            step = x - f / df
            if abs(poly(step)[0]) >= abs(f):
                break
            x = step
        polished.append(x)
    lo, hi = min(polished[0], 0.0), max(polished[1], 0.0)
    return lo, hi, polished[2]


def lagrange_motion(inertia: tuple[float, float], mgr: float, y0: np.ndarray
                    ) -> LagrangeMotion | None:
    """The constants of Lagrange's top (gravity on, ``_lagrange_top_rows``) from the state
    y0 = [q, q̇, ...]; None where the motion comes within ``VERTICAL_MARGIN`` of the vertical
    or its series would need more than ``_free_rotation.SERIES_MAX_SAMPLES`` samples a period."""
    I1, I3 = inertia
    q0 = rb_unit(y0)
    phi0, _, psi0, dphi0, dth0, _ = top_euler(y0)
    w3 = rb_omega(y0)[2]
    ch2, sh2 = q0[3] * q0[3] + q0[2] * q0[2], q0[0] * q0[0] + q0[1] * q0[1]
    u0, s2 = ch2 - sh2, 4.0 * ch2 * sh2  # cos θ₀, sin²θ₀ from the half angles
    a, beta = I3 * w3 / I1, 2.0 * mgr / I1
    w = dth0 * dth0 + dphi0 * dphi0 * s2  # α − β u₀
    # f(u₀ + x) = F₀ + F₁x + F₂x² + βx³
    F0 = s2 * dth0 * dth0
    F1 = -2.0 * u0 * w - beta * s2 + 2.0 * a * dphi0 * s2
    F2 = -w + 2.0 * beta * u0 - a * a
    lo, hi, big = _nutation_roots(beta, F2, F1, F0)
    u1, du, span = u0 + lo, hi - lo, big - lo
    below, above = 2.0 * sh2 - lo, 2.0 * ch2 + lo  # 1 − u₁, 1 + u₁ (1 ∓ u₀ = 2 sin², 2 cos²)
    b_u1 = dphi0 * s2 - a * lo  # b − au₁
    if below - du < VERTICAL_MARGIN or above < VERTICAL_MARGIN:
        return None
    m, m1 = du / span, (big - hi) / span
    kappa = 0.5 * math.sqrt(beta * span)
    K = float(carlson_rf(0.0, m1, 1.0))
    # sn²c = (u₀ − u₁)/(u₂ − u₁), c > 0 while u rises (u̇ = −sin θ θ̇ = 2(u₂ − u₁)κ sn cn dn)
    am0 = math.atan2(math.sqrt(-lo), math.sqrt(hi)) if du > 0.0 else 0.0
    v0 = math.copysign(elliptic_f(am0, m1), -dth0 or 1.0)
    ratios, scale = agm_ratios(m, m1)

    def sample(M: int) -> np.ndarray:  # sn², φ̇ and uφ̇ over one period of sn²
        am, dn = np.empty(M), np.empty(M)
        _amplitudes(2.0 * K * np.arange(M) / M, ratios, scale, m1, am, dn)
        sn2 = np.sin(am) ** 2
        dphi = (b_u1 - a * du * sn2) / ((below - du * sn2) * (above + du * sn2))
        return np.stack([sn2, dphi, (u1 + du * sn2) * dphi])

    # relative to each function's largest value (φ̇ may average to zero)
    found = period_spectra(sample, lambda f, spec: np.maximum(np.max(np.abs(f), axis=1),
                                                              1e-300))
    if found is None:
        return None
    spec, counts = found
    n = max(counts)
    k = np.arange(1, n + 1)
    rate = math.pi / K
    coefs = np.stack([spec[0, 1:n + 1], -kappa * du * rate * k * spec[0, 1:n + 1],
                      spec[1, 1:n + 1] / (kappa * rate * k), spec[2, 1:n + 1] / (kappa * rate * k)])
    terms = np.array([counts[0], counts[0], counts[1], counts[2]], dtype=np.int64)
    x0 = rate * v0
    offsets = [float(np.sum(coefs[r, :terms[r]] * np.sin(k[:terms[r]] * x0))) for r in (2, 3)]
    consts = np.array([kappa, v0, rate, below, above, du, 0.5 * spec[0, 0], a, b_u1, w3,
                       phi0, 0.5 * spec[1, 0], psi0, w3 - 0.5 * spec[2, 0], *offsets, 1.0])
    e0 = np.empty((1, 8))
    _lagrange_top_rows(np.zeros(1), 0.0, consts, coefs, terms, np.zeros(8), e0)
    consts[16] = 1.0 if float(np.dot(e0[0, :4], q0)) >= 0.0 else -1.0
    return LagrangeMotion(consts, np.ascontiguousarray(coefs), terms)


# --- the system -------------------------------------------------------------------------------

INVARIANTS = (Quantity("p_phi", "kg m^2/s", "p_φ: vertical component of L about the support"),
              Quantity("p_psi", "kg m^2/s", "p_ψ = I₃ω₃: L along the symmetry axis"))
OBSERVABLES = (
    Quantity("phi", "rad", "precession angle φ"), Quantity("theta", "rad", "nutation angle θ"),
    Quantity("psi", "rad", "spin angle ψ"),
    Quantity("precession_rate", "rad/s", "φ̇"), Quantity("nutation_rate", "rad/s", "θ̇"),
    Quantity("spin_rate", "rad/s", "ψ̇"),
    *(Quantity(f"omega_{i}", "rad/s", f"body angular velocity ω_{i}") for i in (1, 2, 3)),
    *(Quantity(f"axis_{a}", "", f"symmetry axis x₃, world {a}") for a in "xyz"),
)
FRAMES = (FrameSpec("body", "world"), FrameSpec("nodes", "world"),
          FrameSpec("center_of_mass", "body", static=True))


class SymmetricTop(Model):
    """The registered class: picks the formulation's implementation when instantiated."""

    id = "symmetric_top"
    title = "Symmetric top: torque-free and heavy (Lagrange's top), Euler angles z-x-z"
    source = ("PHYS0500 – Advanced Classical Mechanics, §7.6 and §7.8–7.8.2 (Eulerian angles, "
              "symmetric top, top with one point fixed); Lecture 10: The Methods of Lagrange "
              "Revisited, Lagrange's heavy symmetric top (eqs. 10.37–10.46)")
    formulations = ("quaternion", "euler_angles")
    oracles = ("steady precession Ω± (θ constant), reality condition, sleeping-top threshold, "
               "nutation bounds, conical pendulum Ω² = MgR/(I₁|cosθ|), torque-free body and "
               "space precession; Lagrange's top in closed form (sn² for cos θ) = radau15; "
               "p_φ, p_ψ, E; quaternion and Euler-angle forms agree")
    parameters = (
        positive("mass", 1.0, "kg", "mass M"),
        nonnegative("gravity", 9.81, "m/s^2", "g (0: torque-free top)"),
        positive("cm_distance", 0.1, "m", "R: support point to centre of mass, along x₃"),
        positive("transverse_inertia", 0.02, "kg m^2",
                 "I₁ = I₂ about a perpendicular axis through the support point"),
        positive("axial_inertia", 0.01, "kg m^2", "I₃ about the symmetry axis"),
        number("initial.phi", 0.0, "rad", "initial precession angle φ"),
        Parameter("initial.theta", 0.6, "rad", "initial angle θ of the symmetry axis from the "
                  "upward vertical", minimum=0.0, maximum=math.pi),
        number("initial.psi", 0.0, "rad", "initial spin angle ψ"),
        number("initial_rate.phi", 0.0, "rad/s", "initial φ̇"),
        number("initial_rate.theta", 0.0, "rad/s", "initial θ̇"),
        number("initial_rate.psi", 40.0, "rad/s", "initial ψ̇ (the default top, released "
               "with φ̇ = θ̇ = 0, nutates in cusps)"),
    )

    def __new__(cls, **values: Any) -> SymmetricTop:
        chosen = values.get("formulation", cls.formulations[0])
        target = _EulerAngleTop if chosen == "euler_angles" else _QuaternionTop
        return super().__new__(target)  # type: ignore[arg-type]

    def with_values(self, **changes: Any) -> SymmetricTop:
        merged = dict(self.values)
        merged.update(changes)
        return SymmetricTop(**merged)  # type: ignore[abstract]  # __new__ makes a concrete one

    def check(self) -> None:
        if self.formulation == "euler_angles" and math.sin(self.value("initial.theta")) < 0.01:
            raise ParameterError("initial.theta", "the euler_angles formulation is singular at "
                                 "θ = 0 and π: use formulation quaternion")
        I1, I3 = self.value("transverse_inertia"), self.value("axial_inertia")
        if I3 > 2 * I1 + 1e-12 * I1:
            # about the support: I₁ ≥ I₁,cm ≥ I₃/2 for any real body of revolution
            raise ParameterError("axial_inertia", f"must be ≤ 2 × transverse_inertia "
                                 f"({2 * I1:g}) for a real body")

    def visuals(self) -> tuple[Visual, ...]:
        r = math.sqrt(2 * self.value("axial_inertia") / self.value("mass"))
        rim = tuple((r * math.cos(a), r * math.sin(a), 0.0)
                    for a in np.linspace(0, 2 * math.pi, 41))
        return (Visual("link", "body", to_frame="center_of_mass", radius=0.01),
                Visual("polyline", "center_of_mass", points=rim, radius=0.008,
                       color=(220, 170, 80)),
                Visual("sphere", "center_of_mass", radius=0.02, color=(220, 170, 80)),
                Visual("trail", "center_of_mass", color=(120, 170, 255)),
                Visual("axes", "nodes", radius=0.1))

    def time_scale(self) -> float:
        w = max(abs(self.omega3()), abs(self.value("initial_rate.phi")),
                abs(self.value("initial_rate.theta")), 1e-9)
        g = self.value("gravity")
        if g > 0:
            w = max(w, math.sqrt(self.value("mass") * g * self.value("cm_distance")
                                 / self.value("transverse_inertia")))
        return 2 * math.pi / w

    # --- initial data and analytic oracles -----------------------------------------------
    def _init(self) -> tuple[float, ...]:
        return tuple(self.value(n) for n in ("initial.phi", "initial.theta", "initial.psi",
                                             "initial_rate.phi", "initial_rate.theta",
                                             "initial_rate.psi"))

    def _consts(self) -> tuple[float, float, float]:
        """(I₁, I₃, MgR)."""
        return (self.value("transverse_inertia"), self.value("axial_inertia"),
                self.value("mass") * self.value("gravity") * self.value("cm_distance"))

    def omega3(self) -> float:
        """ω₃ = φ̇ cosθ + ψ̇ (constant: p_ψ = I₃ω₃)."""
        _, th, _, dphi, _, dpsi = self._init()
        return dphi * math.cos(th) + dpsi

    def momenta(self) -> tuple[float, float]:
        """(p_φ, p_ψ) = ((I₁sin²θ + I₃cos²θ)φ̇ + I₃ψ̇cosθ, I₃ω₃) (PHYS0500 eqs. 7.3, 7.4)."""
        I1, I3, _ = self._consts()
        _, th, _, dphi, _, dpsi = self._init()
        s, c = math.sin(th), math.cos(th)
        return (I1 * s * s + I3 * c * c) * dphi + I3 * dpsi * c, I3 * self.omega3()

    def steady_precession_rates(self, theta: float | None = None,
                                omega3: float | None = None) -> tuple[float, ...]:
        """Real roots Ω of I₁cosθ Ω² − I₃ω₃Ω + MgR = 0 (Lecture 10, eq. 10.41), ascending.

        Empty when the reality condition I₃²ω₃² ≥ 4I₁MgR cosθ (10.42) fails.
        """
        I1, I3, mgr = self._consts()
        th = self.value("initial.theta") if theta is None else theta
        w3 = self.omega3() if omega3 is None else omega3
        a, b, c = I1 * math.cos(th), -I3 * w3, mgr
        if abs(a) < 1e-15 * max(abs(b), 1.0):
            return (-c / b,) if b != 0 else ()
        disc = b * b - 4 * a * c
        if disc < 0:
            return ()
        sq = math.sqrt(disc)
        # numerically stable pair of roots
        qq = -0.5 * (b + math.copysign(sq, b)) if b != 0 else -0.5 * sq
        roots = (qq / a, c / qq) if qq != 0 else (math.sqrt(-c / a), -math.sqrt(-c / a))
        return tuple(sorted(roots))

    def sleeping_threshold(self) -> float:
        """ω₃ above which the upright (θ = 0) top is stable: I₃²ω₃² > 4I₁MgR."""
        I1, I3, mgr = self._consts()
        return 2 * math.sqrt(I1 * mgr) / I3

    def conical_pendulum_rate(self, theta: float | None = None) -> float:
        """Suspended top without spin (ω₃ = 0, θ > π/2): Ω² = MgR/(I₁|cosθ|) (10.46)."""
        I1, _, mgr = self._consts()
        th = self.value("initial.theta") if theta is None else theta
        return math.sqrt(mgr / (I1 * abs(math.cos(th))))

    def effective_potential(self, theta: np.ndarray) -> np.ndarray:
        """V(θ) = (p_φ − p_ψcosθ)²/(2I₁sin²θ) + MgR cosθ (PHYS0500 eq. 7.8)."""
        I1, _, mgr = self._consts()
        pphi, ppsi = self.momenta()
        th = np.asarray(theta, dtype=float)
        return (pphi - ppsi * np.cos(th)) ** 2 / (2 * I1 * np.sin(th) ** 2) + mgr * np.cos(th)

    def curves(self) -> tuple[Curve, ...]:
        """V(θ) with E′ and the nutation bounds where they meet (none where the bounds
        cannot be found)."""
        from mechsim.systems.curves import top_potential

        try:
            return (top_potential(self),)
        except (ValueError, ArithmeticError):
            return ()

    def nutation_bounds(self) -> tuple[float, float]:
        """Turning points θ₁ ≤ θ ≤ θ₂: roots u = cosθ in [−1, 1] of
        f(u) = (1 − u²)(α − β′u) − (b − au)², α = 2E′/I₁, β′ = 2MgR/I₁, a = p_ψ/I₁,
        b = p_φ/I₁ (catalog 003 §7.8.1 [SUPPLEMENT]; E′ = ½I₁θ̇² + V(θ), eq. 7.7)."""
        I1, _, mgr = self._consts()
        _, th, _, _, dth, _ = self._init()
        pphi, ppsi = self.momenta()
        e_prime = 0.5 * I1 * dth**2 + float(self.effective_potential(np.array(th)))
        al, be, a, b = 2 * e_prime / I1, 2 * mgr / I1, ppsi / I1, pphi / I1
        coeffs = [be, -(al + a * a), 2 * a * b - be, al - b * b]
        roots = np.roots(coeffs if be != 0 else coeffs[1:])
        u0 = math.cos(th)
        real = sorted(min(max(float(r.real), -1.0), 1.0) for r in roots
                      if abs(r.imag) < 1e-7 and -1 - 1e-9 <= r.real <= 1 + 1e-9)

        def f(u: float) -> float:
            return (1 - u * u) * (al - be * u) - (b - a * u) ** 2

        for lo, hi in zip(real, real[1:], strict=False):
            if lo - 1e-9 <= u0 <= hi + 1e-9 and f(0.5 * (lo + hi)) > 0:
                return math.acos(hi), math.acos(lo)
        return th, th  # steady precession: a double root at cos θ₀

    def free_precession_rates(self) -> tuple[float, float]:
        """Torque-free top: (Ω_body, Ω_space). ω precesses about x₃ in the body at
        Ω = ω₃(I₃ − I₁)/I₁ (PHYS0500 §7.8, line 1805 with ω₃ restored); x₃ and ω precess
        about the fixed L in space at |L|/I₁ (catalog 003 §7.8 [SUPPLEMENT])."""
        I1, I3, _ = self._consts()
        _, th, psi, dphi, dth, _ = self._init()
        w3 = self.omega3()
        w1 = dphi * math.sin(th) * math.sin(psi) + dth * math.cos(psi)
        w2 = dphi * math.sin(th) * math.cos(psi) - dth * math.sin(psi)
        L = math.sqrt((I1 * w1) ** 2 + (I1 * w2) ** 2 + (I3 * w3) ** 2)
        return w3 * (I3 - I1) / I1, L / I1


class _QuaternionTop(SymmetricTop, QuaternionRigidBody):
    kernel_functions = (*RIGID_KERNELS, invariants, top_euler, observables, frames)

    def rigid_data(self) -> RigidData:
        I1, I3, _ = self._consts()
        return RigidData(moments=(I1, I1, I3), center_of_mass=(0.0, 0.0,
                                                               self.value("cm_distance")),
                         weight=self.value("mass") * self.value("gravity"))

    def initial_attitude(self) -> tuple[np.ndarray, np.ndarray]:
        phi, th, psi, dphi, dth, dpsi = self._init()
        q = np.empty(4)
        quat_from_euler_zxz(phi, th, psi, q)
        w = np.array([dphi * math.sin(th) * math.sin(psi) + dth * math.cos(psi),
                      dphi * math.sin(th) * math.cos(psi) - dth * math.sin(psi),
                      dphi * math.cos(th) + dpsi])
        return q, w

    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray,
                  work_terms: bool = True) -> np.ndarray | None:
        """The motion in closed form: torque-free (gravity 0) as any rigid body, else
        Lagrange's top (``lagrange_motion``); None where the top comes near the vertical."""
        if self.torque_free():
            return super().propagate(t0, y0, t, work_terms)
        t = np.ascontiguousarray(t, dtype=float)
        y0 = np.ascontiguousarray(y0, dtype=float)
        I1, I3, mgr = self._consts()
        motion = self.motion_constants(y0, lambda: lagrange_motion((I1, I3), mgr, y0))
        if motion is None:
            return None
        rows = np.empty((t.size, y0.size))
        _lagrange_top_rows(t, float(t0), *motion, y0, rows)
        return rows

    @property
    def invariants(self) -> tuple[Quantity, ...]:
        return INVARIANTS + super().invariants

    @property
    def observables(self) -> tuple[Quantity, ...]:
        return OBSERVABLES

    @property
    def frames(self) -> tuple[FrameSpec, ...]:
        return FRAMES


class _EulerAngleTop(SymmetricTop, LagrangianModel):
    def declare(self, b: LagrangianBuilder) -> None:
        phi, dphi = b.coordinate("phi", "rad")
        th, dth = b.coordinate("theta", "rad")
        psi, dpsi = b.coordinate("psi", "rad")
        M, g, R = b.param("mass"), b.param("gravity"), b.param("cm_distance")
        I1, I3 = b.param("transverse_inertia"), b.param("axial_inertia")
        w1 = dphi * sp.sin(th) * sp.sin(psi) + dth * sp.cos(psi)
        w2 = dphi * sp.sin(th) * sp.cos(psi) - dth * sp.sin(psi)
        w3 = dphi * sp.cos(th) + dpsi
        b.kinetic = I1 * (dth**2 + dphi**2 * sp.sin(th) ** 2) / 2 + I3 * w3**2 / 2
        b.potential = M * g * R * sp.cos(th)
        b.invariant("p_phi", "kg m^2/s", sp.diff(b.kinetic, dphi))
        b.invariant("p_psi", "kg m^2/s", sp.diff(b.kinetic, dpsi))
        values = {"phi": phi, "theta": th, "psi": psi, "precession_rate": dphi,
                  "nutation_rate": dth, "spin_rate": dpsi, "omega_1": w1, "omega_2": w2,
                  "omega_3": w3, "axis_x": sp.sin(th) * sp.sin(phi),
                  "axis_y": -sp.sin(th) * sp.cos(phi), "axis_z": sp.cos(th)}
        for q in OBSERVABLES:
            b.observable(q.name, q.unit, values[q.name])
        # q_z(φ) ⊗ q_x(θ) ⊗ q_z(ψ)
        s2, c2 = sp.sin(th / 2), sp.cos(th / 2)
        body = (s2 * sp.cos((phi - psi) / 2), s2 * sp.sin((phi - psi) / 2),
                c2 * sp.sin((phi + psi) / 2), c2 * sp.cos((phi + psi) / 2))
        nodes = (s2 * sp.cos(phi / 2), s2 * sp.sin(phi / 2), c2 * sp.sin(phi / 2),
                 c2 * sp.cos(phi / 2))
        b.frame("body", "world", (0, 0, 0), body)
        b.frame("nodes", "world", (0, 0, 0), nodes)
        b.frame("center_of_mass", "body", (0, 0, R))

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        phi, th, psi, dphi, dth, dpsi = self._init()
        return np.array([phi, th, psi]), np.array([dphi, dth, dpsi])


MODEL = SymmetricTop
