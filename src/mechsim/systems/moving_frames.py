"""Moving frames on the twisted cubic: VBN, RIC and Frenet–Serret, with their angular velocities.

Source: “Moving Frames and the Twisted Cubic” (L893–981) and “Minimal Frames”
(L983–1152). Prescribed kinematics: a point runs along r(u) = (u, u², u³) with the curve
parameter u advancing at the constant rate u̇ (``initial_rate.curve_parameter``; the document
identifies u with time, u̇ = 1, and plots u ∈ [−2, 2]). Nothing is integrated but u itself and
the work of the force m r̈ that prescribes the motion (so T = ½ m |ṙ|² closes the work balance).

Frames (rows e₁, e₂, e₃ are the axes; all published right-handed, parent ``world``):
- ``vbn``: (V̂, N̂, B̂) with V̂ = v/|v|, N̂ = r×v/|r×v| (orbit normal), B̂ = V̂×N̂. The document
  names it "VBN", but the literal order (V̂, B̂, N̂) is left-handed (V̂×B̂ = −N̂); the frame
  published here is the same three vectors in the right-handed order x = V̂, y = N̂, z = B̂.
  So the document's (V, B, N) components are our (x, z, y).
- ``ric``: (R̂, Î, Ĉ) with R̂ = r/|r|, Ĉ = r×v/|r×v|, Î = Ĉ×R̂ (right-handed as given).
- ``frenet``: (T̂, N̂_F, B̂_F), T̂ = v/|v|, B̂_F = v×a/|v×a|, N̂_F = B̂_F×T̂ (principal normal).

The conventions are those of every VBN/RIC frame mechsim publishes (``_moving_frame``, shared
with ``orbit_frames``). Angular velocities: ω is the angular velocity of the frame relative to
``world`` in the usual sense ė_i = ω × e_i, published as its components along the frame's own
axes. The document's moving-frame matrix
(ė₁; ė₂; ė₃) = [[0, α, β], [−α, 0, γ], [−β, −γ, 0]] (e₁; e₂; e₃) then has α = ω₃, β = −ω₂,
γ = ω₁. The document's mapping "α → −ω_z, β → ω_y, γ → −ω_x" (L963) is this with all signs
flipped, i.e. it describes −ω; magnitudes and minimality are the same.
RIC is minimal: ω along Î is identically zero (published as the invariant ``ric_omega_y``);
so is Frenet–Serret (Darboux vector ω = |v|(τ T̂ + κ B̂), invariant ``frenet_omega_y``).

The t = 0 point (u = 0): r = 0 and r×v = 0, so the document's formulas divide by zero. Here
every unit vector is built from a factor that does not vanish: r×v = u² (u², −2u, 1) and
r = u (1, u, u²), so N̂ = Ĉ = (u², −2u, 1)/|·| is smooth through u = 0 and R̂ = sgn(u)(1, u,
u²)/|·|. R̂ (hence the RIC frame) genuinely flips at u = 0; exactly at u = 0 the limit from
u > 0 is published (R̂ = x̂, Î = ŷ). No output is NaN anywhere.

Document typos corrected: dB̂/dt uses N⃗, V⃗ for N̂, V̂ (L940); the norm derivative's exponent
1/2 should be −1/2 (L1035); L965 says "angular momentum" for angular velocity.
"""

from __future__ import annotations

import math

import numpy as np

from mechsim.codegen.support import tensor as _tensor
from mechsim.codegen.support import vector as _vector
from mechsim.codegen.support import zero_vector as _zero_vector
from mechsim.params import Parameter, positive
from mechsim.systems._moving_frame import FRAME_COLORS, omega_quantities
from mechsim.systems._rotation import quat_from_rows
from mechsim.systems.base import FrameSpec, Quantity, Structure, Visual
from mechsim.systems.direct import DirectModel

# --- kernel functions (pasted into the kernel module; see mechsim.systems.direct) -----------
# Index of mass in p (the first numeric parameter); the kernel module generates the same
# value, which ``DirectModel`` checks.
P_MASS = 0


def _unit(w, dw, e, de):
    """e = w/|w| and its derivative de = dw/|w| − w (w·dw)/|w|³ (w must not vanish)."""
    n2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
    n = math.sqrt(n2)
    wd = w[0] * dw[0] + w[1] * dw[1] + w[2] * dw[2]
    for i in range(3):
        e[i] = w[i] / n
        de[i] = dw[i] / n - w[i] * wd / (n2 * n)


def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


def _cross_rate(a, da, b, db, out, dout):
    """out = a × b and dout = da × b + a × db."""
    t1 = _vector(3)
    t2 = _vector(3)
    _cross(a, b, out)
    _cross(da, b, t1)
    _cross(a, db, t2)
    for i in range(3):
        dout[i] = t1[i] + t2[i]


def _twisted_cubic_frames(u, E, dE):
    """Axes E[f, i, :] of frame f (0 VBN, 1 RIC, 2 Frenet) and their u-derivatives dE."""
    w = _vector(3)
    dw = _vector(3)
    # V̂ = T̂ from r' = (1, 2u, 3u²)
    w[0], w[1], w[2] = 1.0, 2.0 * u, 3.0 * u * u
    dw[0], dw[1], dw[2] = 0.0, 2.0, 6.0 * u
    _unit(w, dw, E[0, 0], dE[0, 0])
    for k in range(3):
        E[2, 0, k] = E[0, 0, k]
        dE[2, 0, k] = dE[0, 0, k]
    # N̂ = Ĉ from (r × r')/u² = (u², −2u, 1)
    w[0], w[1], w[2] = u * u, -2.0 * u, 1.0
    dw[0], dw[1], dw[2] = 2.0 * u, -2.0, 0.0
    _unit(w, dw, E[0, 1], dE[0, 1])
    for k in range(3):
        E[1, 2, k] = E[0, 1, k]
        dE[1, 2, k] = dE[0, 1, k]
    # B̂ = V̂ × N̂
    _cross_rate(E[0, 0], dE[0, 0], E[0, 1], dE[0, 1], E[0, 2], dE[0, 2])
    # R̂ from sgn(u) r/u = sgn(u) (1, u, u²); sgn(0) = +1 (limit from u > 0)
    s = -1.0 if u < 0.0 else 1.0
    w[0], w[1], w[2] = s, s * u, s * u * u
    dw[0], dw[1], dw[2] = 0.0, s, 2.0 * s * u
    _unit(w, dw, E[1, 0], dE[1, 0])
    # Î = Ĉ × R̂
    _cross_rate(E[1, 2], dE[1, 2], E[1, 0], dE[1, 0], E[1, 1], dE[1, 1])
    # Frenet: B̂_F from r' × r'' = (6u², −6u, 2), N̂_F = B̂_F × T̂
    w[0], w[1], w[2] = 6.0 * u * u, -6.0 * u, 2.0
    dw[0], dw[1], dw[2] = 12.0 * u, -6.0, 0.0
    _unit(w, dw, E[2, 2], dE[2, 2])
    _cross_rate(E[2, 2], dE[2, 2], E[2, 0], dE[2, 0], E[2, 1], dE[2, 1])


def _frame_omega(E, dE, rate, f, out):
    """Body components of ω of frame f: ω = ½ Σ e_i × ė_i (ė = u̇ de/du), then ω·e_j."""
    wv = _zero_vector(3)
    c = _vector(3)
    for i in range(3):
        _cross(E[f, i], dE[f, i], c)
        for k in range(3):
            wv[k] += 0.5 * rate * c[k]
    for j in range(3):
        out[j] = wv[0] * E[f, j, 0] + wv[1] * E[f, j, 1] + wv[2] * E[f, j, 2]


def _power(u, rate, p):
    """Power m r̈·ṙ of the force that drives the point along the curve at constant u̇."""
    return p[P_MASS] * (rate * (rate * rate)) * (4.0 * u + 18.0 * (u * (u * u)))


def rhs(t, y, p, dy):
    dy[0] = y[1]
    dy[1] = 0.0
    dy[2] = _power(y[0], y[1], p)
    dy[3] = 0.0


def energy(t, y, p, out):
    u, rate = y[0], y[1]
    out[0] = 0.5 * p[P_MASS] * rate * rate * (1.0 + 4.0 * u * u + 9.0 * ((u * u) * (u * u)))
    out[1] = 0.0
    out[2] = out[0]


def invariants(t, y, p, out):
    E = _tensor(3, 3, 3)
    dE = _tensor(3, 3, 3)
    _twisted_cubic_frames(y[0], E, dE)
    w = _vector(3)
    _frame_omega(E, dE, y[1], 1, w)
    out[0] = w[1]
    _frame_omega(E, dE, y[1], 2, w)
    out[1] = w[1]


def observables(t, y, p, out):
    u, rate = y[0], y[1]
    E = _tensor(3, 3, 3)
    dE = _tensor(3, 3, 3)
    _twisted_cubic_frames(u, E, dE)
    w = _vector(3)
    for f in range(3):
        _frame_omega(E, dE, rate, f, w)
        for j in range(3):
            out[3 * f + j] = w[j]
        out[9 + f] = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    speed2 = 1.0 + 4.0 * u * u + 9.0 * ((u * u) * (u * u))
    b2 = 36.0 * ((u * u) * (u * u)) + 36.0 * u * u + 4.0  # |r' × r''|²
    out[12] = math.sqrt(b2) / speed2 ** 1.5  # κ = |r' × r''| / |r'|³
    out[13] = 12.0 / b2  # τ = (r' × r'')·r''' / |r' × r''|², r''' = (0, 0, 6)
    out[14] = abs(rate) * math.sqrt(speed2)


def frames(t, y, p, out):
    u = y[0]
    E = _tensor(3, 3, 3)
    dE = _tensor(3, 3, 3)
    _twisted_cubic_frames(u, E, dE)
    q = _vector(4)
    for f in range(3):
        out[f, 0] = u
        out[f, 1] = u * u
        out[f, 2] = u * u * u
        quat_from_rows(E[f], q)
        for k in range(4):
            out[f, 3 + k] = q[k]


# --- the model --------------------------------------------------------------------------------

FRAME_NAMES = ("vbn", "ric", "frenet")


class MovingFrames(DirectModel):
    id = "moving_frames"
    title = "Moving frames (VBN, RIC, Frenet–Serret) on the twisted cubic"
    source = ("“Moving Frames and the Twisted Cubic” and “Minimal Frames” (blog posts: VBN, RIC, "
              "Frenet–Serret)")
    oracles = ("closed-form VBN/RIC/Frenet axes; ω from finite differences and the table at "
               "u = ±1, ±2; RIC and Frenet ω_y ≡ 0; κ, τ closed forms; Darboux ω = v(τT̂ + κB̂)")
    parameters = (
        positive("mass", 1.0, "kg", "mass of the point moving along the curve (work balance)"),
        Parameter("initial.curve_parameter", -2.0, "", "curve parameter u at t = 0 "
                  "(the document plots u ∈ [−2, 2])", minimum=-10.0, maximum=10.0),
        Parameter("initial_rate.curve_parameter", 1.0, "1/s", "constant rate u̇ (the document "
                  "takes u = t, i.e. 1)", minimum=-10.0, maximum=10.0),
    )
    kernel_functions = (_unit, _cross, _cross_rate, _twisted_cubic_frames, _frame_omega,
                        quat_from_rows, _power, rhs, energy, invariants, observables, frames)

    @property
    def coordinates(self) -> tuple[Quantity, ...]:
        return (Quantity("curve_parameter", "", "u in r(u) = (u, u², u³) [m]"),)

    @property
    def invariants(self) -> tuple[Quantity, ...]:
        return (Quantity("ric_omega_y", "rad/s", "RIC ω along Î (≡ 0: RIC is minimal)"),
                Quantity("frenet_omega_y", "rad/s", "Frenet ω along N̂_F (≡ 0: minimal)"))

    @property
    def observables(self) -> tuple[Quantity, ...]:
        out = list(omega_quantities(FRAME_NAMES))
        out += [Quantity("curvature", "1/m", "κ = |v × a| / |v|³"),
                Quantity("torsion", "1/m", "τ = (v × a)·ȧ / |v × a|²"),
                Quantity("speed", "m/s", "|v|")]
        return tuple(out)

    @property
    def frames(self) -> tuple[FrameSpec, ...]:
        return tuple(FrameSpec(f, "world") for f in FRAME_NAMES)

    def visuals(self) -> tuple[Visual, ...]:
        u = np.linspace(-2.0, 2.0, 161)
        curve = tuple((float(a), float(a * a), float(a ** 3)) for a in u)
        out = [Visual("polyline", "world", points=curve, radius=0.01, color=(180, 180, 180)),
               Visual("sphere", "vbn", radius=0.08)]
        out += [Visual("axes", f, radius=0.6, color=FRAME_COLORS[f]) for f in FRAME_NAMES]
        return tuple(out)

    @property
    def structure(self) -> Structure:
        # The point is driven along the curve: energy changes by the driving work.
        return Structure(separable=False, driven=True)

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.array([self.value("initial.curve_parameter")]),
                np.array([self.value("initial_rate.curve_parameter")]))

    def law_scales(self) -> dict[str, float]:
        """The ω_y ≡ 0 invariants start at round-off: measure them against the frame's |ω|."""
        out = super().law_scales()
        obs = np.zeros(len(self.observables))
        self.kernels.observables(0.0, self.initial_y(), self.parameter_vector(), obs)
        names = [o.name for o in self.observables]
        for frame in ("ric", "frenet"):
            speed = float(obs[names.index(f"{frame}_angular_speed")])
            out[f"invariant:{frame}_omega_y"] = speed if speed > 0 else 1.0
        return out

    def time_scale(self) -> float:
        rate = abs(self.value("initial_rate.curve_parameter"))
        return 1.0 / rate if rate > 0 else 1.0

    # --- analytic oracles ------------------------------------------------------------------
    @staticmethod
    def curvature_at(u: np.ndarray) -> np.ndarray:
        """κ(u) = 2 √(9u⁴ + 9u² + 1) / (1 + 4u² + 9u⁴)^{3/2} (catalog 000 S14, [D✓])."""
        u = np.asarray(u, dtype=float)
        return 2 * np.sqrt(9 * u**4 + 9 * u**2 + 1) / (1 + 4 * u**2 + 9 * u**4) ** 1.5

    @staticmethod
    def torsion_at(u: np.ndarray) -> np.ndarray:
        """τ(u) = 3 / (9u⁴ + 9u² + 1) (catalog 000 S14, [D✓])."""
        u = np.asarray(u, dtype=float)
        return 3 / (9 * u**4 + 9 * u**2 + 1)


MODEL = MovingFrames
