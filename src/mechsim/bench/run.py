"""Work-precision benchmark: mechsim's integrators against scipy, REBOUND, MuJoCo and Drake.

For each system with a reference solution (see :mod:`mechsim.bench.problems`) every contestant
integrates the same IVP over the same horizon, sampling the same times, once per setting of
its accuracy knob. Time: median of ``repeats`` runs (more, up to 21, for runs under 0.1 s)
after one warm-up run (the warm-up time is
kept separately; a setting whose warm-up exceeds ``budget_s`` is timed once and ends that
contestant's sweep, flagged ``repeats: 1``). Errors against the reference: the state at the
last sample and the largest over the samples (norm of ``[q, v] − ref`` over the largest
reference state norm), and the largest relative drift of the conserved quantity.

mechsim contestants: ``dop853``, ``yoshida8``, ``yoshida6`` (tolerance sets the step),
``exact`` (closed-form propagation, where the system has one; tolerance has no effect) and
``auto``, via ``make_stepper(model, method, tolerance).advance(times)`` (the model is built,
and its kernels loaded or compiled, before timing: see ``compile``). Peers: see
:mod:`mechsim.bench.peers`.

JSON schema (``results.json``)::

    {"schema": "mechsim-bench/1", "created": ISO time, "quick": bool,
     "host": {"python", "platform", "cpu", "cores", "loadavg_start", "loadavg_end",
              "numpy", "scipy", "numba", "env": {...}},
     "settings": {"repeats", "budget_s", "error_levels"},
     "peers": {"found": {family: version}, "missing": {family: reason},
               "skipped": {family: reason}},
     "systems": {SYSTEM: {
         "problem": {"description", "params", "t_end", "n_samples", "reference",
                     "conserved"},
         "compile": {"load_s": model build in this process,
                     "first_call_s": {contestant: first run, loosest setting, not timed
                                      in the sweep (kernel load / JIT, imports)},
                     "cold_s": {method: s} or null (fresh cache, separate process)},
         "runs": [{"contestant", "family", "knob", "setting", "status" ("ok" | "skipped: …"
                   | "failed: …" | "n/a: …"), "time_s" (median), "times_s", "warmup_s",
                   "repeats", "end_error", "max_error", "invariant_error", "n_steps",
                   "n_rhs", "method" (resolved, mechsim)}],
         "matched": {"1e-04": {"mechsim": {"contestant", "time_s", "bound"} | null,
                               "peer": {...} | null, "scipy": {...} | null,
                               "speedup_vs_peer": float | null,
                               "speedup_vs_scipy": float | null}, ...}}},
     "targets": [{"target", "system", "passed": bool | null, "detail"}]}

``matched``: each contestant's Pareto front (end error against median time) is interpolated
log-log at the error level; ``bound: true`` means the contestant's cheapest run was already
more accurate than the level (its time is an upper bound). A speedup is peer time / mechsim
time at the same level.
"""

from __future__ import annotations

import json
import math
import os
import platform
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from mechsim.bench import peers as peers_mod
from mechsim.bench.peers import Contestant, Runner
from mechsim.bench.problems import BUILDERS, Problem, problem

ERROR_LEVELS = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)
MECHSIM_METHODS = ("dop853", "yoshida8", "yoshida6", "exact", "auto")
DEFAULT_SYSTEMS = ("pendulum", "kepler", "driven_oscillator", "harmonic_oscillator")


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


# --- mechsim contestants ----------------------------------------------------------------------
_models: dict[str, Any] = {}


def _model(pb: Problem) -> Any:
    from mechsim.systems import load_system

    key = pb.system
    if key not in _models:
        _models[key] = load_system(pb.system, **pb.params)
    return _models[key]


def _mechsim(method: str) -> Any:
    def prepare(pb: Problem, tol: float) -> Runner:
        from mechsim.integrators import choose_method, make_stepper

        model = _model(pb)
        choose_method(model, method)  # ParameterError when the method does not fit
        t = pb.times()
        n = 2 * pb.n_q

        def run() -> tuple[np.ndarray, dict[str, Any]]:
            st = make_stepper(model, method, tol)
            Y = st.advance(t)
            n_rhs = 0 if st.method == "exact" else st.n_evaluations
            return Y[:, :n].copy(), {"n_steps": st.n_steps, "n_rhs": n_rhs,
                                     "method": st.method}
        return run
    return prepare


def mechsim_contestants(quick: bool) -> list[Contestant]:
    tols = peers_mod._tolerances(quick)
    return [Contestant(f"mechsim:{m}", "mechsim", "tolerance", tols, _mechsim(m))
            for m in MECHSIM_METHODS]


# --- timing -----------------------------------------------------------------------------------
@dataclass
class Timing:
    warmup: float
    times: list[float]
    Y: np.ndarray
    stats: dict[str, Any]


def measure(run: Runner, repeats: int, budget_s: float) -> Timing:
    t0 = time.perf_counter()
    Y, stats = run()
    warm = time.perf_counter() - t0
    times: list[float] = []
    if warm > budget_s:
        times = [warm]
    else:
        # Cheap runs are repeated more (up to ~0.3 s, at most 21): the median is steadier.
        n = repeats if warm > 0.1 else min(21, max(repeats, int(0.3 / max(warm, 1e-6))))
        for _ in range(n):
            t0 = time.perf_counter()
            Y, stats = run()
            times.append(time.perf_counter() - t0)
    return Timing(warm, times, Y, stats)


def prime(pb: Problem, c: Contestant) -> float | None:
    """One untimed-for-the-sweep run at the loosest setting: kernel load or JIT compile,
    imports, caches. Returns its wall time (None if the method does not apply or fails)."""
    try:
        run = c.prepare(pb, c.settings[0])
        t0 = time.perf_counter()
        run()
        return time.perf_counter() - t0
    except Exception:  # noqa: BLE001 - reported by the sweep itself
        return None


def sweep(pb: Problem, c: Contestant, repeats: int, budget_s: float) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    stop: str | None = None
    for setting in c.settings:
        row: dict[str, Any] = {"contestant": c.name, "family": c.family, "knob": c.knob,
                               "setting": setting, "status": "ok", "time_s": None,
                               "times_s": [], "warmup_s": None, "repeats": 0,
                               "end_error": None, "max_error": None, "invariant_error": None,
                               "n_steps": None, "n_rhs": None}
        rows.append(row)
        if stop:
            row["status"] = stop
            continue
        try:
            run = c.prepare(pb, setting)
        except Exception as e:  # noqa: BLE001 - the method does not apply to this system
            row["status"] = f"n/a: {str(e).splitlines()[0]}"
            stop = row["status"]
            continue
        try:
            m = measure(run, repeats, budget_s)
        except Exception as e:  # noqa: BLE001 - a failed run is a data point, not a crash
            row["status"] = f"failed: {type(e).__name__}: {str(e).splitlines()[0][:120]}"
            continue
        row.update(time_s=statistics.median(m.times), times_s=m.times, warmup_s=m.warmup,
                   repeats=len(m.times), **pb.errors(m.Y))
        for k in ("n_steps", "n_rhs", "method", "dt"):
            if m.stats.get(k) is not None:
                row[k] = m.stats[k]
        if m.warmup > budget_s:
            stop = f"skipped: previous setting took {m.warmup:.1f} s > budget {budget_s:g} s"
        log(f"  {c.name:<22} {c.knob}={setting:<8.3g} {row['time_s'] * 1e3:10.3f} ms  "
            f"end {row['end_error']:.2e}  max {row['max_error']:.2e}"
            + (f"  inv {row['invariant_error']:.2e}" if row["invariant_error"] is not None
               else ""))
    return rows


# --- matched error ----------------------------------------------------------------------------
def pareto(rows: list[dict[str, Any]], key: str = "end_error") -> list[tuple[float, float]]:
    """(time, error) points of the front: faster ones first, each more accurate than all the
    faster ones."""
    pts = sorted((r["time_s"], r[key]) for r in rows
                 if r["status"] == "ok" and r[key] is not None and math.isfinite(r[key]))
    front: list[tuple[float, float]] = []
    for t, e in pts:
        if not front or e < front[-1][1]:
            front.append((t, max(e, 1e-300)))
    return front


def time_at(front: list[tuple[float, float]], level: float) -> tuple[float, bool] | None:
    """Time to reach error ``level`` on the front (log-log interpolation); (time, bound)."""
    if not front or front[-1][1] > level:
        return None
    if front[0][1] <= level:
        return front[0][0], True
    for (t0, e0), (t1, e1) in zip(front, front[1:], strict=False):
        if e0 > level >= e1:
            f = math.log(e0 / level) / math.log(e0 / e1)
            return math.exp(math.log(t0) + f * math.log(t1 / t0)), False
    return None


def error_at(front: list[tuple[float, float]], t: float) -> float | None:
    """Best error reachable within time ``t`` on the front (log-log interpolation)."""
    if not front or t < front[0][0]:
        return None
    if t >= front[-1][0]:
        return front[-1][1]
    for (t0, e0), (t1, e1) in zip(front, front[1:], strict=False):
        if t0 <= t < t1:
            f = math.log(t / t0) / math.log(t1 / t0)
            return math.exp(math.log(e0) + f * math.log(e1 / e0))
    return None


def best_at(rows: list[dict[str, Any]], level: float, family_filter: Any
            ) -> dict[str, Any] | None:
    best: dict[str, Any] | None = None
    names = sorted({r["contestant"] for r in rows if family_filter(r["family"])})
    for name in names:
        hit = time_at(pareto([r for r in rows if r["contestant"] == name]), level)
        if hit and (best is None or hit[0] < best["time_s"]):
            best = {"contestant": name, "time_s": hit[0], "bound": hit[1]}
    return best


def matched(rows: list[dict[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for level in ERROR_LEVELS:
        ms = best_at(rows, level, lambda f: f == "mechsim")
        pe = best_at(rows, level, lambda f: f != "mechsim")
        sc = best_at(rows, level, lambda f: f == "scipy")
        out[f"{level:.0e}"] = {
            "mechsim": ms, "peer": pe, "scipy": sc,
            "speedup_vs_peer": pe["time_s"] / ms["time_s"] if ms and pe else None,
            "speedup_vs_scipy": sc["time_s"] / ms["time_s"] if ms and sc else None}
    return out


def targets(systems: dict[str, Any]) -> list[dict[str, Any]]:
    out: list[dict[str, Any]] = []
    for sid, s in systems.items():
        rows = s["runs"]
        ms_front = pareto([r for r in rows if r["family"] == "mechsim"])
        # ≥ 20× faster than scipy's best at matched error 1e-4 .. 1e-12.
        ratios = {lv: m["speedup_vs_scipy"] for lv, m in s["matched"].items()}
        got = {lv: r for lv, r in ratios.items() if r is not None}
        out.append({"target": "≥ 20× scipy's best at matched end error", "system": sid,
                    "passed": all(r >= 20 for r in got.values()) if got else None,
                    "detail": ", ".join(f"{lv}: {r:.1f}×" for lv, r in got.items())
                    or "no level reached by both"})
        if sid == "kepler":
            ias = [r for r in rows if r["contestant"] == "rebound:IAS15" and r["status"] == "ok"]
            det, ok = [], True
            for r in ias:
                hit = time_at(ms_front, r["end_error"])
                if hit is None:
                    ok = False
                    det.append(f"IAS15 ε={r['setting']:g}: {r['end_error']:.1e} in "
                               f"{r['time_s'] * 1e3:.2f} ms, mechsim never reaches it")
                else:
                    ok = ok and hit[0] <= r["time_s"]
                    det.append(f"IAS15 ε={r['setting']:g}: {r['end_error']:.1e} in "
                               f"{r['time_s'] * 1e3:.2f} ms vs mechsim {hit[0] * 1e3:.2f} ms")
            out.append({"target": "kepler: wall time ≤ REBOUND IAS15's at equal end error",
                        "system": sid, "passed": ok if ias else None,
                        "detail": "; ".join(det) or "IAS15 not run"})
        for fam in ("mujoco", "drake"):
            pts = [r for r in rows if r["family"] == fam and r["status"] == "ok"]
            if not pts:
                continue
            worse, slower = [], []
            for r in pts:
                e = error_at(ms_front, r["time_s"])
                if e is None:
                    slower.append(r)
                elif e > r["end_error"]:
                    worse.append((r, e))
            det = [f"{r['contestant']} {r['knob']}={r['setting']:g}: {r['end_error']:.1e} "
                   f"in {r['time_s'] * 1e3:.2f} ms, mechsim {e:.1e}" for r, e in worse]
            det += [f"{r['contestant']} {r['knob']}={r['setting']:g}: "
                    f"{r['time_s'] * 1e3:.2f} ms is below mechsim's fastest run "
                    f"({ms_front[0][0] * 1e3:.2f} ms)" for r in slower]
            out.append({"target": f"never less accurate than {fam} at equal time",
                        "system": sid, "passed": not worse and not slower,
                        "detail": "; ".join(det) or f"all {len(pts)} {fam} points beaten"})
    return out


# --- compile cost -----------------------------------------------------------------------------
_COLD = """
import json, sys, time
t0 = time.perf_counter()
from mechsim.systems import load_system
from mechsim.integrators import make_stepper
from mechsim.bench.problems import problem
pb = problem(sys.argv[1], quick=True)
m = load_system(pb.system, **pb.params)
out = {"load_s": time.perf_counter() - t0}
for meth in sys.argv[2:]:
    t0 = time.perf_counter()
    make_stepper(m, meth, 1e-8).advance(pb.times())
    out[meth] = time.perf_counter() - t0
print(json.dumps(out))
"""


def cold_compile(system: str, methods: list[str]) -> dict[str, float] | None:
    """Model build and first call of each method in a new process with an empty kernel cache
    (imports included in ``load_s``)."""
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        env = dict(os.environ, MECHSIM_CACHE_DIR=d, NUMBA_CACHE_DIR=d)
        try:
            p = subprocess.run([sys.executable, "-c", _COLD, system, *methods], env=env,
                               capture_output=True, text=True, timeout=600, check=True)
            return json.loads(p.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]
        except (subprocess.SubprocessError, ValueError, IndexError) as e:
            log(f"  cold compile of {system} failed: {e}")
            return None


# --- one system -------------------------------------------------------------------------------
def bench_system(system: str, quick: bool, repeats: int, budget_s: float,
                 families: tuple[str, ...] | None, cold: bool,
                 peer_report: dict[str, dict[str, str]]) -> dict[str, Any]:
    pb = problem(system, quick=quick)
    log(f"{system}: {pb.description}")
    t0 = time.perf_counter()
    _model(pb)
    load_s = time.perf_counter() - t0
    cs = mechsim_contestants(quick)
    pc, missing, found = peers_mod.contestants(pb, quick, families)
    for fam, why in missing.items():
        if fam not in peer_report["missing"]:
            print(f"mechsim bench: peer {fam} missing ({why}); continuing without it")
        peer_report["missing"][fam] = why
    peer_report["found"].update(found)
    if quick:
        for fam in pb.peers:
            if fam not in missing and fam != "scipy":
                peer_report["skipped"][fam] = "--quick runs scipy only"
    rows: list[dict[str, Any]] = []
    first: dict[str, float] = {}
    for c in [*cs, *pc]:
        t_first = prime(pb, c)
        if t_first is not None:
            first[c.name] = t_first
        rows += sweep(pb, c, repeats, budget_s)
    cold_s = None
    if cold:
        meths = [m for m in ("dop853", "yoshida8") if f"mechsim:{m}" in first]
        cold_s = cold_compile(system, meths)
    return {"problem": {"description": pb.description, "params": pb.params, "t_end": pb.t_end,
                        "n_samples": pb.n_samples, "reference": pb.reference_kind,
                        "conserved": pb.conserved_name},
            "compile": {"load_s": load_s, "first_call_s": first, "cold_s": cold_s},
            "runs": rows, "matched": matched(rows)}


def host_info() -> dict[str, Any]:
    import numba
    import scipy

    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    env = {k: os.environ[k] for k in ("OPENBLAS_CORETYPE", "OPENBLAS_L2_SIZE",
                                      "NUMBA_NUM_THREADS", "OMP_NUM_THREADS") if k in os.environ}
    return {"python": platform.python_version(), "platform": platform.platform(), "cpu": cpu,
            "cores": os.cpu_count(), "loadavg_start": list(os.getloadavg()),
            "numpy": np.__version__, "scipy": scipy.__version__, "numba": numba.__version__,
            "env": env}


def run_bench(systems: list[str], out: Path, quick: bool = False, repeats: int = 3,
              budget_s: float | None = None, families: tuple[str, ...] | None = None,
              cold: bool | None = None, plots: bool = True) -> dict[str, Any]:
    budget = budget_s if budget_s is not None else (2.0 if quick else 4.0)
    cold = (not quick) if cold is None else cold
    report: dict[str, dict[str, str]] = {"found": {}, "missing": {}, "skipped": {}}
    res: dict[str, Any] = {"schema": "mechsim-bench/1",
                           "created": datetime.now(UTC).isoformat(timespec="seconds"),
                           "quick": quick, "host": host_info(),
                           "settings": {"repeats": repeats, "budget_s": budget,
                                        "error_levels": list(ERROR_LEVELS)},
                           "peers": report, "systems": {}}
    for sid in systems:
        res["systems"][sid] = bench_system(sid, quick, repeats, budget, families, cold, report)
    res["targets"] = targets(res["systems"])
    res["host"]["loadavg_end"] = list(os.getloadavg())
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(json.dumps(_finite(res), indent=1,
                                                 default=_json_default))
    from mechsim.bench import report as report_mod

    (out / "results.md").write_text(report_mod.markdown(res))
    if plots:
        for sid in systems:
            report_mod.plot(res, sid, out / f"{sid}.png")
    print(report_mod.summary_text(res))
    return res


def _finite(o: Any) -> Any:
    """JSON has no inf/nan: a diverged run's error becomes null (its status says why)."""
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, dict):
        return {k: _finite(v) for k, v in o.items()}
    if isinstance(o, list):
        return [_finite(v) for v in o]
    return o


def _json_default(o: Any) -> Any:
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def known_systems() -> list[str]:
    from mechsim.systems import system_ids

    ids = set(system_ids())
    return [s for s in BUILDERS if s in ids]
