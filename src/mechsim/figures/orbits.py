"""Figures of central-force motion: effective potentials with their energy levels, the Kepler
orbit family, orbits in power-law forces with their apsidal angles (Bertrand's closed cases
among them), and the small radial oscillations about a circular orbit."""

from __future__ import annotations

import math

import numpy as np

from mechsim.figures.render import Drawn, label, load_as, new_figure
from mechsim.simulate import simulate
from mechsim.systems import load_system
from mechsim.systems.central_force import CentralForce
from mechsim.systems.curves import effective_potential, kepler_effective_potential
from mechsim.systems.power_law_orbit import PowerLawOrbit

NOTES = "Introduction to analytical mechanics, “Classification of the orbits”"
PHYS = "PHYS0500 – Advanced Classical Mechanics"


def effective_potentials(quick: bool) -> Drawn:
    """U_eff for −k/r with the four levels of the notes (and PHYS0500 Fig. 4.2), for −a/r³
    with its barrier, and for the spring ½k(r − l₀)² with an orbit's turning points."""
    mu, k, l = 1.0, 1.0, 1.0
    kep = kepler_effective_potential(mu, k, l)
    fig, ax = new_figure(1, 3)
    ax[0][0].plot(kep.x, kep.y, lw=1.5, color="k", label="U_eff = −k/r + l²/2μr²")
    for level, color in zip(kep.levels, ("tab:red", "tab:orange", "tab:green", "tab:blue"),
                            strict=True):
        ax[0][0].axhline(level.value, lw=1, ls="--", color=color, label=level.label)
        ax[0][0].plot(level.crossings, [level.value] * len(level.crossings), "o",
                      color=color, ms=4)
    ax[0][0].set_ylim(1.5 * kep.marks["minimum"], -1.5 * kep.marks["minimum"])
    label(ax[0][0], "−k/r: unbound, parabolic, bound, circular", "r [m]", "energy [J]")
    panels = ((ax[0][1], {"potential": "inverse_cube", "initial_rate.r": -0.8},
               "−a/r³: over the barrier, falls", np.geomspace(0.2, 3.0, 300), (-0.3, 0.4)),
              (ax[0][2], {"potential": "spring", "spring_constant": 3.0, "rest_length": 0.8},
               "½k(r − l₀)²: vibrating rotor", np.linspace(0.5, 1.6, 300), (0.0, 1.2)))
    for a, params, title, r, ylim in panels:
        curve = effective_potential(load_system("central_force", formulation="polar", **params),
                                    r)
        a.plot(curve.x, curve.y, lw=1.5, color="k", label="U_eff")
        (level,) = curve.levels
        a.axhline(level.value, lw=1, ls="--", color="tab:red", label="E of the orbit")
        a.plot(level.crossings, [level.value] * len(level.crossings), "o", color="tab:red",
               ms=4, label="turning points")
        a.set_ylim(*ylim)
        label(a, title, "r [m]", "energy [J]")
    text = (f"{NOTES}; {PHYS}, §4.5 (Fig. 4.2). Left: U = −k/r, μ = k = l = 1 (SI) with the "
            "notes' levels E₁ > 0 (one turning point), E₂ = 0, E₃ < 0 (two: the apsides), E₄ = "
            "V_min = −μk²/2l² at r = l²/μk (circle). Middle, right: the central_force system's "
            "−a/r³ orbit (a = 0.1: its energy clears the barrier at r* = 3aμ/l², so it falls) and "
            "spring orbit (k = 3, l₀ = 0.8, turning points where E = U_eff(r)).")
    y_min = float(np.min(kep.y))
    return Drawn(fig, text, {"circular_radius_m": kep.marks["circular_radius"],
                             "minimum_J": kep.marks["minimum"], "sampled_minimum_J": y_min})


def kepler_orbits(quick: bool) -> Drawn:
    """One angular momentum, four energies: circle, ellipse, parabola, hyperbola."""
    fig, ax = new_figure(1, 2)
    k, r0 = 1.0, 1.0
    numbers = {}
    for name, speed in (("circle", 1.0), ("ellipse", 1.2), ("parabola", math.sqrt(2.0)),
                        ("hyperbola", 1.6)):
        m = load_as(CentralForce, "central_force", formulation="polar", mass_1=1e6, mass_2=1.0,
                        force_constant=k, **{"initial.r": r0, "initial_rate.r": 0.0,
                                             "initial_rate.theta": speed / r0,
                                             "initial_rate.cm_x": 0.0})
        run = simulate(m, 12.0, 0.01, tolerance=1e-10)
        r, th = run.coordinate("r"), run.coordinate("theta")
        ax[0][0].plot(r * np.cos(th), r * np.sin(th), lw=1,
                      label=f"{name}: ε = {m.kepler_elements()['eccentricity']:.3f}")
        numbers[f"{name}_eccentricity"] = float(np.median(run.observables["eccentricity"]))
    ax[0][0].plot(0, 0, "k*", ms=8)
    ax[0][0].set_xlim(-4, 2)
    ax[0][0].set_ylim(-3, 3)
    ax[0][0].set_aspect("equal")
    label(ax[0][0], "orbits from pericentre r = 1 m", "x [m]", "y [m]")
    th = np.linspace(0, 2 * math.pi, 400)
    for e in (0.0, 0.3, 0.6, 0.9):
        rr = 1.0 / (1 + e * np.cos(th))
        ax[0][1].plot(rr * np.cos(th), rr * np.sin(th), lw=1, label=f"α/r = 1 + {e} cos θ")
    ax[0][1].set_aspect("equal")
    label(ax[0][1], "conic sections α/r = 1 + ε cos θ, α = 1 m", "x [m]", "y [m]")
    text = (f"{PHYS}, §4.6 (the conic table) and the analytical-mechanics notes' Cases I–IV: "
            "U = −k/r, k = 1 N m², a test body (μ → 1 kg) starting at pericentre r = 1 m with "
            "speeds 1, 1.2, √2, 1.6 m/s, integrated (left; the legend's ε = √(1 + 2El²/μk²)), "
            "and the closed conics (right).")
    return Drawn(fig, text, numbers)


def power_law_orbits(quick: bool) -> Drawn:
    """Orbits in F = −K rⁿ from the same start, and the apsidal angle against n."""
    fig, ax = new_figure(1, 3, width=15.0)
    numbers = {}
    for n in (-2.5, -1.0, 2.0, -2.0, 1.0):
        m = load_as(PowerLawOrbit, "power_law_orbit", exponent=n, **{"initial_rate.theta": 0.6})
        run = simulate(m, 6 * m.radial_period(), 0.01, tolerance=1e-10)
        r, th = run.coordinate("r"), run.coordinate("theta")
        aps = m.apsidal_angle()
        numbers[f"apsidal_angle_n{n:g}"] = aps
        a = ax[0][1] if n in (-2.0, 1.0) else ax[0][0]
        a.plot(r * np.cos(th), r * np.sin(th), lw=0.8,
               label=f"n = {n:g}: apsidal {math.degrees(aps):.1f}°")
    for a, title in ((ax[0][0], "open: rosettes (six radial periods)"),
                     (ax[0][1], "Bertrand's closed orbits")):
        a.plot(0, 0, "k*", ms=8)
        a.set_aspect("equal")
        label(a, f"{title}, from r = 1 m, θ̇ = 0.6 rad/s", "x [m]", "y [m]")
        a.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=2)
    ax = [[ax[0][0], ax[0][2]]]
    ns = np.linspace(-2.9, 3.0, 30 if quick else 60)
    ax[0][1].plot(ns, [math.degrees(math.pi / math.sqrt(n + 3)) for n in ns], lw=1.5,
                  color="k", label="near-circular π/√(n + 3)")
    for rdot in (0.2, 0.5):
        angles = []
        for n in ns:
            m = load_as(PowerLawOrbit, "power_law_orbit", exponent=float(n),
                            **{"initial_rate.theta": 1.0, "initial_rate.r": rdot})
            try:
                angles.append(math.degrees(m.apsidal_angle()))
            except ValueError:  # unbound at this n
                angles.append(math.nan)
        ax[0][1].plot(ns, angles, lw=1, label=f"quadrature, ṙ₀ = {rdot} m/s")
    for n in (-2, 1):
        ax[0][1].axvline(n, color="gray", lw=0.8, ls=":")
    label(ax[0][1], "apsidal angle (closed for n = −2, 1)", "n", "apsidal angle [°]")
    text = (f"{PHYS}, §4.4 (orbits in a central field: Δθ = 2π a/b closes; U ∝ r^(n+1) closes "
            "only for n = −2 and 1) and the analytical-mechanics notes' “Closed orbits of the two "
            "body problem”. power_law_orbit, F = −K rⁿ, μ = K = 1 (SI), from r = 1 m. Left: "
            "bound orbits that do not close (rosettes) and Bertrand's two closed ones. Right: "
            "the apsidal angle by quadrature from E and l, against π/√(n + 3) (circular limit).")
    return Drawn(fig, text, numbers)


def radial_oscillations(quick: bool) -> Drawn:
    """Small radial oscillations about a circular orbit (§4.5.1): r(t) − r₀ against the
    frequency √(U_eff″(r₀)/μ) = √(n + 3) θ̇₀."""
    fig, ax = new_figure(1, 1, width=8.0)
    numbers = {}
    for n in (-2.5, -1.0, 1.0, 2.0):
        base = load_as(PowerLawOrbit, "power_law_orbit", exponent=n,
                       **{"initial_rate.theta": 1.0})
        r0 = base.circular_radius()
        m = load_as(PowerLawOrbit, "power_law_orbit", exponent=n, **{
            "initial.r": r0, "initial_rate.theta": 1.0 / r0**2, "initial_rate.r": 1e-3})
        w = m.radial_frequency()
        run = simulate(m, 10.0, 0.01, tolerance=1e-11)
        line = ax[0][0].plot(run.t, (run.coordinate("r") - r0) * 1e3, lw=1.5, alpha=0.6,
                             label=f"n = {n:g}: ω_r = √(n+3) θ̇₀ = {w:.3f} rad/s")[0]
        ax[0][0].plot(run.t, 1e-3 / w * np.sin(w * run.t) * 1e3, ":", lw=1,
                      color=line.get_color())
        numbers[f"omega_r_n{n:g}"] = w
    label(ax[0][0], "r − r₀ after a radial kick of 1 mm/s (dotted: (ṙ₀/ω_r) sin ω_r t)", "t [s]",
          "r − r₀ [mm]")
    text = (f"{PHYS}, §4.5.1: near the circular orbit r₀ of its angular momentum (l = 1 "
            "kg m²/s, μ = K = 1) the radius oscillates at ω_r = √(U_eff″(r₀)/μ); for F = −K rⁿ "
            "that is √(n + 3) times the orbital rate, equal to it (a closed orbit) only for "
            "n = −2.")
    return Drawn(fig, text, numbers)
