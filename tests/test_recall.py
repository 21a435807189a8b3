"""A Lagrangian model derived before is set up from its recalled summary, without sympy: the
recalled model is the declared one (shape, structure, laws, kernels), the summary is keyed on
every input of the declaration (a changed parameter, another formulation, a class outside
mechsim are never recalled from something else), an unreadable summary is made again, and a
warm process runs without importing sympy."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from mechsim import codegen
from mechsim.systems import SYSTEMS, system_class, system_ids
from mechsim.systems.lagrangian import LagrangianBuilder, LagrangianModel


def _any_model(sid: str, formulation: str, **values: Any) -> Any:
    cls = system_class(sid)
    return cls(formulation=formulation, **values) if len(cls.formulations) > 1 \
        else cls(**values)


def _lagrangian_variants() -> list[tuple[str, str]]:
    return [(sid, f) for sid in system_ids() for f in system_class(sid).formulations
            if isinstance(_any_model(sid, f), LagrangianModel)]


def _model(sid: str, formulation: str, **values: Any) -> LagrangianModel:
    model = _any_model(sid, formulation, **values)
    assert isinstance(model, LagrangianModel)
    return model


def _shape(m: LagrangianModel) -> tuple[Any, ...]:
    return (m.coordinates, m.invariants, m.observables, m.frames, m.events, m.modes,
            m.structure, m.has_canonical_form(), m.energy_function_conserved(), m.laws(),
            m.effort_slice(), m.kernels.module.__name__)


@pytest.fixture
def summaries(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty place for summaries; the kernel modules stay where the session has them."""
    folder = tmp_path / "summaries"
    monkeypatch.setattr(codegen, "_summary_dir", lambda: folder)
    return folder


@pytest.mark.parametrize(("sid", "formulation"), _lagrangian_variants())
def test_recalled_model_is_the_declared_one(summaries: Path, sid: str,
                                            formulation: str) -> None:
    declared = _model(sid, formulation)
    shape = _shape(declared)  # made from the declaration, and remembered
    assert "declaration" in declared.__dict__ and len(list(summaries.iterdir())) == 1
    recalled = _model(sid, formulation)
    assert _shape(recalled) == shape
    assert "declaration" not in recalled.__dict__  # nothing was declared again


def test_every_input_of_the_declaration_is_in_the_key(summaries: Path) -> None:
    base = _model("pendulum", "reduced")
    keys = {base._recall_key(),
            _model("pendulum", "multiplier")._recall_key(),
            _model("pendulum", "reduced", gravity=3.0)._recall_key(),
            _model("pendulum", "reduced", **{"initial.angle": 0.5})._recall_key()}
    assert len(keys) == 4
    # A structural parameter changes what is declared: its summary is its own.
    three = _model("coupled_oscillators", "default", count=3)
    four = _model("coupled_oscillators", "default", count=4)
    assert len(three.coordinates) == 3 and len(four.coordinates) == 4
    assert len(_model("coupled_oscillators", "default", count=3).coordinates) == 3
    # A numeric one does not: another summary, the same kernels.
    assert (_model("pendulum", "reduced", gravity=3.0).kernels.module
            is base.kernels.module)


class _Ball(LagrangianModel):
    """A system outside mechsim (as a plug-in or a test defines one)."""

    id = "recall_ball"
    title = "ball"
    source = "test"
    parameters = ()

    def declare(self, b: LagrangianBuilder) -> None:
        from mechsim.systems._symbolic import sympy as sp

        z, vz = b.coordinate("z", "m")
        b.kinetic = vz**2 / 2
        b.potential = 9.81 * z + sp.Integer(0)


def test_a_class_outside_mechsim_is_always_declared(summaries: Path) -> None:
    ball = _Ball()
    assert ball._recall_key() is None
    assert [c.name for c in ball.coordinates] == ["z"]
    assert not summaries.exists() or not list(summaries.iterdir())


@pytest.mark.parametrize("content", ["", "{not json", "[1, 2]", json.dumps({"coordinates": []})])
def test_an_unreadable_summary_is_made_again(summaries: Path, content: str) -> None:
    shape = _shape(_model("double_pendulum", "angles"))
    (path,) = summaries.iterdir()
    path.write_text(content)
    again = _model("double_pendulum", "angles")
    assert _shape(again) == shape
    assert "declaration" in again.__dict__
    assert json.loads(path.read_text())["value"]["coordinates"]  # and remembered again


def test_an_oversized_summary_is_not_read(summaries: Path) -> None:
    """A summary file far larger than any model's (here a valid one padded with blanks) is
    not ours: it is not read, and the model is declared afresh."""
    shape = _shape(_model("double_pendulum", "angles"))
    (path,) = summaries.iterdir()
    path.write_text(path.read_text() + " " * 1_100_000)
    again = _model("double_pendulum", "angles")
    assert _shape(again) == shape
    assert "declaration" in again.__dict__


def test_system_modules_import_without_sympy() -> None:
    code = ("import importlib, sys\n"
            f"for name in {sorted(SYSTEMS.values())!r}:\n"
            "    importlib.import_module(name)\n"
            "print('sympy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0 and out.stdout.split() == ["False"], out.stderr


def test_a_warm_process_runs_without_sympy() -> None:
    """The second process to run a system finds its summary and kernels in the cache."""
    code = ("import sys\n"
            "from mechsim.systems import system_class\n"
            "from mechsim.simulate import simulate\n"
            "m = system_class('double_pendulum')(**{'initial.angle_1': 0.7})\n"
            "r = simulate(m, 0.5, 0.1)\n"
            "print(m.laws()[0].kind, r.q.shape[0], 'sympy' in sys.modules)")
    runs = [subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           timeout=600) for _ in range(2)]
    for run in runs:
        assert run.returncode == 0, run.stderr
    assert runs[1].stdout.split()[-1] == "False", runs[1].stdout
    assert runs[0].stdout.split()[:2] == runs[1].stdout.split()[:2]
