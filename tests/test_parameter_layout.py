"""``ParameterLayout`` is where every model's parameters, efforts and parameter constants sit in
the kernels' parameter vector, and the generated kernels read them there: for every
Lagrangian formulation the loads in its generated module's source (``p_<name> = p[i]``,
``effort_<coordinate> = p[i]``, ``pc_<k> = p[i]``) and the slots ``parameter_constants``
fills are the layout's places, and the module's ``N_P`` its size; for every direct model
its ``P_<NAME>`` constants are the layout's places."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from mechsim.systems import system_class, system_ids
from mechsim.systems.direct import DirectModel, parameter_constant
from mechsim.systems.lagrangian import LagrangianModel
from mechsim.systems.layout import ParameterLayout

_LOAD = re.compile(r"^ +(p_\w+|effort_\w+|pc_\d+) = p\[(\d+)\]$", re.MULTILINE)
_FILL = re.compile(r"^ +p\[(\d+)\] = ", re.MULTILINE)


def _formulations(kind: type) -> list[tuple[str, dict[str, str]]]:
    out = []
    for sid in system_ids():
        cls = system_class(sid)
        if issubclass(cls, kind):
            forms = cls.formulations
            out += [(sid, {"formulation": f} if len(forms) > 1 else {}) for f in forms]
    return out


@pytest.mark.parametrize("sid,kw", _formulations(LagrangianModel),
                         ids=lambda v: v if isinstance(v, str) else v.get("formulation", ""))
def test_generated_kernels_read_the_layout(sid: str, kw: dict[str, str]) -> None:
    model = system_class(sid)(**kw)
    layout = model.parameter_layout
    source = Path(model.kernels.module.__file__).read_text()
    want = {"p_" + name.replace(".", "_"): i for name, i in layout.indices().items()}
    want |= {f"effort_{c.name}": layout.effort(i) for i, c in enumerate(model.coordinates)}
    want |= {f"pc_{k}": layout.constant(k) for k in range(layout.n_constants)}
    loads = _LOAD.findall(source)
    assert loads, sid
    for symbol, index in loads:
        assert want[symbol] == int(index), (sid, symbol, index)
    filled = sorted(int(i) for i in _FILL.findall(source))
    assert filled == list(range(layout.constants.start, layout.constants.stop)), sid
    assert model.kernels.n_p == layout.size == model.parameter_vector().size
    assert model.effort_slice() == layout.efforts
    assert layout.efforts.stop - layout.efforts.start == len(model.coordinates)
    p = model.parameter_vector()
    values = [float(model.values[n]) for n in layout.parameters]  # type: ignore[arg-type]
    assert np.array_equal(p[layout.values], values) and not p[layout.efforts].any()


@pytest.mark.parametrize("sid,kw", _formulations(DirectModel),
                         ids=lambda v: v if isinstance(v, str) else v.get("formulation", ""))
def test_direct_kernels_index_constants_are_the_layout(sid: str, kw: dict[str, str]) -> None:
    model = system_class(sid)(**kw)
    layout = model.parameter_layout
    constants = model.kernel_source().constants
    assert constants["N_P"] == layout.size == model.parameter_vector().size
    for name in layout.parameters:
        assert constants[parameter_constant(name)] == layout.index(name), (sid, name)
    assert model.effort_slice() is None and layout.n_efforts == 0


def test_the_layout_places_each_part_after_the_last() -> None:
    layout = ParameterLayout(("a", "b.c"), n_efforts=2, offset=3).with_constants(4)
    assert layout.indices() == {"a": 3, "b.c": 4}
    assert (layout.values, layout.efforts, layout.constants) == (
        slice(3, 5), slice(5, 7), slice(7, 11))
    assert layout.effort(1) == 6 and layout.constant(0) == 7 and layout.size == 11
