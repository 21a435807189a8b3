"""`mechsim figures`: the quick set written as PNG files with an index, the numbers behind three
figures against closed forms computed here, existing files refused without --force, one-line
errors for bad input; the committed gallery page shows every figure."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import mpmath
import pytest

from mechsim.figures import FIGURES, select

ROOT = Path(__file__).resolve().parent.parent
PNG = b"\x89PNG\r\n\x1a\n"


def _figures(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "mechsim.cli", "figures", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def quick(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict, str]:
    out = tmp_path_factory.mktemp("figures") / "out"
    r = _figures("--out", str(out), "--quick", cwd=out.parent)
    assert r.returncode == 0, r.stderr
    index = {e["name"]: e for e in json.loads((out / "figures.json").read_text())}
    return out, index, r.stderr


def test_quick_set_is_written(quick: tuple[Path, dict, str]) -> None:
    out, index, log = quick
    names = [s.name for s in select(None, quick=True)]
    assert len(names) >= 5 and list(index) == names
    for i, name in enumerate(names, 1):
        data = (out / f"{name}.png").read_bytes()
        assert data.startswith(PNG) and len(data) > 10_000, name
        assert index[name]["bytes"] == len(data)
        assert f"[{i}/{len(names)}] {name}:" in log  # a progress line per figure
        assert index[name]["caption"]  # names its document
        assert any(t in index[name]["caption"] for t in ("PHYS0500", "“", "Introduction"))


def test_numbers_behind_three_figures_match_closed_forms(quick: tuple[Path, dict, str]) -> None:
    _, index, _ = quick
    # the pendulum's period measured on an integrated run: 4√(R/g) K(sin²(φ₀/2)) (mpmath)
    n = index["pendulum_small_angle"]["numbers"]
    mpmath.mp.dps = 30
    exact = float(4 * mpmath.sqrt(1 / 9.81) * mpmath.ellipk(mpmath.sin(n["amplitude_rad"] / 2)
                                                            ** 2))
    assert n["measured_period_s"] == pytest.approx(exact, rel=1e-7)
    # the resonance sweep: D = A/√((ω₀² − ω²)² + 4ω²β²), ⟨T⟩ = (mA²/4)ω²/(…), PHYS0500 §1.5
    n = index["resonance_curves"]["numbers"]
    w, w0, beta, A, m = n["sweep_omega"], 2.0, n["b"] / 2, 1.0, 1.0
    den = (w0**2 - w**2) ** 2 + 4 * w**2 * beta**2
    assert n["sweep_amplitude_m"] == pytest.approx(A / math.sqrt(den), rel=1e-7)
    assert n["sweep_kinetic_J"] == pytest.approx(m * A * A / 4 * w * w / den, rel=1e-7)
    assert n["omega_R"] == pytest.approx(math.sqrt(w0**2 - 2 * beta**2), rel=1e-14)
    # the twisted cubic at t = 1: |ω_VBN| = √33/7, |ω_RIC| = 1 (closed forms of the frames)
    n = index["twisted_cubic_frames"]["numbers"]
    assert n["t_s"] == pytest.approx(1.0, abs=1e-9)
    assert n["vbn_speed_at_1"] == pytest.approx(math.sqrt(33) / 7, rel=1e-8)
    assert n["ric_speed_at_1"] == pytest.approx(1.0, rel=1e-8)


def test_existing_files_are_not_overwritten(quick: tuple[Path, dict, str]) -> None:
    out, index, _ = quick
    target = out / "pendulum_multipliers.png"
    before = target.read_bytes()
    r = _figures("--out", str(out), "--only", "pendulum_multipliers", cwd=out.parent)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0 and "use --force" in r.stderr
    assert target.read_bytes() == before
    r = _figures("--out", str(out), "--only", "pendulum_multipliers", "--force",
                 cwd=out.parent)
    assert r.returncode == 0, r.stderr
    assert target.read_bytes().startswith(PNG)


def test_bad_input_is_one_line(tmp_path: Path) -> None:
    r = _figures("--out", str(tmp_path), "--only", "pendulum_multiplier", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1
    assert "did you mean 'pendulum_multipliers'" in r.stderr
    blocker = tmp_path / "file"
    blocker.write_text("x")
    r = _figures("--out", str(blocker), "--only", "damped_regimes", cwd=tmp_path)
    assert r.returncode == 2 and "is not a directory" in r.stderr and r.stderr.count("\n") == 1
    r = _figures(cwd=tmp_path)
    assert r.returncode == 2 and "--out" in r.stderr
    r = _figures("--list", cwd=tmp_path)
    assert r.returncode == 0 and all(s.name in r.stdout for s in FIGURES)


def test_gallery_page_shows_every_figure() -> None:
    page = (ROOT / "docs" / "gallery.md").read_text()
    index = json.loads((ROOT / "docs" / "gallery" / "figures.json").read_text())
    assert [e["name"] for e in index] == [s.name for s in FIGURES]
    for e in index:
        assert f"(gallery/{e['file']})" in page
        assert (ROOT / "docs" / "gallery" / e["file"]).read_bytes().startswith(PNG)
        assert e["caption"] in page
