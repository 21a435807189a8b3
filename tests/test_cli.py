"""The mechsim command as a user runs it: one-line errors and exit status 2 on bad input,
never a traceback; `systems --json`; a short run prints the conservation table; every range
the CLI or a scene accepts is accepted by the nodes too (one definition of each range)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from mechsim.cli import NODE_VERBS

MECHSIM = [sys.executable, "-m", "mechsim.cli"]


def run(args: list[str], env: dict[str, str], timeout: float = 120,
        cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([*MECHSIM, *args], env=env, capture_output=True, text=True,
                          timeout=timeout, cwd=cwd)


@pytest.mark.parametrize("args, expected", [
    (["run", "nosuch"], "unknown system 'nosuch'"),
    (["run", "pendulum", "--set", "mass=-1"], "mass: must be > 0"),
    (["run", "pendulum", "--set", "mass=nan"], "mass: must be finite"),
    (["run", "pendulum", "--set", "lenght=2"], "not a parameter"),
    # Did you mean: the close name, then every valid one.
    (["run", "pendlum"], "unknown system 'pendlum': did you mean 'pendulum'? (known: atwood,"),
    (["systems", "keplr"], "did you mean 'kepler'?"),
    (["run", "pendulum", "--set", "lenght=2"], "did you mean 'length'? (names: "),
    (["run", "pendulum", "--set", "method=dop85"], "did you mean 'dop853'? (methods: "),
    (["run", "pendulum", "--set", "pendulm:mass=2"],
     "no instance 'pendulm' in the scene: did you mean 'pendulum'? (instances: pendulum)"),
    (["run", "pendulum", "--set", "pendulum:publish_rate=5"], "a setting of the whole scene"),
    (["run", "pendulum", "--set", "formulation=x"], "formulation: must be one of"),
    (["run", "kepler", "--set", "eccentricity=1.5"], "eccentricity: must be < 1"),
    (["run", "missing_scene.yaml"], "cannot read"),
    (["run", "pendulum", "--duration", "-1"], "--duration: must be > 0"),
    (["run", "pendulum", "--duration", "0"], "--duration: must be > 0"),
    (["run", "pendulum", "--duration", "nan"], "--duration: must be finite"),
    (["run", "pendulum", "--duration", "1e300"], "--duration: must be <= 1e+09"),
    (["record", "pendulum", "--duration", "inf"], "--duration: must be finite"),
    (["run", "pendulum", "--publish-rate", "0"], "--publish-rate: must be >= 0.01"),
    (["record", "pendulum", "--duration", "1", "--publish-rate", "1e7"],
     "--publish-rate: must be <= 10000"),
    (["run", "pendulum", "--set", "mass=" + "9" * 400], "mass: out of range"),
    (["run", "pendulum", "--name", "p\n"], "--name: must be a ROS name"),
    (["run", "pendulum", "--name", "p" * 300], "--name: must be a ROS name"),
    (["run", "pendulum", "--name", "../x"], "--name: must be a ROS name"),
    (["record", "pendulum", "--duration", "1", "--bag", "runs/a\x01b"],
     "--bag: contains the control character"),
])
def test_bad_input_is_one_line(args: list[str], expected: str, ros_env: dict[str, str]) -> None:
    r = run(args, ros_env)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("mechsim: error:") and expected in lines[0]


@pytest.mark.parametrize("text, expected", [
    ("systems: [\n  - system: pendulum\n  bad", "not valid YAML"),
    ("systems:\n  - system: pendulum\n    colour: red\n", "systems[0].colour: unknown key"),
    ("sytems:\n  - system: pendulum\n", "sytems: unknown key: did you mean 'systems'?"),
    ("systems:\n  - system: pendulum\n    methd: dop853\n",
     "systems[0].methd: unknown key: did you mean 'method'?"),
    ("systems: []\n", "systems: must be a non-empty list"),
    ("pacing: warp\nsystems:\n  - system: pendulum\n", "pacing: must be realtime or fast"),
    ("systems:\n  - {system: pendulum}\n  - {system: pendulum}\n", "used twice"),
    ("systems:\n  - {system: pendulum, parameters: {length: -2}}\n",
     "systems[0].parameters.length: must be > 0"),
    # Accepted by scenes before, then refused by the node's ROS ranges with a traceback:
    ("systems:\n  - {system: pendulum, tolerance: 1.0e-16}\n",
     "systems[0].tolerance: must be >= 1e-15"),
    ("publish_rate: 20000.0\nsystems:\n  - {system: pendulum}\n",
     "publish_rate: must be <= 10000"),
    ("real_time_factor: 2.0e+6\nsystems:\n  - {system: pendulum}\n",
     "real_time_factor: must be <= 1e+06"),
    ("diagnostics: {warn_drift: 0.5, error_drift: 2.0}\nsystems:\n  - {system: pendulum}\n",
     "diagnostics.error_drift: must be <= 1"),
    ("duration: " + "9" * 400 + "\nsystems:\n  - {system: pendulum}\n",
     "duration: out of range"),
    ("name: ../../../tmp/x\nsystems:\n  - {system: pendulum}\n", "name: must be letters"),
    ("systems:\n  - {system: pendulum, name: " + "p" * 300 + "}\n",
     "systems[0].name: must be a ROS name"),
])
def test_bad_scene_is_one_line(text: str, expected: str, tmp_path: Path,
                               ros_env: dict[str, str]) -> None:
    scene = tmp_path / "bad.yaml"
    scene.write_text(text)
    r = run(["run", str(scene)], ros_env)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert expected in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_scene_file_not_utf8_is_one_line(tmp_path: Path, ros_env: dict[str, str]) -> None:
    scene = tmp_path / "latin1.yaml"
    scene.write_bytes("name: caf\xe9\nsystems:\n  - {system: pendulum}\n".encode("latin-1"))
    r = run(["run", str(scene)], ros_env)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "not UTF-8" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_every_accepted_range_edge_runs(tmp_path: Path, ros_env: dict[str, str]) -> None:
    """The edges of every range a scene and the CLI accept start nodes without a complaint
    and record a complete bag (before: some were refused by the node's own ROS ranges after
    the bag was created, leaving an empty bag and a traceback)."""
    import yaml

    scene = tmp_path / "edges.yaml"
    scene.write_text(yaml.safe_dump({
        "name": "edges", "pacing": "realtime", "real_time_factor": 1.0e6,
        "publish_rate": 10000.0, "diagnostics": {"warn_drift": 0.5, "error_drift": 1.0},
        "systems": [{"system": "harmonic_oscillator", "name": "tight", "tolerance": 1e-15},
                    {"system": "kepler", "name": "loose", "tolerance": 0.99,
                     "method": "dop853"}]}))
    r = run(["record", str(scene), "--duration", "0.01", "--bag", str(tmp_path / "bag")],
            ros_env)
    assert r.returncode in (0, 1), r.stderr  # 1: the loose tolerance may fail its system
    assert "Traceback" not in r.stderr
    assert (tmp_path / "bag" / "metadata.yaml").exists()
    slow = run(["run", "kepler", "--publish-rate", "0.01", "--duration", "100", "--fast"], ros_env)
    assert slow.returncode == 0, slow.stderr


def test_run_system_with_a_name(ros_env: dict[str, str], tmp_path: Path) -> None:
    """`mechsim run SYSTEM --name NS` names the instance: its topics live under /NS."""
    from rosbags.highlevel import AnyReader

    r = run(["run", "pendulum", "--name", "left", "--fast", "--duration", "0.5", "--bag",
             str(tmp_path / "bag")], ros_env)
    assert r.returncode == 0, r.stderr
    assert "  left " in r.stdout
    with AnyReader([tmp_path / "bag"]) as reader:
        topics = {c.topic for c in reader.connections}
    assert "/left/state" in topics and not any(t.startswith("/pendulum/") for t in topics)


def test_systems_json(ros_env: dict[str, str]) -> None:
    r = run(["systems", "--json"], ros_env, timeout=300)
    assert r.returncode == 0, r.stderr
    data = {d["id"]: d for d in json.loads(r.stdout)}
    assert {"pendulum", "driven_oscillator", "kepler"} <= set(data)
    pend = data["pendulum"]
    assert "Part 3 – Simple Pendulum" in pend["source"]
    names = {p["name"]: p for p in pend["parameters"]}
    assert names["mass"]["unit"] == "kg" and names["initial.angle"]["unit"] == "rad"
    assert data["kepler"]["laws"][:1] == ["energy"]


def test_short_run_prints_conservation_table(ros_env: dict[str, str]) -> None:
    r = run(["run", "pendulum", "--fast", "--duration", "2"], ros_env)
    assert r.returncode == 0, r.stderr
    assert "Conservation results" in r.stdout
    assert "pendulum" in r.stdout and "energy" in r.stdout and "OK" in r.stdout


def test_output_into_a_closed_pipe_is_quiet(ros_env: dict[str, str]) -> None:
    proc = subprocess.Popen([*MECHSIM, "systems"], env=ros_env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    proc.stdout.readline()
    proc.stdout.close()  # like `mechsim systems | head -1`
    _, err = proc.communicate(timeout=120)
    assert "Traceback" not in err and proc.returncode == 0


@pytest.mark.parametrize("args", [["run", "pendulum"], ["run", "pendulum", "--processes"],
                                  ["record", "pendulum"]])
def test_bad_discovery_window_is_one_line(args: list[str], ros_env: dict[str, str],
                                          tmp_path: Path) -> None:
    r = run([*args, "--duration", "0.1"], dict(ros_env, MECHSIM_GRAPH_WAIT="soon"),
            cwd=tmp_path)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("mechsim: error: MECHSIM_GRAPH_WAIT:"), lines


def _options(parser: Any, path: str = "") -> list[tuple[str, str]]:
    """(verb path, option) of every option a user can give, sub-commands included."""
    import argparse

    found = []
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                if name not in NODE_VERBS:
                    found.append((path, name))
                    found += _options(sub, f"{path} {name}".strip())
        elif action.help != argparse.SUPPRESS and action.option_strings:
            found += [(path, o) for o in action.option_strings if o.startswith("--")
                      and o != "--help"]
    return found


def test_the_command_reference_names_every_verb_and_option() -> None:
    """docs/cli.md is the reference of every verb and option the parser has."""
    from pathlib import Path

    from mechsim.cli import build_parser

    text = (Path(__file__).resolve().parents[1] / "docs" / "cli.md").read_text()

    def named(path: str, name: str) -> bool:
        if name.startswith("--"):  # an option, as a whole word
            return re.search(rf"(?<![\w-]){re.escape(name)}(?![\w-])", text) is not None
        # a verb ("mechsim run") or sub-command ("bag info", "cache info|clear")
        verb = f"mechsim {path} {name}".replace("  ", " ") if path else f"mechsim {name}"
        return verb in text or re.search(rf"mechsim {path} [\w|\\]*\b{name}\b", text) \
            is not None

    missing = [f"{path} {name}".strip() for path, name in _options(build_parser())
               if not named(path, name)]
    assert not missing, f"docs/cli.md does not mention: {missing}"


def test_version_and_verb_suggestions() -> None:
    from mechsim import __version__

    r = subprocess.run([*MECHSIM, "--version"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.strip() == f"mechsim {__version__}"
    r = subprocess.run([*MECHSIM, "rn"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2
    assert "invalid choice: 'rn': did you mean 'run'? (choose from: bag," in r.stderr
    assert "simulator" not in r.stderr.splitlines()[-1]  # the node processes' verbs stay unlisted


def test_counts_and_the_deprecated_rate(ros_env: dict[str, str]) -> None:
    """One system is "1 system"; `run --rate` still works, with a warning naming the option
    that replaced it (in replay --rate is the speed factor)."""
    r = run(["run", "pendulum", "--fast", "--duration", "0.1", "--rate", "20"], ros_env)
    assert r.returncode == 0, r.stderr
    assert "(1 system, as fast as possible" in r.stderr
    warning = [ln for ln in r.stderr.splitlines() if "deprecated" in ln]
    assert len(warning) == 1 and "--publish-rate" in warning[0], r.stderr
    assert "0.1 s simulated" in r.stdout
    r = run(["run", "pendulum", "--rate", "20", "--publish-rate", "20"], ros_env)
    assert r.returncode == 2 and "--rate: not with --publish-rate" in r.stderr
