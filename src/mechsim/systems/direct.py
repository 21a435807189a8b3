"""Models that write their kernel functions by hand, for what a Lagrangian declaration does not
cover: contact events, quaternion attitude, prescribed kinematics.

A subclass lists plain Python functions (``kernel_functions``) named after the kernel contract
(``mechsim/codegen/contract.py``): rhs, and any of project, accel_q, energy, invariants,
observables, frames, event; plus private helpers they call. Their source is pasted into the
model's generated kernel module and compiled by numba, so they may use only ``math``, ``np``,
each other, the module's constants — the sizes (N_Q, …), one constant per numeric parameter
giving its index in ``p``, ``P_<NAME>`` (upper case, dots as underscores; e.g. ``p[P_MASS]``),
and any a subclass adds (``kernel_constants``) — and the helpers of ``mechsim.codegen.support``
under the names the kernel module gives them (``_vector``, ``_matrix``, ``_tensor``,
``_zero_vector``, ``_zero_matrix``, ``_solve``, …; import them under the same names). Allocating
through these rather than ``np.empty``/``np.zeros`` spares each new model's compilation numba's
own implementation of those, an element loop instead of a slice assignment
``a[i, :] = b[j, :]`` spares it the shape check's error path, and products
instead of integer powers (``x * x`` for ``x ** 2``: the value numba computes for it) its
compiled power subroutine. Missing contract functions do nothing.

The functions stay callable from Python too, with the constants of their own module. So that
both agree, every upper-case constant a kernel function reads must be defined with the same
value in its Python module as in the kernel module; ``kernel_source`` checks this and raises
``KernelContractError`` naming the function and constant otherwise.
Events: declare ``events`` (``Event(name, direction)``) and ``modes`` (discrete state entries,
read in kernels as ``y[2 * N_Q + 2 + i]``), give an ``event(t, y, p, out)`` kernel function and
handle each event in a method ``on_<event name>(t, y) -> y`` (see ``mechsim.integrators``).
"""

from __future__ import annotations

import inspect
import textwrap
from collections.abc import Callable
from dataclasses import replace
from functools import cached_property
from typing import ClassVar

from mechsim import codegen
from mechsim.systems.base import Model
from mechsim.systems.layout import ParameterLayout


class KernelContractError(ValueError):
    """A hand-written kernel function disagrees with its generated kernel module."""


def parameter_constant(name: str) -> str:
    return "P_" + name.replace(".", "_").upper()


def _constants_used(f: Callable[..., object]) -> set[str]:
    """Upper-case global names the function's code reads (nested code objects included)."""
    names: set[str] = set()
    stack = [f.__code__]  # type: ignore[attr-defined]
    while stack:
        code = stack.pop()
        names.update(n for n in code.co_names if n.isupper())
        stack.extend(c for c in code.co_consts if inspect.iscode(c))
    return names


class DirectModel(Model):
    kernel_functions: ClassVar[tuple[Callable[..., object], ...]] = ()

    @cached_property
    def kernels(self) -> codegen.Kernels:
        src = self.kernel_source()
        return codegen.build(src.name, src.text(""), lambda: src)

    def parameter_offset(self) -> int:
        """Index in ``p`` of the first numeric parameter (entries before it are derived data
        a subclass puts first, see ``_rigid.QuaternionRigidBody``)."""
        return 0

    def kernel_constants(self) -> dict[str, int | float]:
        """Constants of the kernel module besides the sizes and parameter indices."""
        return {}

    @property
    def parameter_layout(self) -> ParameterLayout:
        """The derived block (``parameter_offset`` entries), then the numeric parameters."""
        return replace(super().parameter_layout, offset=self.parameter_offset())

    def kernel_source(self) -> codegen.KernelSource:
        layout = self.parameter_layout
        n = len(self.coordinates)
        constants: dict[str, int | float] = {
            "N_Q": n, "N_Y": 2 * n + 2 + len(self.modes), "N_C": self.structure.n_constraints,
            "N_INV": len(self.invariants), "N_OBS": len(self.observables),
            "N_FRAMES": len(self.frames), "N_EV": len(self.events), "N_MODE": len(self.modes),
            "N_P": layout.size}
        constants.update({parameter_constant(name): i for name, i in layout.indices().items()})
        constants.update(self.kernel_constants())
        self._check_constants(constants)
        parts = []
        for f in self.kernel_functions:
            src = textwrap.dedent(inspect.getsource(f))
            if not src.startswith(f"def {f.__name__}("):
                # inspect reads the file as it is now, at the lines of the code imported
                raise KernelContractError(f"{f.__module__}.{f.__name__}: its source file "
                                          "changed since it was imported: start again")
            parts.append(f"{codegen.decorator(f.__name__)}\n{src}")
        given = tuple(f.__name__ for f in self.kernel_functions
                      if f.__name__ in codegen.FUNCTIONS)
        tag = self.formulation if len(self.formulations) > 1 else "direct"
        return codegen.KernelSource(name=f"{self.id}_{tag}", constants=constants,
                                    body="\n\n".join(parts), functions=given)

    def _check_constants(self, constants: dict[str, int | float]) -> None:
        """Every upper-case global a kernel function reads is a module constant, and its
        Python-side value (if its module defines one) equals the generated one."""
        for f in self.kernel_functions:
            env = f.__globals__  # type: ignore[attr-defined]
            for name in sorted(_constants_used(f)):
                where = f"{type(self).__name__}: kernel function {f.__name__} reads {name}"
                if name not in constants:
                    raise KernelContractError(f"{where}, which its kernel module does not "
                                              "define (only sizes, P_<PARAMETER> and "
                                              "kernel_constants())")
                if name in env and env[name] != constants[name]:
                    raise KernelContractError(
                        f"{where} = {env[name]!r} in {f.__module__}, but the kernel module "
                        f"has {name} = {constants[name]!r}: a Python call would compute "
                        "with the wrong index")
