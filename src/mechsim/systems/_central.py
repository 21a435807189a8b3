"""Shared physics of central-force motion (PHYS0500 ch. 4, Introduction to analytical mechanics,
“Central force problem – with two body” to “Closed orbits of the two body problem”): the relative
orbit's first integrals as sympy expressions, and the analytic oracles (effective potential, turning
points, Kepler elements, conic classes, Kepler's equation), and the three-dimensional orbit vectors
L and A with the orbit frame they define. Used by ``kepler``, ``central_force``,
``central_force_3d`` and ``two_body_field``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from mechsim.systems._symbolic import sympy as sp
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel

if TYPE_CHECKING:
    from sympy import Expr


#: A function of the radius taking a float or an array of radii (numpy broadcasting).
Radial = Callable[[Any], Any]


def declare_orbit_quantities(b: LagrangianBuilder, mu: Expr, x: Expr, y: Expr, dx: Expr,
                             dy: Expr, k: Expr | None = None, conserved: bool = True,
                             radius: Expr | None = None, angular_momentum: Expr | None = None
                             ) -> tuple[Expr, Expr]:
    """Declare l = μ(x ẏ − y ẋ) (an invariant if ``conserved``, else an observable), for
    U = −k/r also the Laplace–Runge–Lenz vector A = μ v × L − μ k r̂ (invariant), and the
    observables radius r and areal velocity dA/dt = l / (2μ). Returns (r, l)."""
    r = radius if radius is not None else sp.sqrt(x**2 + y**2)
    Lz = angular_momentum if angular_momentum is not None else mu * (x * dy - y * dx)
    (b.invariant if conserved else b.observable)("angular_momentum", "kg m^2/s", Lz)
    if k is not None:
        b.invariant("runge_lenz_x", "kg^2 m^3/s^2", mu * Lz * dy - mu * k * x / r)
        b.invariant("runge_lenz_y", "kg^2 m^3/s^2", -mu * Lz * dx - mu * k * y / r)
    b.observable("radius", "m", r)
    b.observable("areal_velocity", "m^2/s", Lz / (2 * mu))
    return r, Lz


def declare_orbit_vectors(b: LagrangianBuilder, mu: Expr, r: tuple[Expr, Expr, Expr],
                          v: tuple[Expr, Expr, Expr], k: Expr | None = None
                          ) -> tuple[tuple[Expr, Expr, Expr], tuple[Expr, Expr, Expr] | None]:
    """Three-dimensional relative orbit: declare the angular momentum L = μ r × ṙ and, for
    U = −k/r, the Laplace–Runge–Lenz vector A = μ ṙ × L − μ k r̂ as invariants
    (``angular_momentum_x`` …, ``runge_lenz_x`` …), and the eccentricity |A|/(μk) as an
    observable. Returns (L, A) (A None without k)."""
    x, y, z = r
    vx, vy, vz = v
    L = (mu * (y * vz - z * vy), mu * (z * vx - x * vz), mu * (x * vy - y * vx))
    for axis, c in zip("xyz", L, strict=True):
        b.invariant(f"angular_momentum_{axis}", "kg m^2/s", c)
    if k is None:
        return L, None
    rn = sp.sqrt(x**2 + y**2 + z**2)
    A = (mu * (vy * L[2] - vz * L[1]) - mu * k * x / rn,
         mu * (vz * L[0] - vx * L[2]) - mu * k * y / rn,
         mu * (vx * L[1] - vy * L[0]) - mu * k * z / rn)
    for axis, c in zip("xyz", A, strict=True):
        b.invariant(f"runge_lenz_{axis}", "kg^2 m^3/s^2", c)
    b.observable("eccentricity", "", sp.sqrt(A[0] ** 2 + A[1] ** 2 + A[2] ** 2) / (mu * k))
    return L, A


def vector_law_scales(scales: dict[str, float], angular_momentum: float,
                      runge_lenz: float | None = None, energy: float | None = None
                      ) -> dict[str, float]:
    """Drift scales for the component laws of ``declare_orbit_vectors``: |L| for each L
    component, μk for each A component (|A| = μkε), and ``energy`` for per-axis energies
    (``energy_x`` …): a component's own initial value may be zero or round-off (cos π/2), which
    would make round-off look like a large relative drift."""
    out = dict(scales)
    for key in out:
        name = key.split(":", 1)[-1]
        if name.startswith("angular_momentum_") and angular_momentum > 0:
            out[key] = angular_momentum
        elif name.startswith("runge_lenz_") and runge_lenz:
            out[key] = runge_lenz
        elif name.startswith("energy_") and energy:
            out[key] = energy
    return out


def orbit_quaternion(L: tuple[Expr, Expr, Expr], A: tuple[Expr, Expr, Expr] | None = None
                     ) -> tuple[Expr, Expr, Expr, Expr]:
    """Quaternion (x, y, z, w) of the orbit frame: z along L, x toward periapsis (along A;
    along the ascending node n̂ = ẑ × L/|ẑ × L| without A), as the z-x-z rotation by the node
    longitude Ω = atan2(L_x, −L_y), the inclination i and the argument of periapsis ω:
    q = q_z(Ω) q_x(i) q_z(ω). At i = 0 only Ω + ω matters and both come from the same n̂."""
    Lx, Ly, Lz = L
    node = sp.atan2(Lx, -Ly)
    incl = sp.atan2(sp.sqrt(Lx**2 + Ly**2), Lz)
    if A is None:
        arg = sp.Integer(0)
    else:
        nx, ny = sp.cos(node), sp.sin(node)
        Ln = sp.sqrt(Lx**2 + Ly**2 + Lz**2)
        # A·(L × n̂) and |L| A·n̂: the sine and cosine of ω, both times |L||A|
        arg = sp.atan2(A[0] * (-Lz * ny) + A[1] * (Lz * nx) + A[2] * (Lx * ny - Ly * nx),
                       Ln * (A[0] * nx + A[1] * ny))
    ci, si = sp.cos(incl / 2), sp.sin(incl / 2)
    return (si * sp.cos((node - arg) / 2), si * sp.sin((node - arg) / 2),
            ci * sp.sin((node + arg) / 2), ci * sp.cos((node + arg) / 2))


# --- oracles ------------------------------------------------------------------------------------
def effective_potential(U: Callable[[float], float], mu: float, l: float
                        ) -> Callable[[float], float]:
    """V_eff(r) = U(r) + l² / (2 μ r²) (PHYS0500 line 960, Introduction to analytical mechanics,
    “Classification of the orbits”)."""
    return lambda r: U(r) + l * l / (2 * mu * r * r)


def turning_points(U: Callable[[float], float], mu: float, E: float, l: float,
                   r_min: float = 1e-6, r_max: float = 1e6, samples: int = 20000
                   ) -> list[float]:
    """All radii in [r_min, r_max] where E = V_eff(r) (PHYS0500 line 913), by sign changes on
    a logarithmic grid refined with brentq."""
    from scipy.optimize import brentq  # here: importing scipy.optimize costs 0.2-0.4 s

    V = effective_potential(U, mu, l)
    grid = np.geomspace(r_min, r_max, samples)
    g = np.array([E - V(r) for r in grid])
    roots = []
    for i in range(samples - 1):
        if g[i] == 0.0:
            roots.append(float(grid[i]))
        elif g[i] * g[i + 1] < 0:
            roots.append(brentq(lambda r: E - V(r), grid[i], grid[i + 1], xtol=1e-300,
                                rtol=1e-15))
    return roots


def radial_range(U: Callable[[float], float], mu: float, E: float, l: float, r0: float,
                 rdot0: float, r_min: float, r_max: float) -> tuple[float, float]:
    """(r_min, r_max) of the motion from (r₀, ṙ₀): the turning points E = V_eff(r) around r₀
    (``turning_points`` on [r_min, r_max]; r_max = ∞ when unbound, r_min = 0 when nothing
    stops an inward motion); r₀ twice for a circular orbit."""
    V = effective_potential(U, mu, l)
    tp = turning_points(U, mu, E, l, r_min=r_min, r_max=r_max)
    inner = [r for r in tp if r < r0 * (1 - 1e-7)]
    outer = [r for r in tp if r > r0 * (1 + 1e-7)]
    lo = max(inner) if inner else 0.0
    hi = min(outer) if outer else math.inf
    if rdot0 == 0.0:  # r0 is a turning point: the side where E ≥ V_eff is the motion
        h = 1e-6 * r0
        slope = (V(r0 + h) - V(r0 - h)) / (2 * h)
        force = abs(U(r0 + h) - U(r0 - h)) / (2 * h) + l * l / (mu * r0**3)
        if abs(slope) < 1e-7 * force:
            return r0, r0  # circular orbit
        return (lo, r0) if slope > 0 else (r0, hi)
    if rdot0 > 0 and not math.isfinite(hi):
        lo = r0  # moving out with nothing to turn it back
    return lo, hi


def nearest_turning_points(gap: Radial, r0: float, rdot0: float,
                           r_min: float, r_max: float) -> tuple[float, float]:
    """(r_min, r_max) of the motion from (r₀, ṙ₀): the roots of gap(r) = E − V_eff(r) nearest
    to r₀ on each side, found by stepping away from r₀ in geometrically growing steps (from
    1e-9 r₀) to the first sign change and refining it with brentq, so that the apsides of a
    nearly circular orbit, any distance apart, are found (a fixed grid misses roots closer
    than its spacing). r_max = ∞ where nothing turns the motion back before ``r_max``,
    r_min = 0 where nothing does before ``r_min``; (r₀, r₀) for a circular orbit. With
    ṙ₀ = 0, r₀ is itself the turning point on the side where E < V_eff."""
    from scipy.optimize import brentq  # here: importing scipy.optimize costs 0.2-0.4 s

    def search(sign: int, limit: float) -> float | None:
        s, inside = 1e-9, r0
        while True:
            r = r0 * math.exp(sign * s)
            if (sign < 0 and r <= limit) or (sign > 0 and r >= limit):
                return None
            if gap(r) < 0.0:
                a, b = (r, inside) if sign < 0 else (inside, r)
                return float(brentq(gap, a, b, xtol=1e-15 * r0, rtol=8.9e-16))
            inside = r
            s *= 2.0

    if rdot0 == 0.0:
        inward, outward = gap(r0 * (1 - 1e-7)), gap(r0 * (1 + 1e-7))
        if inward <= 0.0 and outward <= 0.0:
            return r0, r0  # circular
        if inward <= 0.0:  # moving out from the pericentre r₀
            hi = search(+1, r_max)
            return r0, math.inf if hi is None else hi
        lo = search(-1, r_min)
        return 0.0 if lo is None else lo, r0
    lo, hi = search(-1, r_min), search(+1, r_max)
    if hi is None and rdot0 > 0.0:
        return r0, math.inf  # moving out with nothing to turn it back
    return 0.0 if lo is None else lo, math.inf if hi is None else hi


def orbit_integral(gap: Radial, mu: float, lo: float, hi: float,
                   weight: Callable[[np.ndarray], np.ndarray] | None = None,
                   nodes: int = 256) -> float:
    """∫ w(r) dr / ṙ from the turning point ``lo`` to ``hi``, ṙ = √((2/μ) gap(r)) with
    gap(r) = E − V_eff(r) (vectorized): the time (w = 1; PHYS0500 eq. 4.3) or the angle
    (w = l/(μr²); eq. 4.4) the motion takes between the apsides. Gauss–Chebyshev quadrature
    of the first kind: the gap has simple roots at both ends, so
    f = w √((r − lo)(hi − r)/((2/μ) gap)) is smooth on [lo, hi] and the nodes converge
    geometrically. Near the ends the gap is small: it must be computed without cancellation
    (not as E − V_eff(r) with E and V_eff large) for the result to keep its digits on a nearly
    circular orbit."""
    k = np.arange(1, nodes + 1)
    x = np.cos((2 * k - 1) * math.pi / (2 * nodes))  # nodes on (−1, 1)
    r = 0.5 * (hi + lo) + 0.5 * (hi - lo) * x
    g = (2 / mu) * np.asarray(gap(r), dtype=float)
    f = np.sqrt((r - lo) * (hi - r) / np.maximum(g, 1e-300))
    if weight is not None:
        f = f * weight(r)
    return float(math.pi / nodes * np.sum(f))


def apsidal_angle(gap: Radial, mu: float, l: float, lo: float,
                  hi: float) -> float:
    """The angle swept from one apsis to the next, ½Δθ of PHYS0500 §4.4:
    ∫_{r_min}^{r_max} (l/r²) dr / √(2μ(E − U − l²/2μr²)) (``orbit_integral``). The orbit
    closes iff Δθ = 2π a/b with a, b whole."""
    return orbit_integral(gap, mu, lo, hi, weight=lambda r: l / (mu * r * r))


def merge_at_capture(model: LagrangianModel, t: float, y: np.ndarray, rates: tuple[int, ...],
                     mode: int) -> np.ndarray:
    """What a fall to the centre does (an event at the capture radius): the bodies merge,
    the relative rates ``rates`` (state indices) stop, the mode at index ``mode`` switches the
    potential off, and the relative energy lost goes into work_dissipated so that the work
    balance still closes."""
    layout = model.layout
    p = model.parameter_vector()
    before = np.empty(3)
    model.kernels.energy(t, y, p, before)
    for i in rates:
        y[i] = 0.0
    y[mode] = 1.0
    after = np.empty(3)
    model.kernels.energy(t, y, p, after)
    y[layout.work_dissipated] += (before[0] + before[1]) - (after[0] + after[1])
    return y


def conic_class(eccentricity: float, tol: float = 1e-9) -> str:
    """Seed 003 conic table (line 996): circle, ellipse, parabola or hyperbola."""
    if eccentricity < tol:
        return "circle"
    if abs(eccentricity - 1.0) < tol:
        return "parabola"
    return "ellipse" if eccentricity < 1.0 else "hyperbola"


def kepler_elements(mu: float, k: float, E: float, l: float) -> dict[str, float]:
    """Orbit of U = −k/r from E and l (PHYS0500 lines 984–1042, ε typo fixed):
    α = l²/(μk), ε = √(1 + 2El²/(μk²)), r_min = α/(1 + ε), r_max = α/(1 − ε) (∞ unless bound),
    a = k/(2|E|), τ = 2π √(μ a³ / k) (bound orbits), V_min = −μk²/(2l²)."""
    alpha = l * l / (mu * k)
    eps = math.sqrt(max(0.0, 1.0 + 2.0 * E * l * l / (mu * k * k)))
    out = {"semi_latus_rectum": alpha, "eccentricity": eps, "r_min": alpha / (1 + eps),
           "r_max": alpha / (1 - eps) if eps < 1 else math.inf,
           "effective_minimum": -mu * k * k / (2 * l * l)}
    if E < 0:
        a = k / (2 * abs(E))
        out.update(semi_major_axis=a, semi_minor_axis=l / math.sqrt(2 * mu * abs(E)),
                   period=2 * math.pi * math.sqrt(mu * a**3 / k))
    return out


def pericentre_time(gm: float, r: np.ndarray, v: np.ndarray) -> float:
    """Pericentre passage time 2π √(r_p³ / (GM (1 + e))) of r̈ = −GM r/r³ from the state
    (r, v), in specific quantities (h = |r × v|, p = h²/GM, e from the specific energy): the
    time that limits a fixed step. 1 s when the values leave it undefined (h = 0, or
    parameters so extreme that it under- or overflows): it is only a step-size hint."""
    try:
        with np.errstate(all="ignore"):
            rn, h = math.hypot(*r), math.hypot(*np.cross(r, v))
            energy = 0.5 * math.hypot(*v) ** 2 - gm / rn
            p = h * h / gm
            e = math.sqrt(max(0.0, 1.0 + 2.0 * energy * p / gm))
            rp = p / (1.0 + e)
            ts = 2 * math.pi * math.sqrt(rp**3 / (gm * (1.0 + e)))
    except (ArithmeticError, ValueError):
        return 1.0
    return ts if math.isfinite(ts) and ts > 0 else 1.0


def eccentric_anomaly(M: np.ndarray, e: float) -> np.ndarray:
    """Solve Kepler's equation M = E − e sin E (Newton iteration)."""
    M_full = np.asarray(M, dtype=float)
    turns = np.floor(M_full / (2 * math.pi))
    M = M_full - 2 * math.pi * turns  # solve in [0, 2π), add the whole turns back
    E = M + 0.85 * e * np.sign(np.sin(M))  # Danby's start: converges for every e < 1
    for _ in range(50):
        dE = (E - e * np.sin(E) - M) / (1 - e * np.cos(E))
        E = E - dE
        if np.max(np.abs(dE)) < 1e-15:
            break
    return E + 2 * math.pi * turns


def kepler_propagate(gm: float, r0: np.ndarray, v0: np.ndarray, dt: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray] | None:
    """Exact two-body motion r̈ = −GM r/|r|³ from (r₀, v₀) after times dt, by Kepler's
    equation in difference form and the f and g functions (elliptic orbits; None otherwise).

    With e cos E₀ = 1 − r₀/a and e sin E₀ = r₀·v₀/√(GM a), the eccentric-anomaly change ΔE
    solves n dt = ΔE − e cos E₀ sin ΔE + e sin E₀ (1 − cos ΔE); then r = f r₀ + g v₀,
    v = ḟ r₀ + ġ v₀ with f = 1 − (a/r₀)(1 − cos ΔE), g = dt − (ΔE − sin ΔE)/n,
    ḟ = −√(GM a) sin ΔE/(r r₀), ġ = 1 − (a/r)(1 − cos ΔE).
    """
    r0 = np.asarray(r0, dtype=float)
    v0 = np.asarray(v0, dtype=float)
    rn = float(np.linalg.norm(r0))
    energy = 0.5 * float(v0 @ v0) - gm / rn
    if not (rn > 0 and energy < 0):
        return None
    a = -gm / (2 * energy)
    n = math.sqrt(gm / a**3)
    c = 1 - rn / a
    s = float(r0 @ v0) / math.sqrt(gm * a)
    dt = np.asarray(dt, dtype=float)
    Mr = np.mod(n * dt, 2 * math.pi)  # the motion is periodic: reduce the mean-anomaly change
    # Absolute form: E₀ from (e cos E₀, e sin E₀), M₀ = E₀ − e sin E₀; Danby's start.
    e = math.hypot(c, s)
    E0 = math.atan2(s, c)
    M = (E0 - s) + Mr
    E = M + 0.85 * e * np.sign(np.sin(M))
    for _ in range(60):
        step = (E - e * np.sin(E) - M) / (1 - e * np.cos(E))
        E = E - step
        if np.max(np.abs(step), initial=0.0) < 4e-16 * max(1.0, float(np.max(np.abs(M)))):
            break
    dE = E - E0
    r = a * (1 - c * np.cos(dE) + s * np.sin(dE))
    f = 1 - (a / rn) * (1 - np.cos(dE))
    g = (Mr - (dE - np.sin(dE))) / n
    fd = -math.sqrt(gm * a) * np.sin(dE) / (r * rn)
    gd = 1 - (a / r) * (1 - np.cos(dE))
    pos = f[:, None] * r0 + g[:, None] * v0
    vel = fd[:, None] * r0 + gd[:, None] * v0
    return pos, vel
