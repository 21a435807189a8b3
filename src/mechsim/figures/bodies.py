"""Figures of bodies and frames: the heavy top's nutation (waves, loops, cusps) with its
effective potential V(θ), and the fictitious forces seen from a frame whose rotation rate
varies and whose origin accelerates."""

from __future__ import annotations

import numpy as np

from mechsim.figures.render import Drawn, label, new_figure
from mechsim.simulate import simulate
from mechsim.systems import load_system
from mechsim.systems.curves import top_potential
from mechsim.systems.symmetric_top import SymmetricTop

PHYS = "PHYS0500 – Advanced Classical Mechanics"


def top_nutation(quick: bool) -> Drawn:
    """The symmetry axis of the heavy top seen from above for three starts (φ̇₀ between
    −½ and +½ of the slow precession rate): loops, cusps, waves; V(θ) with E′."""
    base = load_system("symmetric_top")
    assert isinstance(base, SymmetricTop)  # the registry's class: its analyses below
    slow = min(base.steady_precession_rates(), key=abs)
    fig, ax = new_figure(1, 4, height=4.0, width=15.0)
    numbers = {"slow_precession_rad_s": slow}
    cases = (("loops", -0.5 * slow), ("cusps", 0.0), ("waves", 0.5 * slow))
    for a, (name, rate) in zip(ax[0][:3], cases, strict=True):
        m = base.with_values(**{"initial_rate.phi": rate})
        run = simulate(m, 2.0, 0.001, tolerance=1e-11)
        obs = run.observables
        a.plot(obs["axis_x"], obs["axis_y"], lw=0.8)
        a.plot(obs["axis_x"][:1], obs["axis_y"][:1], "ko", ms=3, label="start")
        a.set_aspect("equal")
        label(a, f"{name}: φ̇₀ = {rate:.2f} rad/s", "axis x [1]", "axis y [1]")
        lo, hi = m.nutation_bounds()
        numbers[f"{name}_theta_min"], numbers[f"{name}_theta_max"] = (
            float(obs["theta"].min()), float(obs["theta"].max()))
        numbers[f"{name}_bound_min"], numbers[f"{name}_bound_max"] = lo, hi
    curve = top_potential(base.with_values(**{"initial_rate.phi": 0.0}),
                          np.linspace(0.3, 1.2, 300))
    ax[0][3].plot(curve.x, curve.y, lw=1.5, color="k", label="V(θ)")
    (level,) = curve.levels
    ax[0][3].axhline(level.value, color="tab:red", ls="--", lw=1, label="E′ (cusps)")
    ax[0][3].plot(level.crossings, [level.value] * 2, "o", color="tab:red", ms=4,
                  label="θ₁, θ₂")
    ax[0][3].set_ylim(level.value - 0.3, level.value + 0.6)
    label(ax[0][3], "effective potential (eq. 7.8)", "θ [rad]", "V [J]")
    text = (f"{PHYS}, §7.8.1–7.8.2 (Symmetric Top with One Point Fixed; Qualitative "
            "Analysis): M = 1 kg, g = 9.81 m/s², h = 0.1 m, I₁ = 0.02, I₃ = 0.01 kg m², "
            "θ₀ = 0.6 rad, θ̇₀ = 0, ψ̇₀ = 40 rad/s; the tip of the symmetry axis seen from above "
            "for 2 s. φ̇ changing sign gives loops, φ̇ = 0 at the upper turning point cusps, "
            "φ̇ of one sign waves; θ stays between the roots θ₁, θ₂ of E′ = V(θ).")
    return Drawn(fig, text, numbers)


def fictitious_forces(quick: bool) -> Drawn:
    """The four terms of m a_r for a free particle seen from a frame with a swinging rotation
    rate and an oscillating origin."""
    run = simulate(load_system("noninertial_frame"), 20.0, 0.01, tolerance=1e-11)
    obs = run.observables
    fig, ax = new_figure(1, 2)
    ax[0][0].plot(run.q[:, 0], run.q[:, 1], lw=1)
    ax[0][0].plot(run.q[:1, 0], run.q[:1, 1], "ko", ms=3, label="start")
    ax[0][0].set_aspect("equal")
    label(ax[0][0], "path seen from the moving frame", "x [m]", "y [m]")
    for name in ("translational_force", "euler_force", "centrifugal_force", "coriolis_force"):
        mag = np.hypot(obs[f"{name}_x"], obs[f"{name}_y"])
        ax[0][1].plot(run.t, mag, lw=1, label=name.replace("_", " "))
    label(ax[0][1], "magnitudes of the four terms", "t [s]", "|F| [N]")
    text = (f"{PHYS}, §6.1: m a_r = F − m R̈ − m ω̇ × r − m ω × (ω × r) − 2m ω × v_r with F = 0 "
            "(noninertial_frame defaults: m = 1 kg, ω(t) = 0.5 + 0.4 sin 0.8t rad/s, origin "
            "R = 0.5 sin 0.8t m along x, start (1, 0) m at (0, 0.2) m/s relative to the frame). "
            "The particle moves uniformly in the world; every curve on the left is made by the "
            "frame's motion. The Euler term −m ω̇ × r is of the order of the centrifugal one.")
    return Drawn(fig, text, {"max_euler_force_N": float(np.max(np.hypot(
        obs["euler_force_x"], obs["euler_force_y"])))})
