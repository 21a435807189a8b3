"""Work-precision benchmark: mechsim's integrators against scipy, hand-written numba loops,
matrix exponentials, REBOUND, MuJoCo and Drake.

For each benchmark problem (see :mod:`mechsim.bench.problems`; each runs on one mechsim
system) every contestant integrates the same IVP over the same horizon, sampling the same
times, once per setting of its accuracy knob. Time: median of ``repeats`` runs (more, up to
21, for runs under 0.1 s; not with ``--quick``) after one warm-up run (the warm-up time is
kept separately; a setting whose warm-up exceeds ``budget_s`` is timed once and ends that
contestant's sweep, flagged ``repeats: 1``). The runs each matched-error comparison is
read from are then timed again together, in rounds (:mod:`mechsim.bench.paired`), and their
time is the median over the rounds. Errors against the reference, on the problem's
compared states: the state at the last sample and the largest over the samples (‖C − C_ref‖
over the largest ‖C_ref‖), and the largest relative drift of the conserved quantity.

mechsim contestants: every method of ``mechsim.integrators.METHODS`` except those in
``SKIP_METHODS``, via ``simulate(model, t_end, output_dt, tolerance, method)`` (the model is
built, and its kernels loaded or compiled, before timing: see ``compile``); a method that does
not apply to the system is reported ``n/a``. ``auto`` picks one of the others: where its run
gives bit for bit the states of the method it picked at the same tolerance, it is not timed
again (its row copies that method's times and says ``same_as``). Peers: see
:mod:`mechsim.bench.peers`.

JSON schema (``results.json``)::

    {"schema": "mechsim-bench/1", "created": ISO time, "quick": bool,
     "host": {"python", "platform", "cpu", "cores", "loadavg_start", "loadavg_end",
              "numpy", "scipy", "numba", "env": {...}},
     "settings": {"repeats", "budget_s", "error_levels"},
     "peers": {"found": {family: version}, "missing": {family: reason},
               "skipped": {family: reason}},
      "systems": {PROBLEM: {
         "problem": {"system", "description", "params", "t_end", "n_samples", "reference",
                     "conserved"},
         "compile": {"load_s": model build in this process,
                     "first_call_s": {contestant: first run, loosest setting, not timed
                                      in the sweep (kernel load / JIT, imports)},
                     "cold_s": {method: s} or null (fresh cache, separate process)},
         "runs": [{"contestant", "family", "knob", "setting", "status" ("ok" | "skipped: …"
                   | "failed: …" | "n/a: …"), "time_s" (median), "times_s", "warmup_s",
                   "repeats", "sweep_time_s" and "paired_times_s" (runs timed again
                   together), "end_error", "max_error", "invariant_error", "n_steps",
                   "n_rhs", "method" (resolved, mechsim), "same_as" (auto only)}],
         "matched": {"1e-04": {"mechsim": {"contestant", "time_s", "bound"} | null,
                               "peer": {...} | null, "scipy": {...} | null,
                               "speedup_vs_peer": float | null,
                               "speedup_vs_scipy": float | null}, ...}}},
     "targets": [{"target", "system", "passed": bool | null, "detail"}]}

(``system`` in a target is the problem name, or "all" for targets not tied to one problem.)

``matched``: each contestant's Pareto front (end error against median time) is interpolated
log-log at the error level; ``bound: true`` means the contestant's cheapest run was already
more accurate than the level (its time is an upper bound). "mechsim" is mechsim's fastest
method at that level, "peer" the fastest of every other family, "scipy" the fastest
``solve_ivp`` method. A speedup is peer time / mechsim time at the same level.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from mechsim.bench import peers as peers_mod
from mechsim.bench.front import error_at, pareto, time_at
from mechsim.bench.paired import contested_runs, retime
from mechsim.bench.peers import Contestant, Runner
from mechsim.bench.problems import BUILDERS, Problem, problem, system_of
from mechsim.files import write_atomic

ERROR_LEVELS = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)
# mechsim's loosest tolerance: the error levels start at 1e-4, and DOP853's error at a
# tolerance is far below it (it runs at 1e-3 × the tolerance locally: 1e-3 gives 2e-6 to 1e-5
# on driven_oscillator and heavy_top), so a sweep from 1e-3 would leave it only an upper bound
# at the loose levels. (scipy's sweep keeps 1e-3: its errors there are already above 1e-4,
# and LSODA at 1e-2 crawls on heavy_top.)
MECHSIM_LOOSEST = 1e-1
# Methods of mechsim.integrators.METHODS left out of the benchmark, and why.
SKIP_METHODS = {"verlet": "second order: off the chart at the error levels benchmarked"}


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


# --- mechsim contestants ----------------------------------------------------------------------
_models: dict[tuple[str, tuple[tuple[str, str], ...]], Any] = {}


def _model(pb: Problem) -> Any:
    """The mechsim model of a problem, built once per system and parameter set."""
    from mechsim.systems import load_system

    key = (pb.system, tuple(sorted((k, repr(v)) for k, v in pb.params.items())))
    if key not in _models:
        _models[key] = load_system(pb.system, **pb.params)
    return _models[key]


def stepper_counts(st: Any) -> int | None:
    """Right-hand-side (or force) evaluations of a finished stepper, where it tells."""
    if st.method == "exact":
        return 0
    v = getattr(st, "n_evaluations", None)
    return None if v is None else int(v)


def _mechsim(method: str) -> Any:
    def prepare(pb: Problem, tol: float) -> Runner:
        from mechsim.integrators import choose_method
        from mechsim.simulate import simulate

        model = _model(pb)
        choose_method(model, method)  # ParameterError when the method does not fit
        dt = pb.t_end / pb.n_samples  # simulate's times are then ``pb.times()``

        def run() -> tuple[Any, dict[str, Any]]:
            # What a user calls and reads: the state is all that is compared (and all a peer
            # integrates): no outputs, no work terms. Laid out as rows by ``_mechsim_rows``,
            # after the timing (as a peer's loop returns its rows).
            r = simulate(model, pb.t_end, dt, tolerance=tol, method=method, outputs=(),
                         work_terms=False)
            return (r, r.q, r.v), {}
        return run
    return prepare


def _mechsim_rows(ran: Any, stats: dict[str, Any]) -> tuple[np.ndarray, dict[str, Any]]:
    """A mechsim run's rows [q, v, work terms, modes] and counters (``Contestant.unpack``)."""
    r, q, v = ran
    assert r.modes is not None  # every run has its (maybe empty) modes
    return np.column_stack([q, v, r.work_external, r.work_dissipated, r.modes]), {
        "n_steps": r.n_steps, "n_rhs": 0 if r.method == "exact" else r.n_evaluations,
        "method": r.method}


def _mechsim_convert(pb: Problem, rows: np.ndarray) -> np.ndarray:
    return pb.mechsim_compared(_model(pb), pb.times(), rows)


def mechsim_methods() -> list[str]:
    """mechsim's methods to benchmark: ``METHODS`` less ``SKIP_METHODS``, ``auto`` last."""
    from mechsim.integrators import METHODS

    ms = [m for m in METHODS if m not in SKIP_METHODS and m != "auto"]
    return ms + (["auto"] if "auto" in METHODS else [])


def mechsim_contestants(quick: bool) -> list[Contestant]:
    tols = peers_mod._tolerances(quick, loosest=MECHSIM_LOOSEST)
    return [Contestant(f"mechsim:{m}", "mechsim", "tolerance", tols, _mechsim(m),
                       convert=_mechsim_convert, unpack=_mechsim_rows)
            for m in mechsim_methods()]


# --- timing -----------------------------------------------------------------------------------
@dataclass
class Timing:
    warmup: float
    times: list[float]
    Y: np.ndarray
    stats: dict[str, Any]


Shortcut = Callable[[np.ndarray, dict[str, Any]], "Timing | None"]


def measure(run: Runner, repeats: int, budget_s: float, same: Shortcut | None = None,
            steady_s: float = 0.3, unpack: Any = None) -> Timing:
    """Warm-up run, then the timed repeats; ``same`` may answer from the warm-up's result
    (a run already timed under another name) and skip the repeats. Runs under 0.1 s are
    repeated more, up to about ``steady_s`` in all (at most 21 runs). ``unpack``: the
    contestant's (``Contestant.unpack``), applied outside the timing."""
    t0 = time.perf_counter()
    Y, stats = run()
    warm = time.perf_counter() - t0
    if unpack is not None:
        Y, stats = unpack(Y, stats)
    if same is not None:
        hit = same(Y, stats)
        if hit is not None:
            return hit
    times: list[float] = []
    if warm > budget_s:
        times = [warm]
    else:
        # Cheap runs are repeated more (at most 21): the median is steadier.
        n = repeats if warm > 0.1 else min(21, max(repeats, int(steady_s / max(warm, 1e-6))))
        for _ in range(n):
            t0 = time.perf_counter()
            Y, stats = run()
            times.append(time.perf_counter() - t0)
        if unpack is not None:
            Y, stats = unpack(Y, stats)
    return Timing(warm, times, Y, stats)


def prime(pb: Problem, c: Contestant) -> float | None:
    """One untimed-for-the-sweep run at the loosest setting: kernel load or JIT compile,
    imports, caches. Returns its wall time (None if the method does not apply or fails)."""
    try:
        t0 = time.perf_counter()
        run = c.prepare(pb, c.settings[0])
        run()
        return time.perf_counter() - t0
    except Exception:  # noqa: BLE001 - reported by the sweep itself
        return None


def _digest(Y: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(Y).tobytes()).hexdigest()


def sweep(pb: Problem, c: Contestant, repeats: int, budget_s: float,
          done: dict[tuple[str, float], tuple[str, Timing]] | None = None,
          steady_s: float = 0.3) -> list[dict[str, Any]]:
    """Rows of one contestant over its settings. ``done`` collects (contestant, setting) ->
    (digest of the states, timing) of mechsim runs; ``mechsim:auto`` answers from it when its
    states equal those of the method it picked."""
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
        same = None
        if done is not None and c.name == "mechsim:auto":
            def same(Y: np.ndarray, stats: dict[str, Any], setting: float = setting,
                     row: dict[str, Any] = row) -> Timing | None:
                hit = done.get((f"mechsim:{stats.get('method')}", setting))
                if hit is not None and hit[0] == _digest(Y):
                    row["same_as"] = f"mechsim:{stats.get('method')}"
                    return hit[1]
                return None
        try:
            m = measure(run, repeats, budget_s, same, steady_s, c.unpack)
        except Exception as e:  # noqa: BLE001 - a failed run is a data point, not a crash
            row["status"] = f"failed: {type(e).__name__}: {str(e).splitlines()[0][:120]}"
            continue
        Y = m.Y if c.convert is None else c.convert(pb, m.Y)
        err = pb.errors(Y) if c.convert is None else pb.compared_errors(Y)
        row.update(time_s=statistics.median(m.times), times_s=m.times, warmup_s=m.warmup,
                   repeats=len(m.times), **err)
        for k in ("n_steps", "n_rhs", "method", "dt"):
            if m.stats.get(k) is not None:
                row[k] = m.stats[k]
        if done is not None and c.family == "mechsim" and "same_as" not in row:
            done[(c.name, setting)] = (_digest(m.Y), m)
        if m.warmup > budget_s:
            stop = f"skipped: previous setting took {m.warmup:.1f} s > budget {budget_s:g} s"
        log(f"  {c.name:<24} {c.knob}={setting:<8.3g} {row['time_s'] * 1e3:10.3f} ms  "
            f"end {row['end_error']:.2e}  max {row['max_error']:.2e}"
            + (f"  inv {row['invariant_error']:.2e}" if row["invariant_error"] is not None
               else "") + (f"  (= {row['same_as']})" if "same_as" in row else ""))
    return rows


# --- matched error ----------------------------------------------------------------------------
def best_at(rows: list[dict[str, Any]], level: float, family_filter: Any
            ) -> dict[str, Any] | None:
    best: dict[str, Any] | None = None
    names = sorted({r["contestant"] for r in rows if family_filter(r["family"])})
    for name in names:
        # rows that copy another contestant's run (auto's "same_as") are that contestant's
        hit = time_at(pareto([r for r in rows if r["contestant"] == name
                              and not r.get("same_as")]), level)
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


MACHINE_PRECISION = 1e-12  # the end error of issue 11's machine-precision target


def _level_target(name: str, m: dict[str, Any], who: str, factor: float) -> dict[str, Any]:
    """mechsim's fastest at least ``factor`` × as fast as ``who`` ("peer" or "scipy") at every
    level ``who`` reaches (a level only the other reaches is a miss)."""
    det: list[str] = []
    ok, seen = True, False
    for lv, x in m.items():
        ms, other = x["mechsim"], x[who]
        if other is None:
            continue
        seen = True
        if ms is None:
            ok = False
            det.append(f"{lv}: {other['contestant']} reaches it, mechsim does not")
            continue
        r = other["time_s"] / ms["time_s"]
        ok = ok and r >= factor
        det.append(f"{lv}: {r:.2f}× ({ms['contestant']} vs {other['contestant']})")
    label = ("mechsim's fastest ≥ the best peer at matched end error" if who == "peer"
             else f"mechsim's fastest ≥ {factor:g}× scipy's best at matched end error")
    return {"target": label, "system": name, "passed": ok if seen else None,
            "detail": "; ".join(det) or f"no level reached by {who}"}


def _machine_precision_target(name: str, rows: list[dict[str, Any]]) -> dict[str, Any]:
    """End error ≤ 1e-12 with a numerical mechsim method (not ``exact``) in no more time than
    REBOUND IAS15 needs for it in the same run."""
    lv = MACHINE_PRECISION
    num = [r for r in rows if r["family"] == "mechsim" and r.get("method") != "exact"
           and not r["contestant"].endswith(":exact")]
    front = pareto(num)
    hit = time_at(front, lv)
    best = (f"best numerical mechsim end error {front[-1][1]:.1e} in "
            f"{front[-1][0] * 1e3:.2f} ms" if front else "no numerical mechsim run")
    ms = (f"mechsim reaches {lv:.0e} in {hit[0] * 1e3:.2f} ms" if hit
          else f"mechsim does not reach {lv:.0e} ({best})")
    ias_rows = [r for r in rows if r["contestant"] == "rebound:IAS15"]
    if not any(r["status"] == "ok" for r in ias_rows):
        return {"target": f"end error ≤ {lv:.0e}, numerical, no slower than REBOUND IAS15",
                "system": name, "passed": None, "detail": f"{ms}; IAS15 not run"}
    ias_front = pareto(ias_rows)
    ias = time_at(ias_front, lv)
    ias_txt = (f"IAS15 {ias[0] * 1e3:.2f} ms" if ias else
               f"IAS15 does not reach it (best {ias_front[-1][1]:.1e} in "
               f"{ias_front[-1][0] * 1e3:.2f} ms)")
    passed = hit is not None and (ias is None or hit[0] <= ias[0])
    return {"target": f"end error ≤ {lv:.0e}, numerical, no slower than REBOUND IAS15",
            "system": name, "passed": passed, "detail": f"{ms}; {ias_txt}"}


NOT_MEASURED_HERE = (
    ("machine-precision method: energy error over 10⁷ steps grows no faster than √N "
     "(Brouwer's law)", "a long run of one method, not a work-precision sweep: "
     "`mechsim bench --brouwer` measures it"),
    ("cold start: first message ≤ 2× the warm time; all 29 systems derived and compiled in "
     "≤ 60 s of CPU; cold `make test` ≤ 6 minutes", "start-up and test-suite timings"),
)


#: Why a ``--quick`` run judges no target: its figures stay, its verdicts would mislead.
QUICK_NOT_JUDGED = ("not judged: --quick shortens the problems and times each run once (a "
                    "check that everything runs); the targets are judged on a full run")


def targets(systems: dict[str, Any], quick: bool = False) -> list[dict[str, Any]]:
    """Issue 11's benchmark targets, met (True), missed (False) or not judged (None), with
    the figures; issue 6's comparison with MuJoCo and Drake at equal time is kept. A
    ``quick`` run's problems are not the benchmark's: every verdict is None there."""
    out = _targets(systems)
    if quick:
        for t in out:
            if t["passed"] is not None:
                t["passed"], t["detail"] = None, f"{QUICK_NOT_JUDGED} ({t['detail']})"
    return out


def _targets(systems: dict[str, Any]) -> list[dict[str, Any]]:
    out: list[dict[str, Any]] = []
    for name, s in systems.items():
        rows = s["runs"]
        out.append(_level_target(name, s["matched"], "peer", 1.0))
        out.append(_level_target(name, s["matched"], "scipy", 20.0))
        if any(r["family"] == "rebound" for r in rows) or name in ("kepler", "cr3bp"):
            out.append(_machine_precision_target(name, rows))
        ms_front = pareto([r for r in rows if r["family"] == "mechsim"])
        for fam in ("mujoco", "drake"):
            pts = [r for r in rows if r["family"] == fam and r["status"] == "ok"]
            if not pts or not ms_front:
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
                        "system": name, "passed": not worse and not slower,
                        "detail": "; ".join(det) or f"all {len(pts)} {fam} points beaten"})
    for target, why in NOT_MEASURED_HERE:
        out.append({"target": target, "system": "all", "passed": None,
                    "detail": f"not measured in this run ({why})"})
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


def cold_compile(name: str, methods: list[str]) -> dict[str, float] | None:
    """Model build and first call of each method for problem ``name`` in a new process with an
    empty kernel cache (imports included in ``load_s``)."""
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        env = dict(os.environ, MECHSIM_CACHE_DIR=d, NUMBA_CACHE_DIR=d)
        try:
            p = subprocess.run([sys.executable, "-c", _COLD, name, *methods], env=env,
                               capture_output=True, text=True, timeout=600, check=True)
            return json.loads(p.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]
        except (subprocess.SubprocessError, ValueError, IndexError) as e:
            log(f"  cold compile of {name} failed: {e}")
            return None


# --- one problem ------------------------------------------------------------------------------
def bench_system(name: str, quick: bool, repeats: int, budget_s: float,
                 families: tuple[str, ...] | None, cold: bool,
                 peer_report: dict[str, dict[str, str]]) -> dict[str, Any]:
    """All contestants on one benchmark problem."""
    pb = problem(name, quick=quick)
    log(f"{name} ({pb.system}): {pb.description}")
    t0 = time.perf_counter()
    _model(pb)
    load_s = time.perf_counter() - t0
    pb.reference_states()
    cs = mechsim_contestants(quick)
    pc, missing, found = peers_mod.contestants(pb, quick, families)
    for fam, why in missing.items():
        if fam not in peer_report["missing"]:
            print(f"mechsim bench: peer {fam} missing ({why}); continuing without it")
        peer_report["missing"][fam] = why
    peer_report["found"].update(found)
    if quick:
        for fam in pb.peers:
            if fam not in missing and fam not in peers_mod.QUICK_FAMILIES:
                peer_report["skipped"][fam] = "--quick runs local peers only"
    rows: list[dict[str, Any]] = []
    first: dict[str, float] = {}
    done: dict[tuple[str, float], tuple[str, Timing]] = {}
    for c in [*cs, *pc]:
        t_first = prime(pb, c)
        if t_first is not None:
            first[c.name] = t_first
        # --quick checks that everything runs: cheap runs are not repeated for steadiness
        rows += sweep(pb, c, repeats, budget_s, done, steady_s=0.0 if quick else 0.3)
    if not quick:
        by_name = {c.name: c for c in [*cs, *pc]}
        runs = contested_runs(rows, ERROR_LEVELS)
        rounds = retime(runs, lambda r: by_name[r["contestant"]].prepare(pb, r["setting"]))
        log(f"  {len(runs)} runs timed again together, {rounds} rounds")
    cold_s = None
    if cold:
        meths = [m for m in ("dop853", "yoshida8") if f"mechsim:{m}" in first]
        cold_s = cold_compile(name, meths)
    return {"problem": {"system": pb.system, "description": pb.description,
                        "params": pb.params, "t_end": pb.t_end, "n_samples": pb.n_samples,
                        "reference": pb.reference_kind, "conserved": pb.conserved_name},
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
                                        "error_levels": list(ERROR_LEVELS),
                                        "skipped_methods": dict(SKIP_METHODS)},
                           "peers": report, "systems": {}}
    for sid in systems:
        res["systems"][sid] = bench_system(sid, quick, repeats, budget, families, cold, report)
    res["targets"] = targets(res["systems"], quick)
    res["host"]["loadavg_end"] = list(os.getloadavg())
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "results.json", json.dumps(_finite(res), indent=1,
                                                 default=_json_default))
    from mechsim.bench import report as report_mod

    write_atomic(out / "results.md", report_mod.markdown(res))
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
    """Names of the benchmark problems (each runs on a registered mechsim system)."""
    from mechsim.systems import system_ids

    ids = set(system_ids())
    return [name for name in BUILDERS if system_of(name) in ids]
