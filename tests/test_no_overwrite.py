"""No output is replaced without ``--force``: an .rrd (``run``/``record --rrd``, ``convert``)
is refused before the run starts when it exists and replaced, once the new one is complete,
only with ``--force``; a bag directory with content is never replaced; the report files of
``bench``/``stress --out`` are refused the same way. What was there is left untouched."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

MECHSIM = [sys.executable, "-m", "mechsim.cli"]


def _cli(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*MECHSIM, *args], env=env, capture_output=True, text=True,
                          timeout=300)


@pytest.mark.parametrize("verb", ["run", "record"])
def test_rrd_replaced_only_with_force(verb: str, ros_env: dict[str, str],
                                      tmp_path: Path) -> None:
    rrd = tmp_path / "run.rrd"
    rrd.write_bytes(b"a recording the user keeps")
    args = [verb, "pendulum", "--duration", "0.5", "--rrd", str(rrd), "--bag",
            str(tmp_path / "bag")]
    r = _cli(args, ros_env)
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip().splitlines()[-1] == (
        f"mechsim: error: --rrd: {rrd} exists (add --force to replace it)")
    assert rrd.read_bytes() == b"a recording the user keeps"
    assert not (tmp_path / "bag").exists()  # refused before anything started
    r = _cli([*args, "--force"], ros_env)
    assert r.returncode == 0, r.stderr
    assert rrd.read_bytes()[:4] != b"a re" and rrd.stat().st_size > 1000


@pytest.mark.parametrize("verb", ["run", "record"])
def test_bag_with_content_is_never_replaced(verb: str, ros_env: dict[str, str],
                                            tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "notes.txt").write_text("mine")
    for force in ([], ["--force"]):
        r = _cli([verb, "pendulum", "--duration", "0.5", "--bag", str(bag), *force], ros_env)
        assert r.returncode == 2, r.stderr
        last = r.stderr.strip().splitlines()[-1]
        assert last.startswith(f"mechsim: error: --bag: {bag} exists and is not empty"), last
    assert [p.name for p in bag.iterdir()] == ["notes.txt"]


def test_scene_outputs_are_checked_too(ros_env: dict[str, str], tmp_path: Path) -> None:
    rrd = tmp_path / "scene.rrd"
    rrd.write_text("keep")
    scene = tmp_path / "s.yaml"
    scene.write_text(f"systems: [{{system: pendulum}}]\noutputs: {{rrd: {rrd}}}\n")
    r = _cli(["run", str(scene), "--duration", "0.5", "--fast"], ros_env)
    assert r.returncode == 2 and "--rrd" in r.stderr and "exists" in r.stderr, r.stderr
    assert rrd.read_text() == "keep"


@pytest.mark.parametrize("args, existing", [
    (["stress", "--quick", "--case", "sweeps", "harmonic_oscillator"], "stress.md"),
    (["stress", "--quick", "--case", "sweeps", "harmonic_oscillator"], "sweeps.png"),
    (["bench", "--derive", "pendulum"], "derive.json"),
    (["bench", "--quick", "pendulum"], "pendulum.png"),
])
def test_report_files_replaced_only_with_force(args: list[str], existing: str,
                                               tmp_path: Path) -> None:
    (tmp_path / existing).write_text("keep")
    r = _cli([*args, "--out", str(tmp_path)], {})
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip() == (f"mechsim: error: --out: {tmp_path / existing} exists (add "
                                "--force to replace what this command writes there)")
    assert (tmp_path / existing).read_text() == "keep"
