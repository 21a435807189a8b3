"""Models that write their kernel functions by hand, for what a Lagrangian declaration does not
cover: contact events, quaternion attitude, prescribed kinematics.

A subclass lists plain Python functions (``kernel_functions``) named after the kernel contract
(``mechsim/integrators/contract.py``): rhs, and any of project, accel_q, energy, invariants,
observables, frames; plus private helpers they call. Their source is pasted into the model's
generated kernel module and compiled by numba, so they may use only ``math``, ``np``, each
other, the size constants (N_Q, ...) and one constant per numeric parameter giving its index
in ``p``: ``P_<NAME>`` (upper case, dots as underscores; e.g. ``p[P_MASS]``,
``p[P_INITIAL_ANGLE]``). Missing contract functions default to doing nothing.
Events: declare ``events`` (``Event(name, direction)``) and ``modes`` (discrete state entries,
read in kernels as ``y[2 * N_Q + 2 + i]``), give an ``event(t, y, p, out)`` kernel function and
handle each event in a method ``on_<event name>(t, y) -> y`` (see ``mechsim.integrators``).
"""

from __future__ import annotations

import inspect
import textwrap
from collections.abc import Callable
from functools import cached_property
from types import ModuleType
from typing import ClassVar

from mechsim import codegen
from mechsim.systems.base import Model

_CONTRACT = ("rhs", "project", "accel_q", "energy", "invariants", "observables", "frames",
             "event", "to_momenta", "from_momenta", "canonical_rhs")
_SIGNATURES = {"rhs": "t, y, p, dy", "project": "t, y, p", "accel_q": "t, q, p, a",
               "energy": "t, y, p, out", "invariants": "t, y, p, out",
               "observables": "t, y, p, out", "frames": "t, y, p, out",
               "event": "t, y, p, out", "to_momenta": "t, y, p, z",
               "from_momenta": "t, z, p, y", "canonical_rhs": "t, z, p, dz"}


def parameter_constant(name: str) -> str:
    return "P_" + name.replace(".", "_").upper()


class DirectModel(Model):
    kernel_functions: ClassVar[tuple[Callable[..., object], ...]] = ()

    @cached_property
    def kernels(self) -> ModuleType:
        return codegen.build(self.kernel_source())

    def kernel_source(self) -> codegen.KernelSource:
        given = {f.__name__ for f in self.kernel_functions}
        parts = []
        for f in self.kernel_functions:
            src = textwrap.dedent(inspect.getsource(f))
            parts.append("@njit(cache=True)\n" + src)
        for name in _CONTRACT:
            if name not in given:
                parts.append(f"@njit(cache=True)\ndef {name}({_SIGNATURES[name]}):\n    return\n")
        numeric = [p.name for p in self.parameter_spec() if p.is_numeric]
        n = len(self.coordinates)
        constants: dict[str, int | float] = {
            "N_Q": n, "N_Y": 2 * n + 2 + len(self.modes), "N_C": self.structure.n_constraints,
            "N_INV": len(self.invariants), "N_OBS": len(self.observables),
            "N_FRAMES": len(self.frames), "N_EV": len(self.events), "N_MODE": len(self.modes)}
        constants.update({parameter_constant(name): i for i, name in enumerate(numeric)})
        tag = self.formulation if len(self.formulations) > 1 else "direct"
        return codegen.KernelSource(name=f"{self.id}_{tag}", constants=constants,
                                    body="\n\n".join(parts))
