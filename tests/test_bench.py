"""``mechsim bench``: the harness (schema, errors shrink with tolerance, missing peers reported,
targets judged from the figures), the problems (each reference against independent solutions,
each problem against the mechsim system it names) and the peers (each converges at its order).
No wall-clock thresholds: timings are not asserted, only present."""

from __future__ import annotations

import functools
import json
import math
import os
import warnings
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mechsim.bench import peers, problems, problems_rigid, report
from mechsim.bench.run import (
    SKIP_METHODS,
    _level_target,
    _machine_precision_target,
    error_at,
    matched,
    mechsim_methods,
    pareto,
    time_at,
)
from mechsim.cli import main

TOP_KEYS = {"schema", "created", "quick", "host", "settings", "peers", "systems", "targets"}
SYSTEM_KEYS = {"problem", "compile", "runs", "matched"}
RUN_KEYS = {"contestant", "family", "knob", "setting", "status", "time_s", "times_s",
            "warmup_s", "repeats", "end_error", "max_error", "invariant_error", "n_steps",
            "n_rhs"}
ALL = list(problems.BUILDERS)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, Path, str]:
    out = tmp_path_factory.mktemp("bench")
    real = peers.available

    def fake(family: str) -> tuple[bool, str]:  # one peer missing, whatever is installed
        return (False, "ModuleNotFoundError: No module named 'mujoco'") if family == "mujoco" \
            else real(family)

    mp = pytest.MonkeyPatch()
    mp.setattr(peers, "available", fake)
    import contextlib
    import io

    buf = io.StringIO()
    try:
        with contextlib.redirect_stdout(buf):
            rc = main(["bench", "pendulum", "kepler", "driven_oscillator", "--quick",
                       "--out", str(out), "--no-plots"])
    finally:
        mp.undo()
    assert rc == 0
    return json.loads((out / "results.json").read_text()), out, buf.getvalue()


def test_schema(quick_run: tuple[dict, Path, str]) -> None:
    res, out, _ = quick_run
    assert TOP_KEYS <= res.keys()
    assert res["schema"] == "mechsim-bench/1" and res["quick"] is True
    assert set(res["systems"]) == {"pendulum", "kepler", "driven_oscillator"}
    for s in res["systems"].values():
        assert SYSTEM_KEYS <= s.keys()
        assert set(s["matched"]) == {"1e-04", "1e-06", "1e-08", "1e-10", "1e-12"}
        for r in s["runs"]:
            assert RUN_KEYS <= r.keys()
            if r["status"] == "ok":
                assert r["repeats"] >= 1 and len(r["times_s"]) == r["repeats"]
                assert r["time_s"] > 0 and r["end_error"] is not None
        # --quick: the local peers only (REBOUND, MuJoCo, Drake are skipped)
        assert {r["family"] for r in s["runs"]} == {"mechsim", "scipy", "handwritten"}
    md = (out / "results.md").read_text()
    assert "## Summary" in md and "## pendulum" in md and "## Targets" in md


def test_a_quick_run_judges_no_target(quick_run: tuple[dict, Path, str]) -> None:
    """Its problems are shortened and each run timed once: a PASS or MISS there would be read
    as the benchmark's verdict (a new user saw MISS against a README that says met)."""
    res, out, _ = quick_run
    assert res["targets"] and all(t["passed"] is None for t in res["targets"])
    # Every system's two speed targets would have had a verdict: kept as a figure, not judged.
    withheld = {(t["system"], t["target"]) for t in res["targets"]
                if t["detail"].startswith("not judged: --quick")}
    assert len(withheld) >= 2 * len(res["systems"]), res["targets"]
    md = (out / "results.md").read_text()
    assert "**MISS**" not in md and "**PASS**" not in md


def test_mechsim_methods_follow_the_integrators() -> None:
    from mechsim.integrators import METHODS

    ms = mechsim_methods()
    assert set(ms) == set(METHODS) - set(SKIP_METHODS) and ms[-1] == "auto"


def test_dop853_error_decreases_with_tolerance(quick_run: tuple[dict, Path, str]) -> None:
    res, _, _ = quick_run
    for sid, s in res["systems"].items():
        runs = sorted((r for r in s["runs"] if r["contestant"] == "mechsim:dop853"),
                      key=lambda r: -r["setting"])
        errs = [r["end_error"] for r in runs if r["status"] == "ok"]
        assert len(errs) == 3, sid
        assert errs[0] > errs[1] > errs[2], (sid, errs)
        assert errs[-1] < 1e-7, (sid, errs)


def test_handwritten_errors_decrease_with_steps(quick_run: tuple[dict, Path, str]) -> None:
    res, _, _ = quick_run
    for sid, s in res["systems"].items():
        runs = [r for r in s["runs"] if r["contestant"] == "handwritten:RK4"]
        errs = [r["end_error"] for r in sorted(runs, key=lambda r: r["setting"])]
        assert len(errs) == 3 and errs[0] > errs[1] > errs[2], (sid, errs)
        assert all(r["n_rhs"] == 4 * r["n_steps"] for r in runs)


def test_auto_not_timed_twice(quick_run: tuple[dict, Path, str]) -> None:
    """auto's rows copy the run of the method it picked only where the states are identical
    (pendulum: yoshida8), and the fastest-method choice never names the copy."""
    res, _, _ = quick_run
    runs = res["systems"]["pendulum"]["runs"]
    for r in (r for r in runs if r["contestant"] == "mechsim:auto"):
        assert r["same_as"] == f"mechsim:{r['method']}"
        twin = next(x for x in runs if x["contestant"] == r["same_as"]
                    and x["setting"] == r["setting"])
        assert (r["time_s"], r["end_error"]) == (twin["time_s"], twin["end_error"])
    for m in res["systems"]["pendulum"]["matched"].values():
        assert m["mechsim"] is None or m["mechsim"]["contestant"] != "mechsim:auto"


def test_compositions_not_applicable_to_driven(quick_run: tuple[dict, Path, str]) -> None:
    res, _, _ = quick_run
    runs = [r for r in res["systems"]["driven_oscillator"]["runs"]
            if r["contestant"] == "mechsim:yoshida8"]
    assert runs and all(r["status"].startswith("n/a") for r in runs)


def test_missing_peer_reported(quick_run: tuple[dict, Path, str]) -> None:
    res, _, stdout = quick_run
    assert "mujoco" in res["peers"]["missing"]
    assert stdout.count("peer mujoco missing") == 1


def test_plot_legends_match_their_panels(quick_run: tuple[dict, Path, str]) -> None:
    """Each panel's legend lists exactly the lines drawn in it, in their colours; no two
    contestants share a colour; both axes are named, with units."""
    import matplotlib.pyplot as plt

    res, _, _ = quick_run
    fig = report.figure(res, "pendulum")
    colours: dict[str, tuple] = {}
    try:
        for ax in fig.axes:
            legend = ax.get_legend()
            labels = [t.get_text() for t in legend.get_texts()]
            assert labels == [ln.get_label() for ln in ax.lines]
            for ln, handle in zip(ax.lines, legend.legend_handles, strict=True):
                assert handle.get_color() == ln.get_color()
                name = ln.get_label().split(" (")[0]
                assert colours.setdefault(name, ln.get_color()) == ln.get_color()
            assert "[ms]" in ax.get_ylabel() and "dimensionless" in ax.get_xlabel()
        assert len(set(map(str, colours.values()))) == len(colours)
        assert {"mechsim:dop853", "scipy:LSODA", "handwritten:RK4"} <= set(colours)
    finally:
        plt.close(fig)


# --- problems -----------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ALL)
def test_reference_matches_tight_scipy(name: str) -> None:
    """Every reference (closed form, or extended precision by another formulation) agrees
    with a tight DOP853 run of the problem's own right-hand side."""
    pb = problems.problem(name, quick=True)
    t = pb.times()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sol = solve_ivp(pb.rhs, (0, pb.t_end), pb.y0, method="DOP853", t_eval=t, rtol=1e-13,
                        atol=1e-13)
    assert np.allclose(pb.reference(t[:1])[0], pb.y0, rtol=0,
                       atol=1e-13 * float(np.max(np.abs(pb.y0))))
    err = pb.errors(sol.y.T)
    assert err["max_error"] < 1e-10, err
    if pb.conserved is not None:
        assert err["invariant_error"] < 1e-10, err


@pytest.mark.parametrize("name", ALL)
def test_problem_is_the_mechsim_system(name: str) -> None:
    """mechsim's trajectory at a tight tolerance matches the problem's reference: the problem
    is set up as the system, parameters and coordinates it names. (The bound leaves room for
    the attitude form near the rigid body's intermediate axis, ≈2e-8 at 1e-12; a wrong
    parameter, sign or convention gives 1e-3 or more.)"""
    from mechsim.integrators import make_stepper
    from mechsim.systems import load_system

    pb = problems.problem(name, quick=True)
    model = load_system(pb.system, **pb.params)
    rows = make_stepper(model, "dop853", 1e-12).advance(pb.times())
    err = pb.compared_errors(pb.mechsim_compared(model, pb.times(), rows))
    assert err["max_error"] < 1e-7, err


@pytest.mark.parametrize("name", ["rigid_body_intermediate", "rigid_body_generic",
                                  "heavy_top"])
def test_attitude_references_vs_extended_precision(name: str,
                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    """The elliptic-function references agree with a long-double DOP853 run of the problem's
    own equations (another method, round-off 1e-19) to near double round-off."""
    if not problems.EXTENDED:
        pytest.skip("long double is plain double on this platform")
    pb = problems.problem(name, quick=True)
    p = pb.p.astype(np.longdouble)
    # The kernels are scalar code over ``math``: with numpy's sin, cos, sqrt they keep long
    # double.
    shim = SimpleNamespace(**{k: getattr(math, k) for k in dir(math) if not k.startswith("_")})
    shim.sin, shim.cos, shim.sqrt = np.sin, np.cos, np.sqrt
    monkeypatch.setattr(problems, "math", shim)

    def rhs(y: np.ndarray) -> np.ndarray:
        dy = np.empty_like(y)
        pb.deriv(0.0, y, p, dy)
        return dy

    Y = problems._fixed_dop853_longdouble(rhs, pb.y0, pb.times(), 0.005).astype(float)
    monkeypatch.undo()
    assert pb.errors(Y)["max_error"] < 2e-13


@pytest.mark.parametrize("name", ["cr3bp", "spring_pendulum"])
def test_extended_precision_reference_converged(name: str,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """Halving the step of an extended-precision reference changes it by round-off only."""
    if not problems.EXTENDED:
        pytest.skip("long double is plain double on this platform")
    ref = problems.problem(name, quick=True).reference_states()
    fixed = problems._fixed_dop853_longdouble

    def finer(rhs, y0, t, h_max):  # type: ignore[no-untyped-def]
        return fixed(rhs, y0, t, h_max / 2)

    monkeypatch.setattr(problems, "_fixed_dop853_longdouble", finer)
    pb = problems.problem(name, quick=True)
    assert np.max(np.abs(pb.reference_states() - ref)) / pb.state_scale() < 1e-15


def test_jacobi_agm_vs_mpmath() -> None:
    """sn, cn, dn by the long-double AGM match mpmath's, close to the separatrix too."""
    import mpmath

    u = (0.3, 7.5, 40.0)
    for m1 in (1e-5, 0.4):
        got = problems_rigid.jacobi_elliptic_longdouble(np.array(u), m1)
        with mpmath.workdps(40):
            m = 1 - mpmath.mpf(m1)
            want = [[float(mpmath.ellipfun(f, x, m)) for x in u] for f in ("sn", "cn", "dn")]
        for k in range(3):
            assert np.max(np.abs(got[k].astype(float) - want[k])) < 1e-15, (m1, k)


# --- peers --------------------------------------------------------------------------------------
@pytest.mark.parametrize(("name", "method", "order"), [
    ("pendulum", "rk4", 4), ("pendulum", "yoshida4", 4), ("charged_particle_exb", "boris", 2)])
def test_handwritten_order(name: str, method: str, order: int) -> None:
    """Each hand-written loop converges at its order (doubling the steps divides the error
    by about 2^order): a wrong stage or weight would not."""
    pb = problems.problem(name, quick=True)
    prep = peers._handwritten(method)
    e1 = pb.errors(prep(pb, 256)()[0])["end_error"]
    e2 = pb.errors(prep(pb, 512)()[0])["end_error"]
    assert e1 is not None and e2 is not None
    assert 0.6 * 2**order < e1 / e2 < 1.5 * 2**order, (e1, e2)


def test_expm_propagator() -> None:
    pb = problems.problem("coupled_oscillators_12", quick=True)
    Y, _ = peers._expm(pb, 0.0)()
    assert pb.errors(Y)["max_error"] < 1e-12


def test_boris_keeps_the_speed_in_b() -> None:
    """In B alone the Boris rotation keeps |v| exactly (to round-off), at any step."""
    pb = problems.problem("charged_particle_b", quick=True)
    Y, _ = peers._handwritten("boris")(pb, 4)()
    speed = np.linalg.norm(Y[:, 3:], axis=1)
    assert np.max(np.abs(speed - speed[0])) < 1e-14


# --- matched errors and targets -----------------------------------------------------------------
def test_pareto_interpolation() -> None:
    rows = [{"status": "ok", "time_s": t, "end_error": e}
            for t, e in [(1.0, 1e-4), (10.0, 1e-8), (5.0, 1e-3), (100.0, 1e-12)]]
    front = pareto(rows)
    assert front == [(1.0, 1e-4), (10.0, 1e-8), (100.0, 1e-12)]  # (5 s, 1e-3) is dominated
    t, bound = time_at(front, 1e-6)  # type: ignore[misc]
    assert not bound and math.isclose(t, math.sqrt(10.0))
    assert time_at(front, 1e-2) == (1.0, True)
    assert time_at(front, 1e-13) is None
    e = error_at(front, math.sqrt(10.0))
    assert e is not None and math.isclose(e, 1e-6)
    assert error_at(front, 0.5) is None


def _row(contestant: str, family: str, t: float, e: float, **kw: object) -> dict:
    return {"contestant": contestant, "family": family, "status": "ok", "time_s": t,
            "end_error": e, "setting": 0.0, **kw}


def test_targets_from_figures() -> None:
    rows = [_row("mechsim:a", "mechsim", 1.0, 1e-4), _row("mechsim:a", "mechsim", 2.0, 1e-12),
            _row("scipy:X", "scipy", 30.0, 1e-4), _row("scipy:X", "scipy", 100.0, 1e-8),
            _row("handwritten:RK4", "handwritten", 0.5, 1e-4),
            _row("handwritten:RK4", "handwritten", 0.6, 1e-6)]
    m = matched(rows)
    peer = _level_target("p", m, "peer", 1.0)
    assert peer["passed"] is False and "1e-04: 0.50×" in peer["detail"]
    sc = _level_target("p", m, "scipy", 20.0)
    assert sc["passed"] is True  # 30×, 46×, 71× at 1e-4, 1e-6, 1e-8
    ias = [_row("rebound:IAS15", "rebound", 3.0, 1e-13)]
    assert _machine_precision_target("k", rows + ias)["passed"] is True
    slow_ias = [_row("rebound:IAS15", "rebound", 1.5, 1e-13)]
    assert _machine_precision_target("k", rows + slow_ias)["passed"] is False
    exact_only = [_row("mechsim:exact", "mechsim", 0.1, 0.0, method="exact")] + rows[2:] + ias
    assert _machine_precision_target("k", exact_only)["passed"] is False  # exact: not numerical
    assert _machine_precision_target("k", rows)["passed"] is None  # IAS15 not run


def test_double_pendulum_reference_vs_double_precision() -> None:
    """The extended-precision reference agrees with scipy Radau and DOP853 at 1e-14."""
    pb = problems.problem("double_pendulum", quick=True)
    for method in ("Radau", "DOP853"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sol = solve_ivp(pb.rhs, (0, pb.t_end), pb.y0, method=method, t_eval=pb.times(),
                            rtol=1e-14, atol=1e-14)
        assert pb.errors(sol.y.T)["max_error"] < 1e-11, method


def test_all_runs_every_report_once_in_order(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    """`bench --all` (what `make bench` runs): each report once, long and short problems
    apart, nothing run when a file it writes exists without --force."""
    import mechsim.bench.brouwer as brouwer
    import mechsim.bench.derive as derive
    import mechsim.bench.run as run
    import mechsim.bench.scene_cost as scene_cost
    import mechsim.bench.streaming as streaming
    import mechsim.bench.throughput as throughput
    import mechsim.cli.bench as bench_cli
    from mechsim.bench.problems import SHORT_OF

    calls: list[tuple[str, Any]] = []
    monkeypatch.setattr(run, "run_bench", lambda systems, out, **kw: calls.append(
        ("problems", (list(systems), out, kw["budget_s"]))))
    monkeypatch.setattr(streaming, "run_streaming", lambda out, s: calls.append(("streaming", out)))
    monkeypatch.setattr(throughput, "run_throughput",
                        lambda out, members: calls.append(("throughput", members)))
    monkeypatch.setattr(derive, "run_derive", lambda out, s: calls.append(("derive", s)))
    monkeypatch.setattr(scene_cost, "run_scene_cost",
                        lambda scene, out: calls.append(("scene", scene)))
    monkeypatch.setattr(brouwer, "run_brouwer",
                        lambda out, n_steps, runs: calls.append(("brouwer", (n_steps, runs))))
    # each section runs in a process of its own; here in this one, to see its calls
    monkeypatch.setattr(bench_cli, "_run_apart",
                        lambda name, out, options: bench_cli._run_section(name, out, options)
                        or 0)
    monkeypatch.chdir(Path(__file__).resolve().parents[1])
    (tmp_path / "streaming.md").write_text("kept")
    assert main(["bench", "--all", "--out", str(tmp_path)]) != 0
    assert "streaming.md exists" in capsys.readouterr().err and not calls
    assert main(["bench", "--all", "--out", str(tmp_path), "--force"]) == 0
    assert [c[0] for c in calls] == ["problems", "problems", "streaming", "throughput",
                                     "derive", "scene", "brouwer"]
    (long, long_out, budget), (short, short_out, _) = calls[0][1], calls[1][1]
    assert sorted(short) == sorted(f"{n}_short" for n in SHORT_OF)
    assert "pendulum" in long and not set(long) & set(short) and budget == 2.0
    assert (long_out, short_out) == (tmp_path, tmp_path / "short")
    assert calls[3][1] == 10_000 and calls[5][1] == "scenes/pendulum.yaml"


def test_a_section_of_all_runs_in_a_new_process_and_its_failure_is_one_line(
        tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    """A section of `bench --all` runs in a new interpreter; one that fails ends it with
    the one line of any command and exit status 2."""
    import mechsim.cli.bench as bench_cli

    assert bench_cli._run_apart("no such section", tmp_path, {}) == 2
    err = capfd.readouterr().err
    assert "mechsim: error: bench --all: no section 'no such section'" in err
    assert "Traceback" not in err


def test_the_compiled_call_floor_does_a_whole_run() -> None:
    """The per-call floor `bench --throughput` prints beside simulate (the compiled loop with
    its arguments made once) does the run simulate does on every call, from a fresh start:
    the same steps and evaluations each time, not a continuation of the previous call."""
    import mechsim
    from mechsim.bench.throughput import TOLERANCE, _compiled_loop
    from mechsim.integrators.state import Status

    model = mechsim.load_system("pendulum")
    res = mechsim.simulate(model, 0.01, 0.01, tolerance=TOLERANCE, method="dop853")
    for prepared in _compiled_loop(model, 0.01):
        for _ in range(3):
            status, buf = prepared.run()
            rows, n_steps, n_evaluations = prepared.layout.counters(buf)[:3]
            assert (Status(status), rows, n_steps, n_evaluations) == (
                Status.OK, 2, res.n_steps, res.n_evaluations)
            assert np.array_equal(prepared.layout.rows(buf)[:, :2],
                                  np.column_stack([res.q, res.v]))


def _payloads(path: Path) -> dict[int, list[tuple[int, bytes]]]:
    """(log time, payload) of every message of an MCAP file by channel id, read with the mcap
    library's reader."""
    from mcap.reader import make_reader

    got: dict[int, list[tuple[int, bytes]]] = {}
    with open(path, "rb") as f:
        for _, ch, m in make_reader(f).iter_messages(log_time_order=False):
            got.setdefault(ch.id, []).append((m.log_time, bytes(m.data)))
    return got


def test_recording_designs_write_the_shipped_records_or_drop_only_the_chunks(
        tmp_path: Path) -> None:
    """The bench's recording designs: ``process`` writes every chunk's messages, byte for
    byte as the shipped writer does, in its child's file (and the rest in the bag);
    ``dropped`` keeps only the single messages; each design is undone after its block."""
    from mechsim.bench.recording_designs import design
    from mechsim.outputs import bag
    from mechsim.outputs.bag import mcapfile
    from mechsim.ros.record import run_with_outputs
    from mechsim.scene import single_system_scene

    scene = single_system_scene("pendulum")
    writer, level = bag.BagWriter, mcapfile.ZSTD_LEVEL
    runs = {}
    for name in ("shipped", "process", "dropped"):
        with design(name):
            runs[name], _ = run_with_outputs(scene, fast=True, duration=3.0,
                                             bag=str(tmp_path / name))
        assert (bag.BagWriter, mcapfile.ZSTD_LEVEL) == (writer, level)
    shipped = _payloads(tmp_path / "shipped" / "shipped_0.mcap")
    published = sum(runs["shipped"].messages.values())
    assert sum(map(len, shipped.values())) == published > 0
    in_bag = _payloads(tmp_path / "process" / "process_0.mcap")
    in_child = _payloads(tmp_path / "process" / "chunks.mcap")
    assert in_child and not in_bag.keys() & in_child.keys()
    assert {**in_bag, **in_child} == shipped
    dropped = _payloads(tmp_path / "dropped" / "dropped_0.mcap")
    assert dropped == in_bag  # the single messages alone
    with pytest.raises(ValueError, match="no recording design"), design("fastest"):
        pass


def test_the_runs_a_comparison_rests_on_are_timed_again_together_in_rounds() -> None:
    from mechsim.bench.paired import contested_runs, retime

    rows = [_row("mechsim:a", "mechsim", 1.6e-3, 1e-3, setting=1e-3),  # swept in a slow stretch
            _row("mechsim:a", "mechsim", 2.0e-3, 1e-5, setting=1e-4),
            _row("mechsim:a", "mechsim", 3.0e-3, 1e-3, setting=1e-2),  # dominated: off the front
            _row("mechsim:b", "mechsim", 20e-3, 1e-5, setting=1e-4),  # 10x slower: no contender
            _row("handwritten:RK4", "handwritten", 0.5e-3, 1e-3, setting=16),
            _row("handwritten:RK4", "handwritten", 1.2e-3, 8e-5, setting=32),
            _row("scipy:DOP853", "scipy", 40e-3, 1e-5, setting=1e-4)]
    runs = contested_runs(rows, [1e-4])
    assert [(r["contestant"], r["setting"]) for r in runs] == [
        ("mechsim:a", 1e-3), ("mechsim:a", 1e-4), ("handwritten:RK4", 16),
        ("handwritten:RK4", 32)]
    cost = {1e-3: 1.0e-3, 1e-4: 2.0e-3, 16: 0.5e-3, 32: 1.2e-3}  # what each run really costs
    now, order = [0.0], []

    def runner_of(r: dict[str, Any]) -> Any:
        def run() -> None:
            order.append(r["setting"])
            # every run of the third round meets a stretch twice as slow
            now[0] += cost[r["setting"]] * (2.0 if len(order) in range(29, 41) else 1.0)
        return run

    rounds = retime(runs, runner_of, clock=lambda: now[0])
    assert rounds >= 5
    timed = order[4:]  # after one warm-up run of each
    assert len(timed) == 4 * 3 * rounds
    for n in range(rounds):  # a burst of each per round, each round starting one further on
        got = timed[12 * n:12 * n + 12]
        assert got[0::3] == got[1::3] == got[2::3]
        assert sorted(got[0::3], key=str) == sorted(cost, key=str)
        assert got[0] == [1e-3, 1e-4, 16, 32][n % 4]
    for r in runs:
        assert len(r["paired_times_s"]) == rounds
        assert math.isclose(r["time_s"], cost[r["setting"]])
    assert runs[0]["sweep_time_s"] == 1.6e-3
    # at 1e-4, log-log: mechsim:a halfway between 1 and 2 ms, RK4 0.5 ms x 2.4^(ln 10/ln 12.5)
    peer, mine = 0.5e-3 * 2.4 ** (math.log(10.0) / math.log(12.5)), math.sqrt(2e-6)
    assert math.isclose(matched(rows)["1e-04"]["speedup_vs_peer"], peer / mine)
    assert retime([], runner_of) == 0


def test_calls_are_timed_in_rounds_and_each_gets_its_fastest_run(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """``throughput.best_in_rounds``: each call once a round, each round starting one call
    further on; a slow stretch met by one round leaves every call's fastest run as it was."""
    from mechsim.bench import throughput

    now, order = [0.0], []
    cost = {"two cores": 1.0, "one core": 1.9, "auto": 4.0}

    def call(name: str) -> None:
        order.append(name)
        slow = 2.0 if len(order) <= 3 else 1.0  # the host is slow for the first round
        now[0] += cost[name] * slow

    monkeypatch.setattr(throughput.time, "perf_counter", lambda: now[0])
    best = throughput.best_in_rounds({n: functools.partial(call, n) for n in cost}, 4)
    assert order == ["two cores", "one core", "auto", "one core", "auto", "two cores",
                     "auto", "two cores", "one core", "two cores", "one core", "auto"]
    assert best.keys() == cost.keys()
    assert all(math.isclose(best[n], cost[n]) for n in cost)
    assert throughput.best_in_rounds({"x": functools.partial(call, "auto")}, 0) == {
        "x": math.inf}


def test_the_recordings_of_the_systems_are_made_in_rounds(monkeypatch: pytest.MonkeyPatch
                                                           ) -> None:
    """Every system warmed up once, then recorded once a round; each row: its fastest
    recording, the median and every recording's figure in the order made."""
    import mechsim.ros.record
    import mechsim.scene
    from mechsim.bench import streaming

    made: list[str] = []
    figures = {"a": [900.0, 1200.0, 1000.0], "b": [2000.0, 1500.0, 1800.0]}

    def warm_up(scene: str, fast: bool, duration: float, bag: str) -> None:
        made.append(f"warm {scene}")
        os.mkdir(bag)

    def record(scene: str, duration: float, bag: str) -> dict[str, Any]:
        os.mkdir(bag)
        made.append(scene)
        rtf = figures[scene][made.count(scene) - 1]
        return {"rtf": rtf, "reference_ms": rtf / 1000.0, "us_per_sample": 1e4 / rtf}

    monkeypatch.setattr(mechsim.scene, "single_system_scene", lambda s: s)
    monkeypatch.setattr(mechsim.ros.record, "run_with_outputs", warm_up)
    monkeypatch.setattr(streaming, "_record", record)
    rows = streaming.recordings_in_rounds(["a", "b"], 10.0, 3)
    assert made == ["warm a", "warm b", "a", "b", "a", "b", "a", "b"]
    assert [r["system"] for r in rows] == ["a", "b"]
    for row, runs in zip(rows, figures.values(), strict=True):
        assert row["runs"] == runs and row["reference_ms"] == [x / 1000.0 for x in runs]
        assert row["rtf"] == max(runs) and row["us_per_sample"] == 1e4 / max(runs)
        assert row["median_rtf"] == sorted(runs)[1]


def test_a_systems_recording_figure_is_its_fastest_recording_with_every_one_beside_it() -> None:
    from mechsim.bench.streaming import recording_rtf
    from mechsim.bench.streaming_report import _recording_lines

    row = recording_rtf("pendulum", 20.0, repeats=2)
    assert len(row["runs"]) == len(row["reference_ms"]) == 2
    assert row["rtf"] == max(row["runs"]) and min(row["runs"]) <= row["median_rtf"] <= row["rtf"]
    assert all(r > 0.0 for r in row["reference_ms"]) and row["messages"] > 0
    lines = _recording_lines({"recording": [row]}, 20.0)
    cells = next(line for line in lines if line.startswith("| pendulum |")).split(" | ")
    assert cells[1] == f"{row['rtf']:.0f}" and f"{row['median_rtf']:.0f} (" in cells[2]
