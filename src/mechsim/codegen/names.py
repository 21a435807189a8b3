"""The kernel contract in one table (numba-free, so that it can be imported cheaply).

``KernelContract`` lists, in order, every function a model's kernel module may define and
every size it states, each annotated with what the rest of the code needs to know of it: a
function's argument names (``t`` first, then arrays), which of its arrays is a matrix, and for a
function the loops call many times per step (``HOT``) the sizes of the arrays its raw-pointer
wrapper rebuilds. Everything else is derived from this class: the names and argument lists
below, the compiled signatures and the kernel set (``contract.py``), the pointer wrappers
(``KernelSource.text``), the attributes of ``Kernels``, and the argument lists generated code
is printed with (``mechsim.systems.lagrangian_kernels``). The class is also the typed view of a
model's kernels: ``Kernels`` subclasses it, and the integrators' model protocol types a model's
kernels by it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, get_type_hints


@dataclass(frozen=True)
class Function:
    """A function of the kernel contract: its arguments (``t``, then float64 arrays), those of
    them that are matrices (the others are vectors), and for a function called through raw
    pointers (``HOT``) the size constant of each array its wrapper rebuilds."""

    arguments: tuple[str, ...]
    matrices: tuple[str, ...] = ()
    pointer_sizes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Size:
    """A size of the model, a module constant of its kernel module (upper case) and a field of
    its kernel set (lower case)."""

    description: str


Kernel = Callable[..., None]
_STATE = ("N_Y", "N_P", "N_Y")


class KernelContract:
    """The kernel contract (see ``contract.py`` for what each function computes), in the order
    of the kernel set: functions first, then sizes."""

    rhs: Annotated[Kernel, Function(("t", "y", "p", "dy"), pointer_sizes=_STATE)]
    project: Annotated[Kernel, Function(("t", "y", "p"))]
    accel_q: Annotated[Kernel, Function(("t", "q", "p", "a"))]
    energy: Annotated[Kernel, Function(("t", "y", "p", "out"))]
    invariants: Annotated[Kernel, Function(("t", "y", "p", "out"))]
    observables: Annotated[Kernel, Function(("t", "y", "p", "out"))]
    frames: Annotated[Kernel, Function(("t", "y", "p", "out"), matrices=("out",))]
    event: Annotated[Kernel, Function(("t", "y", "p", "out"))]
    to_momenta: Annotated[Kernel, Function(("t", "y", "p", "z"))]
    from_momenta: Annotated[Kernel, Function(("t", "z", "p", "y"))]
    canonical_rhs: Annotated[Kernel, Function(("t", "z", "p", "dz"), pointer_sizes=_STATE)]
    n_q: Annotated[int, Size("generalized coordinates")]
    n_y: Annotated[int, Size("state entries, 2 N_Q + 2 + N_MODE")]
    n_c: Annotated[int, Size("constraints")]
    n_inv: Annotated[int, Size("invariants (constraint residuals included)")]
    n_obs: Annotated[int, Size("observables")]
    n_frames: Annotated[int, Size("frames")]
    n_ev: Annotated[int, Size("events")]
    n_mode: Annotated[int, Size("discrete modes")]
    n_p: Annotated[int, Size("entries of the parameter vector")]


_ENTRIES = {name: hint.__metadata__[0] for name, hint in
            get_type_hints(KernelContract, include_extras=True).items()}
#: Each function of the contract, by name, in the order of the kernel set.
CONTRACT: dict[str, Function] = {n: e for n, e in _ENTRIES.items() if isinstance(e, Function)}
#: The functions' names, in the order of the kernel set.
FUNCTIONS = tuple(CONTRACT)
#: Called from the loops through raw pointers (see ``contract.POINTER_SIGNATURE``).
HOT = tuple(n for n, f in CONTRACT.items() if f.pointer_sizes)
#: Each function's argument list, as generated source writes it.
ARGUMENTS = {n: ", ".join(f.arguments) for n, f in CONTRACT.items()}
#: The model's sizes as kernel-module constants, in the order of the kernel set.
SIZES = tuple(n.upper() for n, e in _ENTRIES.items() if isinstance(e, Size))
