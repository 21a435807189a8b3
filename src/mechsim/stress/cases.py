"""The stress catalogue: each case runs against the systems it applies to and returns results
with a pass criterion, an explained outcome, metrics and (for plots) downsampled series.

Drifts are measured as the diagnostics node measures them, by asking each ``Law`` (value,
drift, level; scales from ``Model.law_scales()``); the sweeps feed the samples through a real
``DiagnosticsNode``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from mechsim.errors import IntegrationError, MechsimError
from mechsim.integrators import StiffnessError, choose_method
from mechsim.simulate import SimulationResult, simulate
from mechsim.stress.common import (
    ERROR_DRIFT,
    ROUND_OFF,
    WARN_DRIFT,
    Result,
    _down,
    _variant,
    attempt,
    drifts,
    worst,
)
from mechsim.stress.singular import SINGULAR, singular
from mechsim.systems import load_system, system_ids
from mechsim.systems.base import LEVEL_NAMES, Model


# --- 1. long horizons -----------------------------------------------------------------------
def long_horizon(system: str, quick: bool) -> list[Result]:
    """≥ 10⁶ steps (10⁵ quick) with ``auto`` at the default tolerance."""
    target = 100_000 if quick else 1_000_000
    model = load_system(system)
    method = choose_method(model, "auto")
    symplectic = method != "dop853"  # compositions, gauss6
    crit = ("energy error bounded: max drift over the run ≤ 10 × max over its first 10 % "
            "(or round-off: ≤ max(1e-11, steps × 1e-15))" if symplectic else
            "DOP853: worst drift grows no faster than ~t (fitted exponent ≤ 1.5 on the last "
            "90 % of the run, or round-off: ≤ max(1e-11, steps × 1e-15))") + (
        "; in every case below the diagnostics ERROR threshold "
        f"({f'{ERROR_DRIFT:.0e}'.replace('e-0', 'e-')}); "
        "drift relative to max(law scale, running magnitude of T, V and the work terms); "
        "10⁶ steps, or 10⁵ time scales for systems that take few, big steps")
    t_probe = 5.0 * model.time_scale()
    probe, err, _ = attempt(model, t_probe, t_probe / 10, outputs=("energy",))
    if probe is None:
        return [Result("long_horizon", system, method, False, f"probe failed: {err}", crit)]
    rate = max(probe.n_steps, 1) / t_probe
    max_t = 1e5 * model.time_scale()  # cheap systems (few big steps): bounded horizon
    t_end = min(1.02 * target / rate, max_t)
    n_out = 4000
    run, err, wall = attempt(model, t_end, t_end / n_out)
    for _ in range(3):  # adaptive steps grow as a dissipative system settles: go further
        if run is None or run.n_steps >= target or t_end >= max_t:
            break
        t_end = min(t_end * 1.1 * target / max(run.n_steps, 1), max_t)
        run, err, wall = attempt(model, t_end, t_end / n_out)
    if run is None:
        return [Result("long_horizon", system, method, False, f"stopped: {err}", crit,
                       {"t_end": t_end}, wall=wall)]
    d = drifts(model, run, growing=True)
    key, final = worst(d, skip_constraints=True)
    runmax = np.maximum.accumulate(d[key]) if key else np.zeros_like(run.t)
    cons = {k: float(np.max(v)) for k, v in d.items()}
    m: dict[str, Any] = {"method": method, "steps": run.n_steps, "t_end": t_end,
                         "periods": t_end / model.time_scale(), "worst_law": key,
                         "worst_drift": final, "drifts": cons}
    if not np.all(np.isfinite(runmax)):
        ok, why = False, "non-finite law values"
    elif final <= max(ROUND_OFF, 1e-15 * run.n_steps):
        ok, why = True, (f"worst drift {final:.2e} at round-off level (≤ max(1e-11, "
                         "steps × 1e-15))")
    elif symplectic:
        early = float(runmax[max(1, run.t.size // 10)])
        m["early_drift"] = early
        ok = final <= max(10.0 * early, ROUND_OFF)
        why = f"bounded: {final:.2e} overall vs {early:.2e} in the first 10 %"
    else:
        i0 = max(1, run.t.size // 10)
        tt, yy = run.t[i0:], runmax[i0:]
        good = yy > 0
        slope = float(np.polyfit(np.log(tt[good]), np.log(yy[good]), 1)[0]) \
            if good.sum() > 10 else 0.0
        m["growth_exponent"] = slope
        ok = slope <= 1.5
        why = f"worst drift {final:.2e}, growth ~ t^{slope:.2f}"
    if ok and final >= ERROR_DRIFT:
        ok, why = False, f"{why}, but past the diagnostics ERROR threshold {ERROR_DRIFT:g}"
    ts, ds = _down(run.t, runmax)
    return [Result("long_horizon", system, method, ok,
                   f"{run.n_steps:,} steps ({m['periods']:.0f} time scales): {why}"
                   f" [{key}]", crit, m,
                   {"t": ts, "drift": ds, "law": key}, wall)]


# --- 2. chaos -------------------------------------------------------------------------------
CHAOS = {
    "double_pendulum": ({}, "energy", 30.0),
    "cr3bp": ({"initial.x": 0.75, "initial_rate.y": 0.8}, "invariant:jacobi", 100.0),
}


def chaos(system: str, quick: bool) -> list[Result]:
    kw, law, horizon = CHAOS[system]
    horizon *= 0.6 if quick else 1.0
    crit = ("finite-time Lyapunov exponent > 0 from two ICs 1e-9 apart; tolerances 1e-7 and "
            "1e-13 part (‖Δ‖ > 1e-2) before the horizon; the conserved law holds "
            "(drift < 1e-7 at 1e-13, < 1e-5 at 1e-7) while they diverge")
    m1 = load_system(system, **kw)
    key = next(k for k in m1.values if k.startswith("initial."))
    m2 = m1.with_values(**{key: float(m1.values[key]) + 1e-9})  # type: ignore[arg-type]
    dt = 0.02
    start = time.perf_counter()
    a = simulate(m1, horizon, dt, tolerance=1e-13, method="dop853")
    b = simulate(m2, horizon, dt, tolerance=1e-13, method="dop853")
    c = simulate(m1, horizon, dt, tolerance=1e-7, method="dop853")
    wall = time.perf_counter() - start

    def dist(x: SimulationResult, y: SimulationResult) -> np.ndarray:
        return np.linalg.norm(np.hstack([x.q - y.q, x.v - y.v]), axis=1)

    d_ic = dist(a, b)
    d_tol = dist(a, c)
    sel = (d_ic > 1e-8) & (d_ic < 1e-3)
    if sel.sum() > 10:
        first = int(np.argmax(sel))
        last = int(np.argmax(d_ic > 1e-3)) if np.any(d_ic > 1e-3) else d_ic.size
        tt = a.t[first:last]
        lam = float(np.polyfit(tt, np.log(np.maximum(d_ic[first:last], 1e-300)), 1)[0])
    else:
        lam = 0.0
    t_div = float(a.t[np.argmax(d_tol > 1e-2)]) if np.any(d_tol > 1e-2) else math.inf
    t_div_ic = float(a.t[np.argmax(d_ic > 1e-2)]) if np.any(d_ic > 1e-2) else math.inf
    drift_tight = float(np.max(drifts(m1, a)[law]))
    drift_loose = float(np.max(drifts(m1, c)[law]))
    ok = lam > 0.0 and math.isfinite(t_div) and drift_tight < 1e-7 and drift_loose < 1e-5
    m = {"lyapunov_exponent": lam, "lyapunov_time": 1.0 / lam if lam > 0 else math.inf,
         "t_diverge_tolerances": t_div, "t_diverge_ic": t_div_ic, "horizon": horizon,
         "law": law, "drift_tol_1e-13": drift_tight, "drift_tol_1e-7": drift_loose,
         "steps": a.n_steps + b.n_steps + c.n_steps}
    ts, ys = _down(a.t, np.log10(np.maximum(d_ic, 1e-300)))
    _, yt = _down(a.t, np.log10(np.maximum(d_tol, 1e-300)))
    _, dl = _down(a.t, np.log10(np.maximum(drifts(m1, a)[law], 1e-17)))
    return [Result("chaos", system, _variant(kw), ok,
                   f"λ ≈ {lam:.3f}/s (Lyapunov time {m['lyapunov_time']:.2f} s); tolerances "
                   f"part at t = {t_div:.1f} s, ICs at {t_div_ic:.1f} s; {law} drift "
                   f"{drift_tight:.1e} (1e-13) / {drift_loose:.1e} (1e-7) throughout", crit, m,
                   {"t": ts, "log_sep_ic": ys, "log_sep_tol": yt, "log_drift": dl}, wall)]


# --- 3. stiffness ---------------------------------------------------------------------------
STIFF: dict[str, list[tuple[dict[str, Any], float]]] = {
    "damped_oscillator": [({"damping": 1e6}, 10.0), ({"spring_constant": 1e8, "damping": 1e5},
                                                      10.0), ({"damping": 1e3}, 10.0)],
    "spring_pendulum": [({"spring_constant": 1e9, "initial.extension": 9.81e-9}, 1.0),
                        ({"formulation": "cartesian", "spring_constant": 1e9}, 0.3)],
    "driven_oscillator": [({"damping": 1e7}, 10.0)],
}


def stiffness(system: str, quick: bool) -> list[Result]:
    crit = ("auto either stops with a StiffnessError naming the system and the remedies, or "
            "finishes with its laws kept (worst drift < 1e-6); never a blow-up or a silent "
            "crawl (a crawl is counted in steps per output interval, not in seconds)")
    out = []
    for kw, t_end in STIFF[system][: 1 if quick else None]:
        model = load_system(system, **kw)
        run, err, wall = attempt(model, t_end, 0.01)  # a node's default publish rate
        m: dict[str, Any] = {"method": choose_method(model, "auto"), "t_end": t_end,
                             "wall_s": wall}
        if run is None:
            stiff = err is not None and err.startswith("StiffnessError") and system in err
            ok = stiff
            m["error"] = err
            outcome = (f"stiffness detected and reported in {wall:.2f} s: {err}" if stiff
                       else f"stopped without a stiffness diagnosis: {err}")
        else:
            key, w = worst(drifts(model, run))
            m.update(steps=run.n_steps, worst_law=key, worst_drift=w)
            ok = w < 1e-6
            outcome = (f"finished: {run.n_steps:,} steps in {wall:.2f} s, worst drift "
                       f"{w:.1e} [{key}] (stiff phases cheap enough: under 1000 steps per "
                       "output interval, or an oscillatory fast mode resolved)")
        out.append(Result("stiffness", system, _variant(kw), ok, outcome, crit, m, wall=wall))
    return out


# --- 5. step-size and tolerance sweeps, with the diagnostics node's logic -----------------------
SWEEPS = {
    "pendulum": ({"initial.angle": 2.5}, 20.0),
    "kepler": ({"eccentricity": 0.7}, 6 * math.pi),
    "double_pendulum": ({"initial.angle_1": 0.5, "initial.angle_2": 0.3}, 10.0),
    "harmonic_oscillator": ({}, 30.0),
    "spring_pendulum": ({}, 10.0),
}
GARBAGE = 1e-2  # relative state error that makes the numbers garbage


class _Diag:
    """A real DiagnosticsNode (no discovery, no timer traffic) fed a run's messages."""

    def __init__(self) -> None:
        from mechsim.environment import import_rclpy

        rclpy = import_rclpy()
        self.rclpy = rclpy
        self.context = rclpy.context.Context()
        rclpy.init(context=self.context)

    def levels(self, model: Model, run: SimulationResult, method: str,
               tol: float) -> tuple[int, float]:
        from mechsim.outputs import messages
        from mechsim.ros.diagnostics import DiagnosticsNode

        node = DiagnosticsNode(context=self.context, warn_drift=WARN_DRIFT,
                               error_drift=ERROR_DRIFT, period=3600.0, discover=False)
        try:
            f = messages.MessageFactory(model, "sweep")
            laws = model.laws()
            scales = model.law_scales()
            node.feed("/sweep", "system_info",
                      f.system_info(0, method, tol, [law.key for law in laws],
                                    [scales[law.key] for law in laws]))
            inv = run.invariants
            names = [q.name for q in model.invariants]
            for k in range(run.t.size):
                s = messages.Sample(float(run.t[k]), run.q[k], run.v[k],
                                    float(run.work_external[k]), float(run.work_dissipated[k]))
                s.energy = np.array([run.kinetic[k], run.potential[k],
                                     run.energy_function[k]])
                node.feed("/sweep", "energy", f.energy(s, k))
                if names:
                    s.invariants = np.array([inv[nm][k] for nm in names])
                    node.feed("/sweep", "invariants", f.invariants(s, k))
            st = node.systems["/sweep"]
            # Over the whole run: a non-finite sample was ERROR when it came.
            lv = max((2 if law.nonfinite else node.level(law, False)
                      for law in st.laws.values()), default=0)
            md = max((law.worst for law in st.laws.values()), default=0.0)
            return lv, md
        finally:
            node.destroy_node()

    def close(self) -> None:
        self.context.try_shutdown()


def sweeps(system: str, quick: bool) -> list[Result]:
    kw, t_end = SWEEPS[system]
    crit = (f"every setting whose state error vs a 1e-13 reference exceeds {GARBAGE:g} (garbage) "
            "is WARN or ERROR on the diagnostics node (or stopped by a guard) — never OK")
    model = load_system(system, **kw)
    dt = t_end / 500
    ref = simulate(model, t_end, dt, tolerance=1e-13, method="dop853")
    scale = max(1.0, float(np.max(np.abs(ref.q))))
    points: list[tuple[str, float | None, float | None]] = []
    # The tolerance bounds the end error (DOP853 keeps its local error a thousandth of it), so
    # garbage needs a tolerance near 1.
    tols = [0.5, 1e-2, 1e-4, 1e-6, 1e-8, 1e-10] if quick else [0.5] + [10.0 ** -k
                                                                       for k in range(1, 13)]
    points += [("dop853", t, None) for t in tols]
    if model.structure.separable:
        tau = model.time_scale()
        facs = [1.0, 0.3, 0.1, 0.03, 0.01] if quick else [2.0, 1.0, 0.5, 0.3, 0.2, 0.1, 0.05,
                                                         0.03, 0.02, 0.01, 0.003, 0.001]
        for meth in ("verlet", "yoshida8"):
            points += [(meth, 1e-10, f * tau) for f in facs]
    diag = _Diag()
    rows = []
    start = time.perf_counter()
    try:
        for meth, tol, step in points:
            run, err, wall = attempt(model, t_end, dt, method=meth, tolerance=tol or 1e-10,
                                     step=step)
            row: dict[str, Any] = {"method": meth, "tolerance": tol, "step": step}
            if run is None:
                row.update(error=err, level="ERROR (guard)", garbage=True, flagged=True)
            else:
                bad = ~np.all(np.isfinite(np.hstack([run.q, run.v])), axis=1)
                e = float(np.max(np.linalg.norm(run.q - ref.q, axis=1))) / scale \
                    if not bad.any() else math.inf
                lv, md = diag.levels(model, run, meth, tol or 1e-10)
                row.update(state_error=e, max_drift=md, level=LEVEL_NAMES[lv], steps=run.n_steps,
                           garbage=e > GARBAGE, flagged=lv in (1, 2))
            rows.append(row)
    finally:
        diag.close()
    wall = time.perf_counter() - start
    silent = [r for r in rows if r["garbage"] and not r["flagged"]]
    by_method: dict[str, list[dict[str, Any]]] = {}
    for r in rows:
        by_method.setdefault(r["method"], []).append(r)
    notes = []
    for meth, rs in by_method.items():
        g = [r for r in rs if r["garbage"]]
        f = [r for r in rs if r["flagged"]]
        key = "tolerance" if meth == "dop853" else "step"
        notes.append(f"{meth}: garbage from {key} {g[-1][key]:.3g} up" if g and meth !=
                     "dop853" else f"{meth}: garbage at {key} ≥ {min(r[key] for r in g):.3g}"
                     if g else f"{meth}: never garbage")
        if f:
            notes[-1] += f", flagged from {max(r[key] for r in f if r[key]) if meth == 'dop853' else min(r[key] for r in f):.3g}"  # noqa: E501
    ok = not silent
    outcome = ("; ".join(notes) + (f"; {len(silent)} silent garbage point(s)" if silent else
                                   "; diagnostics flag every garbage point"))
    return [Result("sweeps", system, _variant(kw), ok, outcome, crit,
                   {"points": rows, "silent_garbage": len(silent)}, {"points": rows}, wall)]


# --- 6. Hamilton's principle ----------------------------------------------------------------
def _lagrangian_model(system: str) -> tuple[Model | None, str]:
    """A formulation of ``system`` where Hamilton's principle applies to L alone, or why not."""
    from mechsim.systems import system_class
    from mechsim.systems.lagrangian import LagrangianModel

    cls = system_class(system)
    if not issubclass(cls, LagrangianModel):
        return None, "not declared by a Lagrangian (hand-written kernels)"
    why = ""
    for form in cls.formulations:
        kw = {"formulation": form} if len(cls.formulations) > 1 else {}
        try:
            model = cls(**kw)
        except MechsimError as e:
            why = str(e)
            continue
        s = model.structure
        if s.n_constraints:
            why = "constrained (multiplier) form"
        elif s.dissipative:
            why = "dissipative: Rayleigh forces are not in L"
        elif s.driven:
            why = "generalized forces are not in L"
        elif model.events:
            why = "events (impacts) break smoothness"
        else:
            return model, ""
    return None, why


def hamilton(system: str, quick: bool) -> list[Result]:
    import sympy as sp

    crit = ("S = ∫L dt on a computed trajectory is stationary: fixed-endpoint variations εη "
            "change it by O(ε²) — fitted slope of log|ΔS| vs log ε in [1.8, 2.2] — while the "
            "same variations of a non-solution give slope ≈ 1 (≤ 1.3): the check has power")
    model, why = _lagrangian_model(system)
    if model is None:
        return [Result("hamilton", system, "n/a", True, f"not applicable: {why}", crit,
                       {"applicable": False})]
    d = model.declaration  # type: ignore[attr-defined]
    L = d.kinetic - d.potential + d.linear
    syms = [d.t, *d.q, *d.v, *d.params.values()]
    f = sp.lambdify(syms, L, "numpy")
    pvals = [float(model.values[name]) for name in d.params]  # type: ignore[arg-type]
    T = min(model.time_scale(), 5.0)
    N = 4000
    start = time.perf_counter()
    run = simulate(model, T, T / N, tolerance=1e-13, method="dop853", outputs=("energy",))
    t = run.t
    n = len(model.coordinates)
    rng = np.random.default_rng(7)
    direction = rng.normal(size=n)
    direction /= np.linalg.norm(direction)
    scale = np.maximum(np.max(np.abs(run.q), axis=0), 1.0) * 0 + 1.0
    eta = np.sin(np.pi * t / T)[:, None] * direction * scale
    eta_dot = (np.pi / T) * np.cos(np.pi * t / T)[:, None] * direction * scale

    def action(q: np.ndarray, v: np.ndarray) -> float:
        vals = f(t, *q.T, *v.T, *pvals)
        vals = np.broadcast_to(np.asarray(vals, dtype=float), t.shape)
        from scipy.integrate import simpson
        return float(simpson(vals, x=t))

    eps = np.logspace(-5, -2, 7)

    def slope(q: np.ndarray, v: np.ndarray) -> tuple[float, list[float]]:
        s0 = action(q, v)
        ds = [abs(action(q + e * eta, v + e * eta_dot) - s0) for e in eps]
        good = np.array(ds) > 0
        if good.sum() < 3:
            return math.nan, ds
        return float(np.polyfit(np.log(eps[good]), np.log(np.array(ds)[good]), 1)[0]), ds

    k_sol, ds_sol = slope(run.q, run.v)
    # Control: a path that is not a solution (the same endpoints, bent by 0.1·4s(1 − s),
    # s = t/T; a sine bend can be orthogonal to η for linear systems).
    s_ = t / T
    bend = (0.4 * s_ * (1 - s_))[:, None] * direction
    bend_dot = (0.4 * (1 - 2 * s_) / T)[:, None] * direction
    k_ctl, ds_ctl = slope(run.q + bend, run.v + bend_dot)
    wall = time.perf_counter() - start
    ok = 1.8 <= k_sol <= 2.2 and k_ctl <= 1.3
    return [Result("hamilton", system, model.formulation, ok,
                   f"|ΔS| ∝ ε^{k_sol:.2f} on the trajectory, ε^{k_ctl:.2f} on a bent path "
                   f"(window {T:.3g} s, {N} intervals)", crit,
                   {"applicable": True, "slope": k_sol, "control_slope": k_ctl,
                    "epsilons": list(eps), "dS": ds_sol, "dS_control": ds_ctl, "window": T},
                   {"eps": [float(e) for e in eps], "dS": ds_sol, "dS_control": ds_ctl}, wall)]


# --- the catalogue ----------------------------------------------------------------------------
@dataclass(frozen=True)
class Case:
    name: str
    run: Callable[[str, bool], list[Result]]
    applies: Callable[[str], bool]
    quick_systems: tuple[str, ...]


CASES: dict[str, Case] = {
    "long_horizon": Case("long_horizon", long_horizon, lambda s: True,
                         ("pendulum", "kepler", "double_pendulum", "damped_oscillator")),
    "chaos": Case("chaos", chaos, lambda s: s in CHAOS, ("double_pendulum", "cr3bp")),
    "stiffness": Case("stiffness", stiffness, lambda s: s in STIFF,
                      ("damped_oscillator", "spring_pendulum")),
    "singular": Case("singular", singular, lambda s: s in SINGULAR,
                     ("pendulum", "kepler", "moving_frames", "bead_on_wire")),
    "sweeps": Case("sweeps", sweeps, lambda s: s in SWEEPS, ("pendulum", "kepler")),
    "hamilton": Case("hamilton", hamilton, lambda s: True,
                     ("pendulum", "kepler", "double_pendulum", "spring_pendulum",
                      "harmonic_oscillator", "damped_oscillator")),
}


def plan(systems: list[str] | None, quick: bool,
         cases: list[str] | None = None) -> list[tuple[str, str]]:
    """(case, system) pairs to run, in catalogue order."""
    known = system_ids()
    chosen = systems or known
    out = []
    for name, case in CASES.items():
        if cases and name not in cases:
            continue
        for s in chosen:
            if case.applies(s) and (not quick or s in case.quick_systems):
                out.append((name, s))
    return out


__all__ = ["CASES", "Result", "plan", "IntegrationError", "StiffnessError"]
