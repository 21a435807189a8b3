"""Figures of the blog series (each post cited by its title): the bead on a wire, the simple
pendulum's multipliers and its small-angle limit, the energy E against the energy function h in
six cases, the restricted three-body problem against the unrestricted one, and the twisted
cubic's moving frames."""

from __future__ import annotations

import math

import numpy as np

from mechsim.figures.render import Drawn, constant_scale, label, new_figure
from mechsim.simulate import simulate
from mechsim.systems import load_system

BEAD = "“Dynamical Systems and Constraints: Part 2 – Bead on a Wire”"
PENDULUM = "“Dynamical Systems and Constraints: Part 3 – Simple Pendulum”"
EXAMPLES = "“Energy and Hamiltonians: Part 3 – Examples”"
ACTION = "“Action and Reaction”, Case 2"
CUBIC = "“Moving Frames and the Twisted Cubic”"


def bead_on_wire(quick: bool) -> Drawn:
    """The post's naive Newtonian form (the 'static' normal force) against the Lagrangian
    reduced form on the parabola z = x² from (1, 1) at rest, and on a straight wire."""
    t_end = 4.0 if quick else 10.0
    runs = {}
    for shape in ("parabola", "line"):
        for form in ("naive", "reduced"):
            m = load_system("bead_on_wire", formulation=form, shape=shape, **{"initial.x": 1.0})
            runs[shape, form] = simulate(m, t_end, 0.005, tolerance=1e-10)
    fig, ax = new_figure(1, 3, height=4.4)
    for form, style in (("naive", "-"), ("reduced", "--")):
        r = runs["parabola", form]
        z = r.q[:, 1] if form == "naive" else r.q[:, 0] ** 2
        ax[0][0].plot(r.q[:, 0], z, style, lw=1, label=f"{form}")
        de = r.total - r.total[0]
        ax[0][2].plot(r.t, de, style, lw=1, label=f"parabola, {form}")
        line = runs["line", form]
        ax[0][2].plot(line.t, line.total - line.total[0], ":", lw=1, label=f"line, {form}")
    xs = np.linspace(-1.2, 1.2, 200)
    ax[0][0].plot(xs, xs**2, color="gray", lw=3, alpha=0.3, label="wire z = x²")
    ax[0][0].set_ylim(-3, 2)
    naive = runs["parabola", "naive"]
    gap = naive.q[:, 1] - naive.q[:, 0] ** 2
    ax[0][1].plot(naive.t, gap, lw=1, label="naive: z − x²")
    label(ax[0][0], "path on the parabola", "x [m]", "z [m]")
    label(ax[0][1], "distance from the wire (naive form)", "t [s]", "z − x² [m]")
    label(ax[0][2], "energy change", "t [s]", "E − E₀ [J]")
    text = (f"{BEAD}: a bead released at rest from (1, 1) m on the wire z = x² (and on the line "
            "z = −0.5 x), g = 9.81 m/s², m = 1 kg. The post's 'Newtonian' form keeps only the "
            "static normal force and leaves the wire, dropping below it while its energy departs "
            "from its start (by about a kilojoule in 10 s, whatever the tolerance); "
            "the Lagrangian form with the constraint substituted stays on the wire and keeps "
            "its energy. On the straight wire both are exact (the missing term is the "
            "curvature's m τ f″ẋ²).")
    return Drawn(fig, text, {"naive_max_gap_m": float(np.max(np.abs(gap))),
                             "reduced_energy_drift_J": float(np.ptp(runs["parabola",
                                                                         "reduced"].total))})


def pendulum_multipliers(quick: bool) -> Drawn:
    """λ of the post's polar multiplier form and of the Cartesian form against −T read off
    the reduced form's state, T = m g cos φ + m R φ̇² (the post's Newtonian tension)."""
    phi0, t_end = 2.5, 6.0
    runs = {f: simulate(load_system("pendulum", formulation=f, **{"initial.angle": phi0}),
                        t_end, 0.01, tolerance=1e-11, method="dop853")
            for f in ("reduced", "polar_multiplier", "multiplier")}
    red = runs["reduced"]
    phi, dphi = red.q[:, 0], red.v[:, 0]
    tension = 9.81 * np.cos(phi) + 1.0 * dphi**2
    fig, ax = new_figure(1, 2)
    ax[0][0].plot(red.t, phi, lw=1, label="φ (reduced form)")
    label(ax[0][0], "angle from straight down", "t [s]", "φ [rad]")
    ax[0][1].plot(red.t, -tension, lw=3, alpha=0.3, color="k",
                  label="−T = −(mg cos φ + mRφ̇²)")
    ax[0][1].plot(red.t, runs["polar_multiplier"].observables["multiplier"], lw=1,
                  label="λ, polar (ρ, φ), ρ − R = 0")
    ax[0][1].plot(red.t, runs["multiplier"].observables["multiplier"], "--", lw=1,
                  label="λ, Cartesian (y, z)")
    label(ax[0][1], "the multiplier is the outward radial force", "t [s]", "λ [N]")
    text = (f"{PENDULUM}: m = 1 kg, R = 1 m, g = 9.81 m/s², released at rest from φ₀ = 2.5 "
            "rad. The multiplier of the post's own polar form (L′ = L + λ(ρ − R)) equals −T "
            "(the post's 'λ = T' has the sign wrong) and the Cartesian form's λ; it is "
            "positive where the rod pushes (T < 0, above the horizontal).")
    lam = runs["polar_multiplier"].observables["multiplier"]
    return Drawn(fig, text, {"max_lambda_plus_tension_N": float(np.max(np.abs(lam + tension))),
                             "min_tension_N": float(tension.min())})


def pendulum_small_angle(quick: bool) -> Drawn:
    """The linearised pendulum beside the exact one: φ(t) at 1 rad, and the period against
    the amplitude, measured from integrated runs (zero crossings), with 4√(R/g) K(k)."""
    from scipy.special import ellipk

    amplitudes = np.linspace(0.2, 3.0, 6 if quick else 12)
    t0 = 2 * math.pi / math.sqrt(9.81)
    exact = 4 * math.sqrt(1 / 9.81) * ellipk(np.sin(amplitudes / 2) ** 2)
    measured = []
    for a, period in zip(amplitudes, exact, strict=True):  # 2.5 periods: two crossings
        run = simulate(load_system("pendulum", **{"initial.angle": float(a)}), 2.5 * period,
                       t0 / 400, tolerance=1e-12, method="dop853")
        measured.append(_period(run.t, run.q[:, 0]))
    fig, ax = new_figure(1, 2)
    runs = {f: simulate(load_system("pendulum", formulation=f, **{"initial.angle": 1.0}),
                        3 * t0, t0 / 200, tolerance=1e-11, method="dop853")
            for f in ("reduced", "small_angle")}
    for f, r in runs.items():
        ax[0][0].plot(r.t, r.q[:, 0], lw=1, label=f"{f} (φ₀ = 1 rad)")
    label(ax[0][0], "exact and linearised motion", "t [s]", "φ [rad]")
    grid = np.linspace(0.01, 3.1, 200)
    ax[0][1].plot(grid, 4 * math.sqrt(1 / 9.81) * ellipk(np.sin(grid / 2) ** 2), lw=1,
                  label="4√(R/g) K(sin²(φ₀/2))")
    ax[0][1].plot(amplitudes, measured, "o", ms=4, label="measured (exact form)")
    ax[0][1].axhline(t0, color="gray", ls="--", lw=1, label="small angle: 2π√(R/g)")
    label(ax[0][1], "period against amplitude", "φ₀ [rad]", "period [s]")
    text = (f"{PENDULUM}, with its small-angle limit: R = 1 m, g = 9.81 m/s², released at rest. "
            "Left: φ(t) of the exact and the linearised pendulum from 1 rad. Right: the period "
            "measured on integrated runs against the closed form 4√(R/g)K(k), k² = sin²(φ₀/2), "
            "and the amplitude-independent 2π√(R/g).")
    err = np.max(np.abs(np.array(measured) / exact - 1))
    return Drawn(fig, text, {"amplitude_rad": float(amplitudes[-1]),
                             "measured_period_s": float(measured[-1]),
                             "max_relative_period_error": float(err)})


def _period(t: np.ndarray, x: np.ndarray) -> float:
    """Mean spacing of successive downward zero crossings of x(t) (linear interpolation)."""
    i = np.flatnonzero((x[:-1] > 0) & (x[1:] <= 0))
    tc = t[i] - x[i] * (t[i + 1] - t[i]) / (x[i + 1] - x[i])
    return float(np.mean(np.diff(tc)))


def energy_and_energy_function(quick: bool) -> Drawn:
    """E = T + V against h = Σ q̇ ∂L/∂q̇ − L in the post's six cases."""
    cases = [
        ("Case 1: Galilean coordinate", "moving_coordinates", {"formulation": "galilean"}),
        ("Case 2: accelerating coordinate", "moving_coordinates",
         {"formulation": "accelerating"}),
        ("Case 3: planar oscillator (polar)", "planar_oscillator", {"formulation": "polar"}),
        ("Case 4: motor-driven spring", "rotating_spring", {}),
        ("Case 5: damped oscillator", "damped_oscillator", {}),
        ("Case 6: time-dependent force", "forced_particle", {}),
    ]
    fig, ax = new_figure(2, 3, height=3.3)
    numbers = {}
    for k, (title, sid, params) in enumerate(cases):
        run = simulate(load_system(sid, **params), 8.0, 0.02, tolerance=1e-10)
        a = ax[k // 3][k % 3]
        a.plot(run.t, run.total, lw=1.5, label="E = T + V")
        h = run.energy_function
        if sid == "damped_oscillator":  # the post's h is Caldirola–Kanai's, not the engine's
            h = run.observables["caldirola_kanai_energy_function"]
        a.plot(run.t, h, "--", lw=1.5, label="h")
        constant_scale(a, run.total, h)
        label(a, title, "t [s]", "[J]")
        if k == 1:
            numbers["case2_h_slope_W"] = float(np.polyfit(run.t, h, 1)[0])
    text = (f"{EXAMPLES}: the energy E and the energy function h in the post's six cases (SI, "
            "m = 1 kg; defaults of moving_coordinates, planar_oscillator, rotating_spring, "
            "damped_oscillator, forced_particle). Case 1: both constant, E ≠ h (h_q = −½mv₀², "
            "not the post's 0); Case 2: E constant, h falls linearly (−m a v₀ per second); "
            "Case 3: E = h; Case 4: only h constant; Case 5: neither (h = e^{bt/m}E); Case 6: "
            "E = h, neither constant.")
    return Drawn(fig, text, numbers)


def jacobi_drift(quick: bool) -> Drawn:
    """The restricted problem's Jacobi integral: exact in the CR3BP, drifting in the
    unrestricted problem, in proportion to the third mass."""
    t_end = 10.0 if quick else 20.0
    fig, ax = new_figure(1, 2)
    cr = simulate(load_system("cr3bp"), t_end, 0.01, tolerance=1e-11, method="dop853")
    ax[0][0].plot(cr.t, cr.invariants["jacobi"], lw=1.5, label="J (CR3BP)")
    ax[0][0].plot(cr.t, cr.observables["inertial_energy"], lw=1, label="E per unit mass")
    ax[0][0].plot(cr.t, -cr.observables["angular_momentum_z"], lw=1, label="−L_z per unit mass")
    label(ax[0][0], "restricted problem: J kept, E and L_z exchanged", "t [s]",
          "[J/kg], [m²/s]")
    numbers = {}
    for m3 in (1e-3, 1e-2, 3e-2):
        run = simulate(load_system("three_body", third_mass=m3), t_end, 0.01, tolerance=1e-11,
                       method="dop853")
        J = run.observables["jacobi"]
        ax[0][1].plot(run.t, (J - J[0]) / m3, lw=1, label=f"m₃ = {m3:g} kg")
        numbers[f"jacobi_span_per_mass_{m3:g}"] = float(np.ptp(J) / m3)
    label(ax[0][1], "unrestricted: J drifts, in proportion to m₃", "t [s]",
          "(J − J₀)/m₃ [J/kg²]")
    text = (f"{ACTION}: G = 1, m₁ = 0.9 kg, m₂ = 0.1 kg, L = 1 m, third body from (0.5, 0) m "
            "at (0, 0.9) m/s. Left: the restricted problem drives the test particle: its "
            "energy and angular momentum change, J = E − ωL_z does not. Right: with a mass, the "
            "third body pulls the primaries off their circle and J drifts; the drift divided by "
            "m₃ is the same curve for every small m₃ (first order), while E, P and L are kept.")
    return Drawn(fig, text, numbers)


def twisted_cubic(quick: bool) -> Drawn:
    """The VBN and RIC frames' angular velocities along r = (t, t², t³), t ∈ [−2, 2]."""
    run = simulate(load_system("moving_frames"), 4.0, 0.002, tolerance=1e-12, method="dop853")
    u = run.q[:, 0]
    obs = run.observables
    fig, grid = new_figure(2, 2, height=3.6)
    spot = grid[0][0].get_subplotspec()
    grid[0][0].remove()
    ax3 = fig.add_subplot(spot, projection="3d")
    ax3.plot(u, u**2, u**3, lw=1.5)
    ax3.set_title("r = (t, t², t³) m, t ∈ [−2, 2] s", fontsize=10)
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax3.set_zlabel("z [m]")
    axes = [grid[0][1], grid[1][0], grid[1][1]]
    for frame, a in (("vbn", axes[0]), ("ric", axes[1])):
        for c in "xyz":
            a.plot(u, obs[f"{frame}_omega_{c}"], lw=1, label=f"ω_{c}")
        label(a, f"{frame.upper()} angular velocity (own axes)", "t [s]", "ω [rad/s]")
    axes[2].plot(u, obs["vbn_angular_speed"], lw=1, label="|ω| VBN")
    axes[2].plot(u, obs["ric_angular_speed"], lw=1, label="|ω| RIC")
    label(axes[2], "magnitudes", "t [s]", "|ω| [rad/s]")
    k = int(np.argmin(np.abs(u - 1.0)))
    text = (f"{CUBIC}: the curve traversed at unit parameter rate, t ∈ [−2, 2] s (the post's "
            "range). VBN (x along v, y along r × v, right-handed) turns about all three of its "
            "axes; RIC is minimal (ω_y ≡ 0). VBN turns more slowly away from the origin and "
            "faster near it (crossover at |t| ≈ 0.689). Components in each frame's own axes with "
            "ė = ω × e (the post's mapping α → −ω_z, β → ω_y, γ → −ω_x describes −ω).")
    return Drawn(fig, text, {"t_s": float(u[k]), "vbn_speed_at_1": float(
        obs["vbn_angular_speed"][k]), "ric_speed_at_1": float(obs["ric_angular_speed"][k])})


def orbit_frames(quick: bool) -> Drawn:
    """|ω| of VBN and RIC along an eccentric Kepler orbit, and the VBN components with an
    oblate body's J₂ (the force leaves the orbit plane: VBN is no longer minimal)."""
    e, incl = 0.6, math.radians(30.0)
    speed = math.sqrt(1 + e)  # at periapsis r = 1 m, μ = 1 m³/s²
    period = 2 * math.pi * (1 / (1 - e)) ** 1.5
    start = {"initial_rate.y": speed * math.cos(incl), "initial_rate.z": speed * math.sin(incl)}
    kepler = simulate(load_system("orbit_frames", **start), period, period / 2000,
                      tolerance=1e-12, method="dop853")
    oblate = simulate(load_system("orbit_frames", perturbation="oblateness", **start),
                      3 * period, period / 1000, tolerance=1e-12, method="dop853")
    fig, grid = new_figure(1, 2, height=3.8)
    a, b = grid[0][0], grid[0][1]
    obs = kepler.observables
    a.plot(kepler.t / period, obs["vbn_angular_speed"], lw=1.5, label="|ω| VBN")
    a.plot(kepler.t / period, obs["ric_angular_speed"], lw=1.5, label="|ω| RIC")
    a.set_yscale("log")
    label(a, f"Kepler, e = {e:g}: both turn about the orbit normal only", "t / period",
          "|ω| [rad/s]")
    for c in "xz":
        b.plot(oblate.t / period, oblate.observables[f"vbn_omega_{c}"], lw=1,
               label=f"VBN ω_{c}")
    b.plot(oblate.t / period, oblate.observables["ric_omega_y"], lw=1, ls="--",
           label="RIC ω_y")
    label(b, "with J₂ = 0.05, R = 0.8 m: the components zero under −k/r", "t / period",
          "ω [rad/s]")
    ratio = obs["vbn_angular_speed"] / obs["ric_angular_speed"]
    apo = int(np.argmax(np.linalg.norm(kepler.q, axis=1)))
    text = ("“Minimal Frames”: the VBN (x along v, y along r × v, right-handed) and RIC frames "
            f"of the astrodynamics section on an orbit of eccentricity {e:g} inclined 30° "
            "(k = m = 1, periapsis 1 m). Left: under the central force both frames turn about "
            "the fixed orbit normal only (minimal); RIC at θ̇ = |L|/r², VBN at the velocity's "
            "turning rate μ/(r²v) at the apsides, |ω_VBN|/|ω_RIC| = 1/(1 ± e). Right: an oblate "
            "body's J₂ pulls out of the orbit plane, which precesses; VBN's ω_x and ω_z (zero "
            "under −k/r) are not, near periapsis, while RIC's ω_y stays zero (ω_y of VBN, "
            "the turning in the plane, is left out). Components in each frame's own axes, "
            "ė = ω × e.")
    return Drawn(fig, text, {"eccentricity": e, "ratio_periapsis": float(ratio[0]),
                             "ratio_apoapsis": float(ratio[apo])})
