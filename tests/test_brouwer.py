"""Brouwer's law for ``radau15`` on a short run (the 10⁷-step figure: ``mechsim bench
--brouwer``): over N steps its energy error grows like √N (the random walk of round-off),
not like N (a bias). The energy comes from the state in closed form, E = μ|v|²/2 − μGM/|r| in
40 digits (``mechsim.bench.brouwer.kepler_energy``, checked against the vis-viva value here),
not from the model's kernels nor the integrator. The slope check is shown to fail on two
biased integrations: DOP853's truncation drift and radau15 with a one-sided rounding."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import mechsim
from mechsim.bench.brouwer import energy_walks, fit_slope, kepler_energy
from mechsim.cli import main

#: The check: slope of log(RMS relative energy error) against log(N) (√N: 0.5, drift: 1).
MAX_SLOPE = 0.6


def _slope_and_rms(n_steps: int, runs: int, **kw: object) -> tuple[float, float]:
    w = energy_walks(n_steps, runs, **kw)  # type: ignore[arg-type]
    rms = w.rms()
    return fit_slope(w.mean_steps(), rms), float(rms[-1])


@pytest.mark.parametrize("e", [0.0, 0.5, 0.9])
def test_energy_is_vis_viva(e: float) -> None:
    """At pericentre of an orbit of a = GM = μ = 1, E = −μGM/(2a) = −½ for every e."""
    y = mechsim.load_system("kepler", eccentricity=e).initial_y()
    assert abs(float(kepler_energy(y)) + 0.5) < 4e-16


def test_radau15_energy_error_grows_like_sqrt_n() -> None:
    """48 perturbed Kepler orbits (e = 0.5), 10⁵ steps each: the RMS energy error rises
    from round-off with slope ½ (measured 0.44–0.54 over six sets of perturbations, 0.455 for
    this one; 24 runs spread it to 0.41–0.58), about 2e-17 per √step."""
    slope, rms = _slope_and_rms(100_000, 48)
    assert 0.3 <= slope <= MAX_SLOPE, slope
    assert rms < 3e-14, rms  # 10⁵ steps: ~6e-15 measured


@pytest.mark.parametrize("tolerance", [1e-8, 1e-10])
def test_the_check_fails_on_truncation_drift(tolerance: float) -> None:
    """DOP853 is not symplectic: its truncation error drifts the energy one way, and the same
    check sees slope ≈ 1."""
    slope, _ = _slope_and_rms(100_000, 4, method="dop853", tolerance=tolerance)
    assert slope > 0.9 > MAX_SLOPE, slope


def test_the_check_fails_on_biased_rounding() -> None:
    """radau15 with the velocity rounded one ulp away from zero after every step (a rounding
    that always leans one way): slope ≈ 1."""
    slope, rms = _slope_and_rms(20_000, 2, rounding_up=True)
    assert slope > 0.9 > MAX_SLOPE, slope
    assert rms > 1e-12, rms


def test_fit_slope_of_power_laws() -> None:
    n = np.geomspace(10, 1e6, 30)
    assert fit_slope(n, 3e-17 * np.sqrt(n)) == pytest.approx(0.5, abs=1e-12)
    assert fit_slope(n, 1e-16 * n) == pytest.approx(1.0, abs=1e-12)
    with pytest.raises(ValueError):
        fit_slope(n[:5], n[:5])


def test_bench_brouwer_writes_figure_and_data(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    """``mechsim bench --brouwer``: every sample of every run in brouwer.json, the figure,
    and a slope line; bad sizes are one-line errors naming the option."""
    assert main(["bench", "--brouwer", "--steps", "20000", "--runs", "3",
                 "--out", str(tmp_path)]) == 0
    res = json.loads((tmp_path / "brouwer.json").read_text())
    assert len(res["errors"]) == 3 and len(res["errors"][0]) == len(res["times"])
    assert res["mean_steps"][-1] > 15000 and 0.0 < res["slope"] < 1.5
    assert (tmp_path / "brouwer.png").stat().st_size > 10_000
    assert "fitted slope" in capsys.readouterr().out
    for args, field in ((["--steps", "5"], "--steps"), (["--runs", "1"], "--runs"),
                        (["kepler"], "--brouwer")):
        assert main(["bench", "--brouwer", *args, "--out", str(tmp_path)]) == 2
        err = capsys.readouterr().err.strip()
        assert field in err and len(err.splitlines()) == 1, err
