"""``mechsim stress --quick`` in-process, its pass criteria asserted, plus the DOP853
stiffness test (the integrator side of the stiffness case)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import mechsim
from mechsim.errors import IntegrationError
from mechsim.integrators import StiffnessError, make_stepper


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    from mechsim.cli import main

    out = tmp_path_factory.mktemp("stress")
    assert main(["stress", "--quick", "--out", str(out)]) == 0
    data = json.loads((out / "stress.json").read_text())
    data["_dir"] = str(out)
    return data


def _results(report: dict[str, Any], case: str) -> list[dict[str, Any]]:
    return [r for r in report["results"] if r["case"] == case]


def test_quick_catalogue_passes_and_reports(report: dict[str, Any]) -> None:
    s = report["summary"]
    assert s["failed"] == 0, [r["outcome"] for r in report["results"] if not r["passed"]]
    assert set(s["cases"]) == {"long_horizon", "chaos", "stiffness", "singular", "sweeps",
                               "hamilton"}
    out = Path(report["_dir"])
    md = (out / "stress.md").read_text()
    assert "## long_horizon" in md and "**FAIL**" not in md
    for png in ("long_horizon_drift.png", "chaos.png", "sweeps.png", "hamilton.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", png
        assert f"]({png})" in md


def test_long_horizons(report: dict[str, Any]) -> None:
    rs = _results(report, "long_horizon")
    assert {r["system"] for r in rs} >= {"pendulum", "kepler", "double_pendulum"}
    for r in rs:
        m = r["metrics"]
        assert r["passed"], r
        assert m["steps"] >= 100_000 or m["periods"] >= 0.99e5, m  # 10⁵ steps or time scales
        if m["method"] == "yoshida8":  # symplectic: bounded, tiny
            assert m["worst_drift"] < 1e-9
        else:  # DOP853: at most ~linear growth
            assert m.get("growth_exponent", 0.0) <= 1.5 and m["worst_drift"] < 1e-5


def test_chaos(report: dict[str, Any]) -> None:
    rs = {r["system"]: r["metrics"] for r in _results(report, "chaos")}
    assert set(rs) == {"double_pendulum", "cr3bp"}
    for m in rs.values():
        assert m["lyapunov_exponent"] > 0.05
        assert m["t_diverge_tolerances"] < m["horizon"]
        assert m["drift_tol_1e-13"] < 1e-7
    # Tolerance 1e-10 vs 1e-13 differ by ~1e-10 at first: parting takes ~ln(1e8)/λ.
    dp = rs["double_pendulum"]
    assert dp["t_diverge_tolerances"] > 0.5 * math.log(1e8) / dp["lyapunov_exponent"]


def test_stiffness_reported(report: dict[str, Any]) -> None:
    rs = _results(report, "stiffness")
    damped = next(r for r in rs if r["system"] == "damped_oscillator")
    assert damped["passed"] and "StiffnessError" in damped["metrics"]["error"]
    assert "damped_oscillator" in damped["metrics"]["error"]


def test_singular_cases(report: dict[str, Any]) -> None:
    rs = _results(report, "singular")
    assert {r["system"] for r in rs} >= {"pendulum", "kepler", "moving_frames", "bead_on_wire"}
    assert all(r["passed"] for r in rs)
    kep = [r for r in rs if r["system"] == "kepler" and "dop853" in r["variant"]
           and "worst_drift" in r["metrics"]]
    assert kep and all(r["metrics"]["worst_drift"] < 1e-6 for r in kep)


def test_sweeps_flag_garbage(report: dict[str, Any]) -> None:
    for r in _results(report, "sweeps"):
        pts = r["metrics"]["points"]
        assert r["metrics"]["silent_garbage"] == 0
        assert any(p["garbage"] for p in pts), "the sweep must reach garbage"
        assert any(p.get("level") == "OK" for p in pts), "and accurate settings"
        for p in pts:
            if p["garbage"]:
                assert p["level"] in ("WARN", "ERROR", "ERROR (guard)"), p


def test_hamilton_principle(report: dict[str, Any]) -> None:
    rs = [r for r in _results(report, "hamilton") if r["metrics"]["applicable"]]
    assert len(rs) >= 4
    for r in rs:
        assert 1.8 <= r["metrics"]["slope"] <= 2.2, r
        assert r["metrics"]["control_slope"] <= 1.3, r


def test_stress_rejects_unknown_system(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                       ) -> None:
    from mechsim.cli import main

    assert main(["stress", "no_such_system", "--quick", "--out", str(tmp_path)]) == 2
    assert "unknown system 'no_such_system'" in capsys.readouterr().err


# --- the integrator's stiffness test ---------------------------------------------------------
def test_stiff_damping_stops_with_reason() -> None:
    model = mechsim.load_system("damped_oscillator", damping=1e6)
    stepper = make_stepper(model, "auto")
    with pytest.raises(StiffnessError) as e:
        stepper.advance(np.arange(1, 1001) * 0.01)
    msg = str(e.value)
    assert isinstance(e.value, IntegrationError)
    assert "damped_oscillator" in msg and "stiff" in msg and "publish rate" in msg
    assert stepper.n_steps < 5000  # detected early, not after crawling
    assert np.all(np.isfinite(stepper.y))


def test_stiff_but_cheap_phases_go_on() -> None:
    """A damped oscillator settled at rest is stiff by Hairer's test but takes big steps: it
    must go on (no false stop on long runs), and the overdamped k = 1e8, b = 1e5 case (under
    1000 steps per output) finishes."""
    run = mechsim.simulate(mechsim.load_system("damped_oscillator"), 40_000.0, 10.0)
    assert run.t[-1] == 40_000.0 and abs(run.q[-1, 0]) < 1e-9
    model = mechsim.load_system("damped_oscillator", spring_constant=1e8, damping=1e5)
    run = mechsim.simulate(model, 1.0, 0.01)
    assert np.all(np.isfinite(run.q))


def test_non_stiff_runs_never_trip() -> None:
    for sid, kw in [("pendulum", {"formulation": "multiplier"}), ("kepler",
                    {"eccentricity": 0.9}), ("double_pendulum", {})]:
        st = make_stepper(mechsim.load_system(sid, **kw), "dop853")
        st.advance(np.linspace(0.01, 50.0, 5000))
        assert st.st[10] < 15
