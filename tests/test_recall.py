"""A Lagrangian model derived before is set up from its recalled summary, without sympy: the
recalled model is the declared one (shape, structure, laws, kernels), the summary is keyed on
every input of the declaration (a changed value the declaration reads, another formulation, a
class outside mechsim are never recalled from something else; a value it does not read changes
nothing it makes, so models that differ only there share one summary), an unreadable summary
is made again, and a warm process runs without importing sympy."""

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
    monkeypatch.setattr(codegen, "_recalled", {})  # as in a new process
    return folder


@pytest.mark.parametrize(("sid", "formulation"), _lagrangian_variants())
def test_recalled_model_is_the_declared_one(summaries: Path, sid: str,
                                            formulation: str) -> None:
    declared = _model(sid, formulation)
    shape = _shape(declared)  # made from the declaration, and remembered
    # its summary, and the names of the values its class's declaration read
    assert "declaration" in declared.__dict__ and len(list(summaries.iterdir())) == 2
    kept = _model(sid, formulation)  # from what this process read or stored
    assert _shape(kept) == shape and "declaration" not in kept.__dict__
    codegen._recalled.clear()
    recalled = _model(sid, formulation)  # from the files, as by a new process
    assert _shape(recalled) == shape
    assert "declaration" not in recalled.__dict__  # nothing was declared again


def test_every_value_the_declaration_reads_is_in_the_key(summaries: Path) -> None:
    base = _model("pendulum", "reduced")
    base_shape = _shape(base)
    assert "declaration" in base.__dict__
    # Another formulation (a value the declaration reads) is declared afresh.
    multiplier = _model("pendulum", "multiplier")
    assert len(multiplier.coordinates) == 2 and "declaration" in multiplier.__dict__
    # Values a pendulum's declaration does not read: the summary made before, as made.
    swept = _model("pendulum", "reduced", gravity=3.0, **{"initial.angle": 0.5})
    assert _shape(swept) == base_shape and "declaration" not in swept.__dict__
    # A structural parameter changes what is declared: its summary is its own.
    three = _model("coupled_oscillators", "default", count=3)
    four = _model("coupled_oscillators", "default", count=4)
    assert len(three.coordinates) == 3 and len(four.coordinates) == 4
    assert len(_model("coupled_oscillators", "default", count=3).coordinates) == 3
    # A numeric one does not: the same kernels.
    assert (_model("pendulum", "reduced", gravity=3.0).kernels.module
            is base.kernels.module)


def test_a_declaration_that_branches_on_a_value_is_keyed_on_what_each_branch_read(
        summaries: Path) -> None:
    """A bead on a custom wire reads the curve, one on a parabola does not: each is keyed on
    its own reads, and a second curve is declared afresh, not recalled from the first."""
    parabola = _shape(_model("bead_on_wire", "reduced", shape="parabola"))
    first = _model("bead_on_wire", "reduced", shape="custom", curve="x**2/2")
    second = _model("bead_on_wire", "reduced", shape="custom", curve="cosh(x)")
    assert first.derivation_key() != second.derivation_key()
    for model in (first, second):
        assert model._summary["derivation_key"] == model.derivation_key()
    again = _model("bead_on_wire", "reduced", shape="parabola", **{"initial.x": 0.3})
    assert _shape(again) == parabola and "declaration" not in again.__dict__
    assert _shape(_model("bead_on_wire", "reduced", shape="custom", curve="cosh(x)")
                  )[-1] == second.kernels.module.__name__


def _other_values(model: LagrangianModel, read: set[str]) -> dict[str, Any]:
    """Another valid value of every numeric parameter ``read`` leaves out (those a new value
    of which the model refuses on its own or with the others keep theirs)."""
    changes: dict[str, Any] = {}
    for spec in model.parameter_spec():
        if spec.name in read or not spec.is_numeric or spec.kind is bool:
            continue
        value = model.values[spec.name]
        assert isinstance(value, int | float)
        others = (value + 1, value - 1, value * 2) if spec.kind is int else (
            value * 1.25 + 0.125, value * 0.75 - 0.0625, value * 0.5)
        for other in others:
            try:
                model.with_values(**changes, **{spec.name: other})
            except ValueError:
                continue
            changes[spec.name] = other
            break
    return changes


@pytest.mark.parametrize(("sid", "formulation"), _lagrangian_variants())
def test_the_values_a_declaration_does_not_read_change_nothing_it_makes(
        summaries: Path, sid: str, formulation: str) -> None:
    """Every value that reaches a declaration is noted as read: a model with another value
    of each parameter its declaration did not read, declared on its own (as every model was
    before summaries were shared), makes the same summary."""
    model = _model(sid, formulation)
    made, names = model._summary_made()
    changes = _other_values(model, set(names))
    assert changes, "no parameter took another value"
    other = model.with_values(**changes)
    assert isinstance(other, LagrangianModel)
    assert {"derivation_key": other.derivation_key(), **other._summarize()} == made


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


def _stored(summaries: Path, kind: str) -> Path:
    """The one stored file of ``kind``: "summary" or "read_sets" (the names read)."""
    (path,) = [path for path in summaries.iterdir()
               if ("read_sets" in json.loads(path.read_text())["value"]) == (kind == "read_sets")]
    return path


@pytest.mark.parametrize("kind", ["summary", "read_sets"])
@pytest.mark.parametrize("content", ["", "{not json", "[1, 2]", json.dumps({"coordinates": []})])
def test_an_unreadable_summary_is_made_again(summaries: Path, content: str, kind: str) -> None:
    shape = _shape(_model("double_pendulum", "angles"))
    path = _stored(summaries, kind)
    path.write_text(content)
    codegen._recalled.clear()  # read by a new process
    again = _model("double_pendulum", "angles")
    assert _shape(again) == shape
    assert "declaration" in again.__dict__
    assert json.loads(path.read_text())["value"][  # and remembered again
        "coordinates" if kind == "summary" else "read_sets"]


def test_an_oversized_summary_is_not_read(summaries: Path) -> None:
    """A summary file far larger than any model's (here a valid one padded with blanks) is
    not ours: it is not read, and the model is declared afresh."""
    shape = _shape(_model("double_pendulum", "angles"))
    path = _stored(summaries, "summary")
    path.write_text(path.read_text() + " " * 1_100_000)
    codegen._recalled.clear()  # read by a new process
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
