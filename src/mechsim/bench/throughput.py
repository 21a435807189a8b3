"""Throughput where users feel it: what one call of ``simulate`` costs beyond its steps, and
ensembles (``simulate_many``) against what a user would write instead, in one run.

- Per call: ``simulate`` of a pendulum for one output interval (two samples), with every
  output (and with reading its end state: a result makes its arrays when they are first
  read) and with the state only, and on a new model each call (another gravity, as a fit or
  a sweep calls it); ``make_stepper`` and its ``advance``; ``advance`` of a
  running stepper by one sample; the compiled call ``simulate`` makes (its arguments
  prepared once, its buffer made each call), through numba's dispatcher and through its
  compiled entry point, as ``simulate`` calls it: the floor of a call; scipy's ``solve_ivp`` and a
  hand-written numba RK4 loop for the same interval. µs per call in batches: the fastest
  batch and the median one (``per_call``).
- Ensembles: ``ENSEMBLE`` pendulums released from rest at random amplitudes, ten
  small-oscillation periods, ``SAMPLES`` samples, tolerance 1e-10: ``simulate_many`` (all
  cores and one), a loop of ``simulate``, a loop of scipy's ``solve_ivp`` (DOP853) and a
  hand-written numba ``prange`` RK4 loop (all cores and one), each at its end error against
  the closed form (Jacobi sn, cn) over the members; the loops of Python calls are timed on
  the first ``LOOP_MEMBERS`` members and scaled to the ensemble (said in the table); the
  RK4 loop's step is chosen to match ``simulate_many``'s largest end error. ``simulate_many``
  and the RK4 loop: the fastest of five runs each, made in rounds (``best_in_rounds``).
"""

from __future__ import annotations

import functools
import itertools
import json
import math
import os
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from mechsim.bench.host import reference_loop
from mechsim.files import write_atomic

ENSEMBLE = 10_000
SAMPLES = 100
TOLERANCE = 1e-10
LOOP_MEMBERS = {"simulate": 500, "solve_ivp": 40}
SEED = 3


#: Calls timed together in a batch.
BATCH = 50
#: The host's reference loop (``mechsim.bench.host``), timed before and after the calls.
REFERENCE = "reference loop"


def _batches_us(calls: dict[str, Callable[[], Any]], batches: int) -> dict[str, list[float]]:
    """µs per call of each of ``calls`` in each of ``batches`` batches of ``BATCH`` calls,
    one call's batches after the other's (after a warm-up call), as a loop of that call
    runs."""
    got: dict[str, list[float]] = {}
    for name, call in calls.items():
        call()
        got[name] = []
        for _ in range(batches):
            t0 = time.perf_counter()
            for _ in range(BATCH):
                call()
            got[name].append((time.perf_counter() - t0) / BATCH * 1e6)
    return got


def per_call(batches: int = 80) -> dict[str, dict[str, float]]:
    """µs per call of each way to run a pendulum for one output interval (module docstring):
    ``best``, the fastest batch (timeit's convention: slower batches met other work on the
    host), and ``median``, over ``batches`` batches; and the reference loop of
    :mod:`mechsim.bench.host` timed the same way, before and after them, in ms."""
    from scipy.integrate import solve_ivp

    import mechsim
    from mechsim.integrators import make_stepper

    model = mechsim.load_system("pendulum")
    dt = 0.01
    t1 = np.array([dt])
    st = make_stepper(model, "dop853", TOLERANCE)
    clock = [0.0]

    def advance() -> Any:
        clock[0] += dt
        return st.advance(np.array([clock[0]]))

    dispatched, entry = _compiled_loop(model, dt)
    g = 9.81
    loop = _rk4_one()
    y0 = model.initial_y()[:2].copy()
    def simulate(**kw: Any) -> Any:
        return mechsim.simulate(model, dt, dt, tolerance=TOLERANCE, **kw)

    other = itertools.count(1)

    def new_model() -> Any:  # a fit's or a sweep's call: a value changed each time
        changed = model.with_values(gravity=9.81 + 1e-9 * next(other))
        return mechsim.simulate(changed, dt, dt, tolerance=TOLERANCE, method="dop853",
                                outputs=(), work_terms=False)

    def scipy_call() -> Any:
        return solve_ivp(lambda t, y: [y[1], -g * math.sin(y[0])], (0.0, dt), y0,
                         method="DOP853", rtol=1e-13, atol=1e-13, t_eval=t1)

    calls: dict[str, Callable[[], Any]] = {
        "simulate, every output (auto)": simulate,
        "simulate, every output (dop853)": lambda: simulate(method="dop853"),
        "simulate, every output (dop853), then reading q[-1] and v[-1]":
            lambda: _end_state(simulate(method="dop853")),
        "simulate, state only (dop853)":
            lambda: simulate(method="dop853", outputs=(), work_terms=False),
        "simulate, every output (radau15)": lambda: simulate(method="radau15"),
        "simulate of a model with another gravity each call (with_values; dop853, state only)":
            new_model,
        "make_stepper + advance (dop853)":
            lambda: make_stepper(model, "dop853", TOLERANCE).advance(t1),
        "advance of a running stepper by one sample": advance,
        "the compiled call alone (dop853, every output), numba's dispatcher": dispatched.run,
        "the same call through its compiled entry point (as simulate calls it)": entry.run,
        "hand-written numba RK4 loop (one call, 4 steps)": lambda: loop(g, y0, dt, 4),
        "scipy solve_ivp (DOP853)": scipy_call,
    }
    before = _batches_us({REFERENCE: reference_loop}, 4)[REFERENCE]
    got = _batches_us(calls, batches)
    ref = before + _batches_us({REFERENCE: reference_loop}, 4)[REFERENCE]
    return {"best": {k: min(v) for k, v in got.items()},
            "median": {k: statistics.median(v) for k, v in got.items()},
            "reference_ms": {"best": min(ref) / 1e3, "median": statistics.median(ref) / 1e3,
                             "slowest": max(ref) / 1e3}}


def _end_state(result: Any) -> tuple[np.ndarray, np.ndarray]:
    return result.q[-1], result.v[-1]


def _compiled_loop(model: Any, dt: float) -> tuple[Any, Any]:
    """The one compiled call of ``simulate(model, dt, dt, tolerance=TOLERANCE,
    method="dop853")`` with its arguments made once and its buffer made each call: through
    numba's dispatcher, and through the entry point of the overload it picks (as ``simulate``
    calls it: what is left of a call is unboxing the arguments): two ``PreparedRun``."""
    from mechsim.integrators.runs import RunPlan, plan_run
    from mechsim.simulate import OUTPUTS, output_times

    plan = plan_run(model, "dop853", TOLERANCE, OUTPUTS, horizon=dt)
    assert isinstance(plan, RunPlan)
    y, p, t = model.initial_y(), model.parameter_vector(), output_times(dt, dt)
    return (plan.prepare(model, y, p, t, None, entry=False),
            plan.prepare(model, y, p, t, None, entry=True))


@functools.cache
def _rk4_step() -> Any:
    """One classical RK4 step of the pendulum θ'' = -g sin θ (inlined where it is called)."""
    from numba import njit

    @njit(inline="always", cache=False)
    def step(g, th, om, h):  # type: ignore[no-untyped-def]
        k1t, k1o = om, -g * math.sin(th)
        k2t, k2o = om + 0.5 * h * k1o, -g * math.sin(th + 0.5 * h * k1t)
        k3t, k3o = om + 0.5 * h * k2o, -g * math.sin(th + 0.5 * h * k2t)
        k4t, k4o = om + h * k3o, -g * math.sin(th + h * k3t)
        return (th + h / 6.0 * (k1t + 2.0 * (k2t + k3t) + k4t),
                om + h / 6.0 * (k1o + 2.0 * (k2o + k3o) + k4o))
    return step


def _rk4_one() -> Any:
    from numba import njit

    step = _rk4_step()

    @njit(cache=False)
    def rk4(g, y0, t, n):  # type: ignore[no-untyped-def]
        th, om = y0[0], y0[1]
        h = t / n
        for _ in range(n):
            th, om = step(g, th, om, h)
        out = np.empty((2, 2))
        out[0] = y0
        out[1, 0], out[1, 1] = th, om
        return out
    return rk4


def _rk4_many() -> Any:
    """The hand-written ensemble loop a user would write: RK4 on the pendulum, fixed steps,
    members in parallel (``prange``)."""
    from numba import njit, prange

    step = _rk4_step()

    @njit(cache=False, parallel=True)
    def rk4_many(g, y0, t_out, n_sub, Y):  # type: ignore[no-untyped-def]
        for i in prange(y0.shape[0]):
            th, om = y0[i, 0], y0[i, 1]
            Y[i, 0, 0], Y[i, 0, 1] = th, om
            for k in range(1, t_out.size):
                h = (t_out[k] - t_out[k - 1]) / n_sub
                for _ in range(n_sub):
                    th, om = step(g, th, om, h)
                Y[i, k, 0], Y[i, k, 1] = th, om
    return rk4_many


def _reference_end(amplitudes: np.ndarray, t_end: float, g: float) -> np.ndarray:
    """The pendulums' states at ``t_end`` from the closed form (released from rest)."""
    from scipy.special import ellipj, ellipk

    w0 = math.sqrt(g)
    k = np.sin(amplitudes / 2)
    K = ellipk(k * k)
    sn, cn, _, _ = ellipj(np.mod(K - w0 * t_end, 4 * K), k * k)
    return np.stack([2 * np.arcsin(k * sn), -2 * k * w0 * cn], axis=1)


def _end_error(end: np.ndarray, ref: np.ndarray, amplitudes: np.ndarray, g: float) -> float:
    """The largest end error over the members, each relative to its state scale (its
    amplitude and largest rate)."""
    scale = np.hypot(amplitudes, 2 * np.sqrt(g) * np.sin(amplitudes / 2))
    return float(np.max(np.linalg.norm(end - ref, axis=1) / scale))


def _cores(n: int) -> str:
    return f"{n} core{'s' if n > 1 else ''}"


def best_in_rounds(calls: dict[str, Callable[[], Any]], rounds: int) -> dict[str, float]:
    """The fastest of ``rounds`` timed runs of each call, made in rounds (each call once a
    round, each round starting one call further on), so a slow stretch of the host meets one
    run of several calls rather than every run of one (a ratio of two calls, such as the
    scaling from one core to all, compares runs that met the same host)."""
    from mechsim.bench.paired import timed_in_rounds

    got = timed_in_rounds(list(calls.values()), rounds, clock=time.perf_counter)
    return {name: min(times, default=math.inf) for name, times in zip(calls, got, strict=True)}


def ensembles(n: int = ENSEMBLE, repeats: int = 5) -> dict[str, Any]:
    """The ensemble contest of the module docstring: {contestant: {time_s, end_error,
    measured_members, threads}} and the scaling from one core to all."""
    import numba
    from scipy.integrate import solve_ivp

    import mechsim

    model = mechsim.load_system("pendulum")
    g = float(model.values["gravity"]) / float(model.values["length"])
    T = 10.0 * model.time_scale()
    rng = np.random.default_rng(SEED)
    amplitudes = rng.uniform(0.1, 3.0, n)
    states = np.stack([amplitudes, np.zeros(n)], axis=1)
    ref = _reference_end(amplitudes, T, g)
    cores = numba.config.NUMBA_NUM_THREADS
    out: dict[str, Any] = {"members": n, "t_end": T, "samples": SAMPLES + 1,
                           "tolerance": TOLERANCE, "cores": cores, "contestants": {}}
    runs = out["contestants"]

    def many(method: str, threads: int | None) -> Any:
        return mechsim.simulate_many(model, T, T / SAMPLES, states=states, tolerance=TOLERANCE,
                                     method=method, outputs=(), work_terms=False,
                                     threads=threads)

    calls: dict[str, Callable[[], Any]] = {}
    for method in ("dop853", "auto"):
        for threads in (None, 1):
            r = many(method, threads)  # warm-up (compiled on first use)
            name = f"simulate_many ({method}, {_cores(threads or cores)})"
            calls[name] = functools.partial(many, method, threads)
            runs[name] = {"end_error": _end_error(np.c_[r.q[:, -1, 0], r.v[:, -1, 0]], ref,
                                                  amplitudes, g),
                          "measured_members": n, "methods": sorted(set(r.methods))}
    for name, seconds in best_in_rounds(calls, repeats).items():
        runs[name]["time_s"] = seconds
    target = runs[f"simulate_many (dop853, {cores} cores)"]["end_error"]
    k = LOOP_MEMBERS["simulate"]
    t0 = time.perf_counter()
    ends = []
    for a in amplitudes[:k]:
        st = mechsim.simulate(model.with_values(**{"initial.angle": float(a)}), T, T / SAMPLES,
                              tolerance=TOLERANCE, method="dop853", outputs=(),
                              work_terms=False)
        ends.append([st.q[-1, 0], st.v[-1, 0]])
    runs["loop of simulate (dop853, 1 core)"] = {
        "time_s": (time.perf_counter() - t0) * n / k, "measured_members": k,
        "end_error": _end_error(np.array(ends), ref[:k], amplitudes[:k], g)}
    k = LOOP_MEMBERS["solve_ivp"]
    t_eval = np.linspace(0.0, T, SAMPLES + 1)
    t0 = time.perf_counter()
    ends = []
    for a in amplitudes[:k]:
        sol = solve_ivp(lambda t, y: [y[1], -g * math.sin(y[0])], (0.0, T), [a, 0.0],
                        method="DOP853", rtol=TOLERANCE * 1e-3, atol=TOLERANCE * 1e-3,
                        t_eval=t_eval)
        ends.append(sol.y[:, -1])
    runs["loop of scipy solve_ivp (DOP853, 1 core)"] = {
        "time_s": (time.perf_counter() - t0) * n / k, "measured_members": k,
        "end_error": _end_error(np.array(ends), ref[:k], amplitudes[:k], g)}
    runs.update(_rk4_contest(states, amplitudes, ref, T, g, target, repeats, cores))
    best = runs[f"simulate_many (dop853, {cores} cores)"]["time_s"]
    one = runs["simulate_many (dop853, 1 core)"]["time_s"]
    rk4 = runs[f"hand-written numba prange RK4 ({cores} cores)"]
    out["speedup_vs_rk4"] = rk4["time_s"] / best
    out["scaling"] = one / best
    out["rk4_scaling"] = runs["hand-written numba prange RK4 (1 core)"]["time_s"] / rk4["time_s"]
    return out


def _rk4_contest(states: np.ndarray, amplitudes: np.ndarray, ref: np.ndarray, T: float,
                 g: float, target: float, repeats: int, cores: int) -> dict[str, Any]:
    """The hand-written prange RK4 at the fewest steps per output interval whose largest end
    error meets ``target`` (bisected from a first guess by its h⁴ error), on all cores and
    one."""
    import numba

    loop = _rk4_many()
    t_out = np.linspace(0.0, T, SAMPLES + 1)
    Y = np.empty((states.shape[0], t_out.size, 2))

    def error(n_sub: int) -> float:
        loop(g, states, t_out, n_sub, Y)
        return _end_error(Y[:, -1], ref, amplitudes, g)

    hi = max(1, math.ceil(8 * (error(8) / target) ** 0.25))
    while error(hi) > target:
        hi = math.ceil(hi * 1.2)
    lo = 0  # the fewest steps that meet the target: in (lo, hi]
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (lo, mid) if error(mid) <= target else (mid, hi)
    n_sub, e = hi, error(hi)
    before = numba.get_num_threads()

    def on(threads: int) -> None:
        numba.set_num_threads(threads)
        try:
            loop(g, states, t_out, n_sub, Y)
        finally:
            numba.set_num_threads(before)

    times = best_in_rounds({f"hand-written numba prange RK4 ({_cores(threads)})":
                            functools.partial(on, threads) for threads in (cores, 1)}, repeats)
    return {name: {"time_s": t, "end_error": e, "measured_members": states.shape[0],
                   "steps_per_output": n_sub} for name, t in times.items()}


def markdown(res: dict[str, Any]) -> str:
    ref = res.get("reference_ms") or {"best": math.nan, "median": math.nan, "slowest": math.nan}
    lines = ["# Per-call overhead and ensembles", "",
             f"Host: {os.cpu_count()} cores; all figures from one run.", "",
             "## One call: a pendulum for one output interval (two samples)", "",
             f"µs per call in {BATCH}-call batches of each call back to back: the fastest "
             "batch (timeit's convention: a slower batch met other work on the host) and the "
             "median batch. The host's speed before and after: a fixed pure-Python loop "
             f"(`mechsim.bench.host`) took {ref['best']:.2f} ms in its fastest batch, "
             f"{ref['median']:.2f} in the median one and {ref['slowest']:.2f} in the slowest.",
             "", "| call | µs, fastest batch | µs, median batch |", "| --- | ---: | ---: |"]
    median = res.get("per_call_median", {})
    lines += [f"| {k} | {v:.1f} | {median.get(k, float('nan')):.1f} |"
              for k, v in res["per_call"].items()]
    e = res["ensembles"]
    lines += ["", f"## {e['members']} pendulums, random amplitudes 0.1–3 rad, "
              f"{e['t_end']:.4g} s (ten small-oscillation periods), {e['samples']} samples, "
              f"tolerance {e['tolerance']:g}", "",
              "| contestant | time (s) | largest end error | members timed |",
              "| --- | ---: | ---: | ---: |"]
    for name, r in e["contestants"].items():
        lines.append(f"| {name} | {r['time_s']:.3g} | {r['end_error']:.2e} | "
                     f"{r['measured_members']} |")
    lines += ["", f"simulate_many (dop853) against the hand-written prange RK4 at matched "
              f"error: {e['speedup_vs_rk4']:.2f}×; scaling from one core to {e['cores']}: "
              f"{e['scaling']:.2f}× (the RK4 loop: {e['rk4_scaling']:.2f}×).", ""]
    return "\n".join(lines)


def run_throughput(out: Path, members: int = ENSEMBLE) -> dict[str, Any]:
    """Measure, write ``throughput.json`` and ``throughput.md`` into ``out``, print the
    table."""
    calls = per_call()
    res = {"per_call": calls["best"], "per_call_median": calls["median"],
           "reference_ms": calls["reference_ms"], "ensembles": ensembles(members)}
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "throughput.json", json.dumps(res, indent=1) + "\n")
    text = markdown(res)
    write_atomic(out / "throughput.md", text)
    print(text)
    return res
