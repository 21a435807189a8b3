"""Figures of oscillations: the damped regimes, the resonance and kinetic-energy resonance
curves from a sweep, the beats of two coupled oscillators, the frequencies of oscillator chains
(the n/2 claim), the double pendulum's normal modes, and phase portraits."""

from __future__ import annotations

import math

import numpy as np

from mechsim.experiments.phase_portrait import phase_portrait
from mechsim.experiments.resonance import sweep
from mechsim.figures.render import Drawn, label, load_as, new_figure
from mechsim.simulate import simulate
from mechsim.systems import load_system
from mechsim.systems.coupled_oscillators import CoupledOscillators
from mechsim.systems.curves import pendulum_separatrix, resonance_curves
from mechsim.systems.oscillator_chain import OscillatorChain

PHYS = "PHYS0500 – Advanced Classical Mechanics"


def damped_regimes(quick: bool) -> Drawn:
    """Under-, critically and over-damped motion from the same start, with the envelope."""
    fig, ax = new_figure(1, 1, width=8.0)
    numbers = {}
    m, k = 1.0, 4.0
    for name, b in (("underdamped, b = 0.8", 0.8), ("critical, b = 4", 4.0),
                    ("overdamped, b = 10", 10.0)):
        run = simulate(load_system("damped_oscillator", mass=m, spring_constant=k, damping=b),
                       8.0, 0.01, tolerance=1e-10)
        ax[0][0].plot(run.t, run.q[:, 0], lw=1.2, label=name)
        numbers[f"x_at_8s_b{b:g}"] = float(run.q[-1, 0])
    beta = 0.8 / (2 * m)
    t = np.linspace(0, 8, 400)
    ax[0][0].plot(t, np.exp(-beta * t), "k:", lw=1, label="envelope e^{−βt}, β = b/2m")
    ax[0][0].plot(t, -np.exp(-beta * t), "k:", lw=1)
    label(ax[0][0], "x(0) = 1 m at rest, m = 1 kg, k = 4 N/m", "t [s]", "x [m]")
    text = (f"{PHYS}, §1.3 (Damped Oscillations, §1.3.1–1.3.3): m ẍ + b ẋ + k x = 0 with "
            "ω₀ = 2 rad/s; β = b/2m below, at and above ω₀. The underdamped motion decays "
            "inside e^{−βt}; the critical one returns fastest without overshoot.")
    return Drawn(fig, text, numbers)


def resonance(quick: bool) -> Drawn:
    """D(ω) and ⟨T⟩(ω) closed forms with swept measurements, for three dampings."""
    fig, ax = new_figure(1, 2)
    omegas = np.linspace(0.5, 3.5, 7 if quick else 15)
    numbers = {}
    for b in (0.4, 1.0, 2.0):
        model = load_system("driven_oscillator", damping=b)
        D, T = resonance_curves(model)
        measured = sweep(model, omegas, periods=2 if quick else 4)
        line = ax[0][0].plot(D.x, D.y, lw=1.2, label=f"b = {b} kg/s")[0]
        ax[0][0].plot(measured.omega, measured.amplitude, "o", ms=3, color=line.get_color())
        ax[0][1].plot(T.x, T.y, lw=1.2, color=line.get_color(), label=f"b = {b} kg/s")
        ax[0][1].plot(measured.omega, measured.kinetic, "o", ms=3, color=line.get_color())
        if "omega_R" in D.marks:
            ax[0][0].axvline(D.marks["omega_R"], color=line.get_color(), lw=0.8, ls=":")
        if b == 0.4:
            numbers.update({"b": b, "omega_R": D.marks["omega_R"],
                            "sweep_omega": float(measured.omega[3]),
                            "sweep_amplitude_m": float(measured.amplitude[3]),
                            "sweep_kinetic_J": float(measured.kinetic[3])})
    ax[0][1].axvline(2.0, color="gray", lw=0.8, ls=":", label="ω_E = ω₀")
    label(ax[0][0], "amplitude resonance (dotted: ω_R = √(ω₀² − 2β²))", "ω [rad/s]", "D [m]")
    label(ax[0][1], "kinetic-energy resonance", "ω [rad/s]", "⟨T⟩ [J]")
    text = (f"{PHYS}, §1.5 (Resonance Phenomena) and §1.5.1 (Kinetic Energy Resonance), typos "
            "corrected (the minus sign of D, the plus sign of ⟨T⟩): m = 1 kg, k = 4 N/m "
            "(ω₀ = 2 rad/s), F₀ = 1 N. Lines: D = A/√((ω₀² − ω²)² + 4ω²β²), A = F₀/m, and "
            "⟨T⟩ = (mA²/4)ω²/((ω₀² − ω²)² + 4ω²β²); dots: driven_oscillator integrated past its "
            "transient at each ω and measured over whole periods. The amplitude peaks at ω_R, "
            "below ω₀; the kinetic energy at ω₀ for every damping.")
    return Drawn(fig, text, numbers)


def coupled_beats(quick: bool) -> Drawn:
    """Two weakly coupled oscillators exchanging their energy (§8.2)."""
    model = load_as(CoupledOscillators, "coupled_oscillators", count=2, coupling_constant=0.4)
    t_swap = model.transfer_time()
    run = simulate(model, 2.2 * t_swap, 0.02, tolerance=1e-10)
    fig, ax = new_figure(1, 2)
    ax[0][0].plot(run.t, run.q[:, 0], lw=0.8, label="x₁")
    ax[0][0].plot(run.t, run.q[:, 1], lw=0.8, label="x₂")
    label(ax[0][0], "displacements", "t [s]", "x [m]")
    for j in (1, 2):
        ax[0][1].plot(run.t, run.observables[f"oscillator_energy_{j}"], lw=1,
                      label=f"½mẋ_{j}² + ½κx_{j}²")
    ax[0][1].axvline(t_swap, color="gray", ls="--", lw=1, label="π/(ω₁ − ω₂)")
    ax[0][1].axvline(model.transfer_time(approximate=True), color="gray", ls=":", lw=1,
                     label="π/(2εω₀) (first order)")
    label(ax[0][1], "energy transfer", "t [s]", "[J]")
    text = (f"{PHYS}, §8.2 (Weak Coupling): m = 1 kg, κ = 4 N/m, κ₁₂ = 0.4 N/m (ε = 0.05), "
            "x₁(0) = 0.2 m, all else at rest. The energy passes completely to the second "
            "oscillator at t = π/(ω₁ − ω₂), the notes' π/(2εω₀) to first order in ε.")
    return Drawn(fig, text, {"transfer_time_s": t_swap})


def chain_frequencies(quick: bool) -> Drawn:
    """ω_r/ω₀ of chains of n = 1 … 12 masses with two walls, one wall, none."""
    fig, ax = new_figure(1, 3, height=4.0)
    numbers = {}
    for a, walls in zip(ax[0], ("both", "left", "none"), strict=True):
        holds = []
        for n in range(1, 13):
            m = load_as(OscillatorChain, "oscillator_chain", count=n, walls=walls)
            w = m.mode_frequencies() / m.held_frequency()
            a.plot([n] * n, w, "o", ms=3, color="tab:blue")
            holds.append(m.document_claim_holds())
        a.axhline(1.0, color="tab:red", lw=1, label="ω₀ = √(2κ/m)")
        ok = [n for n, h in zip(range(1, 13), holds, strict=True) if h]
        label(a, f"walls: {walls}; claim holds for n = {_ranges(ok)}", "n", "ω_r / ω₀")
        numbers[f"claim_holds_{walls}"] = float(len(ok))
    text = (f"{PHYS}, §8.1: “for n identical coupled oscillators, n/2 characteristic "
            "frequencies are greater than ω₀ and n/2 lesser; for odd n, ω₀ itself is one”. "
            "Chains of n masses m and identical springs κ (oscillator_chain): with walls at both "
            "ends the claim holds for every n; tied to one wall it fails for odd n; free, for "
            "every n (ω₀ = √(2κ/m): one mass between two held neighbours).")
    return Drawn(fig, text, numbers)


def _ranges(ns: list[int]) -> str:
    if not ns:
        return "none"
    if ns == list(range(ns[0], ns[-1] + 1)):
        return f"{ns[0]}–{ns[-1]}"
    return ", ".join(str(n) for n in ns)


def double_pendulum_modes(quick: bool) -> Drawn:
    """The equal double pendulum started in each small-oscillation mode, A₂ = ∓√2 A₁."""
    fig, ax = new_figure(1, 2)
    g, l = 9.81, 1.0
    numbers = {}
    for a, sign, name in ((ax[0][0], -1, "fast, ω² = (2 + √2)g/l"),
                          (ax[0][1], +1, "slow, ω² = (2 − √2)g/l")):
        th1 = 0.01
        run = simulate(load_system("double_pendulum", **{
            "initial.angle_1": th1, "initial.angle_2": sign * math.sqrt(2) * th1}),
            8.0, 0.005, tolerance=1e-11)
        a.plot(run.t, run.q[:, 0], lw=1, label="θ₁")
        a.plot(run.t, run.q[:, 1], lw=1, label="θ₂")
        w = math.sqrt((2 - sign * math.sqrt(2)) * g / l)
        a.plot(run.t, th1 * np.cos(w * run.t), "k:", lw=1, label="θ₁(0) cos ωt")
        label(a, f"mode {name}", "t [s]", "angle [rad]")
        numbers[f"omega_{'fast' if sign < 0 else 'slow'}"] = w
    text = ("Introduction to analytical mechanics, “Double pendulum” and “Small Oscillations”: "
            "m₁ = m₂ = 1 kg, l₁ = l₂ = 1 m, g = 9.81 m/s², from rest with θ₁ = 0.01 rad and "
            "θ₂ = ∓√2 θ₁: each start is a normal mode of the notes' |V − ω²T| = 0, and the "
            "integrated nonlinear motion keeps the single frequency ω² = (2 ± √2)g/l.")
    return Drawn(fig, text, numbers)


def phase_portraits(quick: bool) -> Drawn:
    """The pendulum's phase plane (librations, separatrix, rotations) and the damped
    oscillator's spirals, each from several initial conditions."""
    fig, ax = new_figure(1, 2)
    pend = load_system("pendulum")
    w0 = math.sqrt(9.81)
    starts = [{"initial.angle": a, "initial_rate.angle": 0.0} for a in (0.5, 1.5, 2.5, 3.0)]
    starts += [{"initial.angle": -math.pi, "initial_rate.angle": r}
               for r in (0.3 * w0, 0.8 * w0)]
    starts += [{"initial.angle": 0.0, "initial_rate.angle": r} for r in (2.2 * w0, 2.8 * w0)]
    for tr in phase_portrait(pend, starts, 4.0, 0.005, tolerance=1e-10):
        q = np.mod(tr.q + math.pi, 2 * math.pi) - math.pi
        q[np.abs(np.diff(q, prepend=q[0])) > math.pi] = np.nan  # break the line at ±π
        ax[0][0].plot(q, tr.v, lw=0.8)
    sep = pendulum_separatrix(pend)
    ax[0][0].plot(sep.x, sep.y, "k--", lw=1, label="separatrix φ̇ = ±2ω₀ cos(φ/2)")
    ax[0][0].plot(sep.x, -sep.y, "k--", lw=1)
    label(ax[0][0], "pendulum: librations, separatrix, rotations", "φ [rad]", "φ̇ [rad/s]")
    damped = load_system("damped_oscillator")
    for x0, v0 in ((1.0, 0.0), (-1.0, 1.0), (0.0, -2.5), (0.5, 2.0)):
        tr = phase_portrait(damped, [{"initial.x": x0, "initial_rate.x": v0}], 15.0, 0.01,
                            tolerance=1e-10)[0]
        ax[0][1].plot(tr.q, tr.v, lw=0.8, label=f"(x₀, ẋ₀) = ({x0}, {v0})")
    label(ax[0][1], "damped oscillator: spirals into the origin", "x [m]", "ẋ [m/s]")
    text = ("“Dynamical Systems and Constraints: Part 3 – Simple Pendulum” (R = 1 m, g = 9.81 "
            f"m/s²) and {PHYS}, §1.3 (m = 1 kg, k = 4 N/m, b = 0.4 kg/s): phase trajectories "
            "from several initial conditions, each integrated (mechsim.experiments."
            "phase_portrait); the pendulum's separatrix E = 2mgR is the closed form.")
    return Drawn(fig, text, {"omega_0": w0})
