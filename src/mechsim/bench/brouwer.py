"""Brouwer's law for the machine-precision method: the energy error of ``radau15`` grows like
√N over N steps, not like N.

Round-off makes every step's energy error a random number of at most an ulp or so, with mean
zero when the method has no bias of its own (Brouwer 1937, AJ 46, 149; IAS15's long-term
energy test in Rein & Spiegel 2015, MNRAS 446, 1424, with perturbed initial conditions): the
errors add up as a random walk, whose RMS over independent runs grows like √N. A method with
a bias (truncation error of one sign, or a rounding that always leans one way) drifts like N.

The experiment (``mechsim bench --brouwer``): Kepler's problem (``kepler``, GM = μ = a = 1,
e = 0.5) with ``runs`` initial states perturbed by a relative 1e-8 (seeded), each integrated
with ``radau15`` at its finest setting (tolerance 1e-14) for ``n_steps`` steps. At
log-spaced times the stepper's state is read and its energy computed in closed form,
E = μ|v|²/2 − μGM/|r|, in 40-digit arithmetic from the double-precision state (so the
measured error is the integrator's, not the energy formula's round-off, and not the model's
own energy kernel); the relative error (E − E₀)/|E₀| is against the same formula at the
run's initial state. The RMS over runs is fitted log-log against the number of steps N: the
slope is ½ for a random walk and 1 for a drift.
"""

from __future__ import annotations

import io
import json
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import mpmath as mp
import numpy as np

from mechsim.files import write_atomic
from mechsim.systems import load_system

#: Kepler's problem of the experiment (a = GM = μ = 1).
ECCENTRICITY = 0.5
#: Relative size of the perturbation of each run's initial state.
PERTURBATION = 1e-8
#: Fits start here: below ~10³ steps the error is a few ulps of E and the random walk has not
#: yet risen above the rounding of E₀ itself (a floor that would flatten the slope).
FIT_FROM_STEPS = 1000


@dataclass
class Walks:
    """Relative energy errors of ``runs`` perturbed Kepler runs at common sample times."""

    method: str
    tolerance: float
    times: list[float]  # sample times [s]
    steps: list[list[int]]  # steps[run][sample]: steps taken up to that sample
    errors: list[list[float]]  # errors[run][sample]: (E − E₀)/|E₀|
    cpu_s: float  # CPU time of the integration (energy evaluation excluded)

    def mean_steps(self) -> np.ndarray:
        return np.mean(np.asarray(self.steps, dtype=float), axis=0)

    def rms(self) -> np.ndarray:
        return np.sqrt(np.mean(np.asarray(self.errors) ** 2, axis=0))


def kepler_energy(y: np.ndarray, gm: float = 1.0, mu: float = 1.0) -> mp.mpf:
    """E = μ(ẋ² + ẏ²)/2 − μGM/√(x² + y²) of the state [x, y, ẋ, ẏ, …], in 40 digits (the
    double-precision inputs taken as exact)."""
    with mp.workdps(40):
        x, yy, vx, vy = (mp.mpf(float(c)) for c in y[:4])
        return mu * (vx * vx + vy * vy) / 2 - mu * gm / mp.sqrt(x * x + yy * yy)


def perturbed_states(runs: int, seed: int = 11) -> list[np.ndarray]:
    """``runs`` initial states of the experiment's orbit, each coordinate and velocity scaled
    by 1 + PERTURBATION·ξ (ξ standard normal, seeded)."""
    model = load_system("kepler", eccentricity=ECCENTRICITY)
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(runs):
        y = model.initial_y().copy()
        y[:4] *= 1.0 + PERTURBATION * rng.standard_normal(4)
        out.append(y)
    return out


def _advance_rounding_up(st: Any, t: float) -> np.ndarray:
    """Advance a ``radau15`` stepper to ``t`` one planned step at a time, and after each step
    round the velocity one ulp away from zero: a rounding that always leans one way (the
    bias Brouwer's law excludes), for showing that the slope check detects it."""
    y = st.y.copy()
    while st.t < t:
        y = st.advance(np.array([min(st.t + float(st.state["h"][0]), t)]))[0]
        st.y[2:4] = np.nextafter(st.y[2:4], np.copysign(np.inf, st.y[2:4]))
    return y


def energy_walks(n_steps: int, runs: int, method: str = "radau15", tolerance: float = 1e-14,
                 samples: int = 40, seed: int = 11, rounding_up: bool = False) -> Walks:
    """Integrate the ``runs`` perturbed orbits with ``method`` for about ``n_steps`` steps
    each (the horizon is sized from a probe of one orbit), sampling ``samples`` log-spaced
    times from one orbit on; see the module docstring. ``rounding_up`` (``radau15`` only):
    bias the state after every step (``_advance_rounding_up``)."""
    from mechsim.integrators import make_stepper

    model = load_system("kepler", eccentricity=ECCENTRICITY)
    period = 2 * math.pi  # a = GM = 1
    probe = make_stepper(model, method, tolerance)
    probe.advance(np.array([period]))
    per_orbit = max(probe.n_steps, 1)
    orbits = max(n_steps / per_orbit, 2.0)
    # whole orbits, log-spaced, plus half an orbit: every sample at apocentre, the same phase
    times = period * (np.unique(np.round(np.geomspace(1.0, orbits, samples))) + 0.5)
    steps: list[list[int]] = []
    errors: list[list[float]] = []
    cpu = 0.0
    for y0 in perturbed_states(runs, seed):
        e0 = kepler_energy(y0)
        st = make_stepper(model, method, tolerance, y0=y0)
        ys, ns = [], []
        for t in times:
            c0 = time.process_time()
            ys.append(_advance_rounding_up(st, t) if rounding_up
                      else st.advance(np.array([t]))[0])
            cpu += time.process_time() - c0
            ns.append(st.n_steps)
        steps.append(ns)
        errors.append([float((kepler_energy(y) - e0) / abs(e0)) for y in ys])
    return Walks(method, tolerance, times.tolist(), steps, errors, cpu)


def fit_slope(n: np.ndarray, rms: np.ndarray, from_steps: int = FIT_FROM_STEPS) -> float:
    """Least-squares slope of log(rms) against log(n) over the samples with n ≥
    ``from_steps`` (and a nonzero rms)."""
    keep = (n >= from_steps) & (rms > 0)
    if np.count_nonzero(keep) < 3:
        raise ValueError(f"fewer than 3 samples with at least {from_steps} steps")
    return float(np.polyfit(np.log(n[keep]), np.log(rms[keep]), 1)[0])


def figure(w: Walks, note: str = "") -> Any:
    """RMS relative energy error over the runs against the number of steps (log-log), each
    run's |error| faint, the fit and reference lines ∝ √N and ∝ N through the fitted RMS at
    the first fitted sample."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n, rms = w.mean_steps(), w.rms()
    slope = fit_slope(n, rms)
    fig, ax = plt.subplots(figsize=(8, 5.5), dpi=90)
    for i, (ns, es) in enumerate(zip(w.steps, w.errors, strict=True)):
        ax.loglog(ns, np.maximum(np.abs(es), 1e-18), color="0.75", lw=0.7,
                  label=f"|error| of each of the {len(w.steps)} runs" if i == 0 else None)
    ax.loglog(n, rms, "o-", color="C0", lw=2, ms=4,
              label=f"RMS over the runs ({w.method}, tolerance {w.tolerance:g})")
    keep = n >= FIT_FROM_STEPS
    coef = np.polyfit(np.log(n[keep]), np.log(rms[keep]), 1)
    nf = n[keep]
    ax.loglog(nf, np.exp(np.polyval(coef, np.log(nf))), "--", color="C3", lw=1.5,
              label=f"least-squares fit for N ≥ {FIT_FROM_STEPS}: slope {slope:.3f}")
    anchor_n, anchor = nf[0], float(np.exp(np.polyval(coef, math.log(nf[0]))))
    ax.loglog(nf, anchor * np.sqrt(nf / anchor_n), ":", color="k", lw=1.5,
              label="∝ √N (Brouwer's law: round-off random walk)")
    ax.loglog(nf, anchor * (nf / anchor_n), "-.", color="C1", lw=1.2,
              label="∝ N (linear drift: a biased method)")
    ax.set_xlabel("steps N (dimensionless)")
    ax.set_ylabel("relative energy error |E − E₀| / |E₀| (dimensionless)")
    ax.set_title(f"Brouwer's law: Kepler e = {ECCENTRICITY}, {len(w.steps)} runs, "
                 f"up to {int(n[-1]):,} steps" + (f"\n{note}" if note else ""), fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    return fig


def run_brouwer(out: Path, n_steps: int = 10_000_000, runs: int = 16) -> dict[str, Any]:
    """The experiment; writes ``brouwer.json`` (every sample of every run) and
    ``brouwer.png`` to ``out`` and prints the fitted slope."""
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    w = energy_walks(n_steps, runs)
    n, rms = w.mean_steps(), w.rms()
    slope = fit_slope(n, rms)
    per_step = w.cpu_s / float(np.sum(np.asarray(w.steps)[:, -1]))
    # A bias shows as a mean error of one sign: the signed mean over the runs against the RMS
    # at the end (a random walk: ±1/√runs), and the slope over the last decade alone.
    bias = float(np.mean(np.asarray(w.errors)[:, -1]) / rms[-1])
    last = fit_slope(n, rms, from_steps=int(n[-1] / 10))
    res = {"schema": "mechsim-brouwer/1", "system": "kepler", "eccentricity": ECCENTRICITY,
           "perturbation": PERTURBATION, "fit_from_steps": FIT_FROM_STEPS, "slope": slope,
           "slope_last_decade": last, "mean_over_rms_at_end": bias,
           "mean_steps": n.tolist(), "rms": rms.tolist(), "cpu_per_step_s": per_step,
           **asdict(w)}
    write_atomic(out / "brouwer.json", json.dumps(res, indent=1))
    note = (f"CPU {w.cpu_s:.0f} s, {per_step * 1e6:.2f} µs a step "
            "(shared 2-core machine: times noisy)")
    fig = figure(w, note)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    write_atomic(out / "brouwer.png", buf.getvalue())
    plt.close(fig)
    print(f"Brouwer: {runs} runs × {int(n[-1]):,} steps of {w.method}: RMS relative energy "
          f"error {rms[np.argmax(n >= FIT_FROM_STEPS)]:.2e} at N = "
          f"{int(n[np.argmax(n >= FIT_FROM_STEPS)]):,}, {rms[-1]:.2e} at N = {int(n[-1]):,}; "
          f"fitted slope {slope:.3f} (√N: 0.5, drift: 1), {last:.3f} over the last decade; "
          f"mean/RMS at the end {bias:+.2f} (random walk: ±{1 / math.sqrt(runs):.2f}); "
          f"CPU {w.cpu_s:.1f} s; "
          f"wrote {out / 'brouwer.png'}")
    return res
