"""``mechsim bench``: sanity of the harness (schema, errors shrink with tolerance, missing peers
reported). No wall-clock thresholds: timings are not asserted, only present."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mechsim.bench import peers, problems
from mechsim.bench.run import error_at, pareto, time_at
from mechsim.cli import main

TOP_KEYS = {"schema", "created", "quick", "host", "settings", "peers", "systems", "targets"}
SYSTEM_KEYS = {"problem", "compile", "runs", "matched"}
RUN_KEYS = {"contestant", "family", "knob", "setting", "status", "time_s", "times_s",
            "warmup_s", "repeats", "end_error", "max_error", "invariant_error", "n_steps",
            "n_rhs"}


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
        assert {r["family"] for r in s["runs"]} == {"mechsim", "scipy"}  # --quick: scipy only
    md = (out / "results.md").read_text()
    assert "## Summary" in md and "## pendulum" in md


def test_dop853_error_decreases_with_tolerance(quick_run: tuple[dict, Path, str]) -> None:
    res, _, _ = quick_run
    for sid, s in res["systems"].items():
        runs = sorted((r for r in s["runs"] if r["contestant"] == "mechsim:dop853"),
                      key=lambda r: -r["setting"])
        errs = [r["end_error"] for r in runs if r["status"] == "ok"]
        assert len(errs) == 3, sid
        assert errs[0] > errs[1] > errs[2], (sid, errs)
        assert errs[-1] < 1e-7, (sid, errs)


def test_compositions_not_applicable_to_driven(quick_run: tuple[dict, Path, str]) -> None:
    res, _, _ = quick_run
    runs = [r for r in res["systems"]["driven_oscillator"]["runs"]
            if r["contestant"] == "mechsim:yoshida8"]
    assert runs and all(r["status"].startswith("n/a") for r in runs)


def test_missing_peer_reported(quick_run: tuple[dict, Path, str]) -> None:
    res, _, stdout = quick_run
    assert "mujoco" in res["peers"]["missing"]
    assert stdout.count("peer mujoco missing") == 1


@pytest.mark.parametrize("system", ["pendulum", "kepler", "driven_oscillator",
                                    "harmonic_oscillator", "double_pendulum"])
def test_reference_matches_tight_scipy(system: str) -> None:
    """The closed-form references (Radau at 1e-14 for the double pendulum) agree with a tight
    DOP853 run of the bench's numpy RHS."""
    pb = problems.problem(system, quick=True)
    t = pb.times()
    sol = solve_ivp(pb.rhs, (0, pb.t_end), pb.y0, method="DOP853", t_eval=t, rtol=1e-13,
                    atol=1e-13)
    assert np.allclose(pb.reference_states()[0], pb.y0, rtol=0, atol=1e-14)
    assert pb.errors(sol.y.T)["max_error"] < 1e-10


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


def test_double_pendulum_rhs_matches_mechsim() -> None:
    """The bench's hand-written RHS and mechsim's generated kernels describe the same system."""
    from mechsim.integrators import make_stepper
    from mechsim.systems import load_system

    pb = problems.problem("double_pendulum", quick=True)
    model = load_system(pb.system, **pb.params)
    q0, v0 = model.initial_state()
    assert np.allclose(np.concatenate([q0, v0]), pb.y0)
    Y = make_stepper(model, "dop853", 1e-12).advance(pb.times())[:, :4]
    assert pb.errors(Y)["max_error"] < 1e-9


def test_double_pendulum_reference_vs_double_precision() -> None:
    """The extended-precision reference agrees with scipy Radau and DOP853 at 1e-14."""
    import warnings

    pb = problems.problem("double_pendulum", quick=True)
    for method in ("Radau", "DOP853"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sol = solve_ivp(pb.rhs, (0, pb.t_end), pb.y0, method=method, t_eval=pb.times(),
                            rtol=1e-14, atol=1e-14)
        assert pb.errors(sol.y.T)["max_error"] < 1e-11, method
