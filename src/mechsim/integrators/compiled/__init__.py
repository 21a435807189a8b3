"""The integrator loops, compiled once per machine and shared by every model.

Each loop takes the model's ``KernelSet`` (``mechsim.codegen.contract``): the model's compiled
functions as first-class function values and its sizes, so one compiled loop serves every
model and the calls into the model stay compiled.

The loops are resumable: their whole state lives in arrays the caller keeps between calls (a
state record of ``mechsim.integrators.state`` and work arrays), so a node can advance a run
output by output with no restart cost and no forced short steps. Every loop updates the
state with compensated (Kahan) summation: the low-order bits lost when a small increment is
added to a large state are kept in ``comp`` and added back at the next step, so round-off
does not accumulate in long runs.

The source is this package's fragments, one per family (``FRAGMENTS``, in this order):
``common`` (helpers of every loop), ``stages`` (stand-ins for the explicit pairs' stage sums),
``radau_basis`` and ``radau_iteration`` (the Gauss–Radau expansion and its
predictor–corrector iteration), ``events`` (the state inside a step, and event location
there), ``erk`` (DOP853 and DOPRI5), ``radau`` (radau15), ``fixed`` (the compositions and
Gauss–Legendre) and ``outputs``. Each fragment imports what it uses of the others, so that it
reads, and is checked, as a module of its own; none is imported to run. ``load`` joins them
into one module (``source``: their imports of each other left out, one namespace; the
stand-ins replaced by the stage sums ``dop853_tableau`` and ``dopri5_tableau`` write out from
their tableaus) and loads it through ``mechsim.codegen.load_module`` under a name that hashes
its text and every module it reads (tableaus, state records), so numba's disk cache, keyed on
the time stamp of a function's own file alone, can never serve a loop compiled from older
inputs.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from mechsim import codegen
from mechsim.integrators import dop853_tableau, dopri5_tableau, state
from mechsim.integrators.state import DOP853_STATE, FIXED_STATE, RADAU_STATE, new_state

#: The fragments of the loops' source, in the order of the joined module.
FRAGMENTS = ("common", "stages", "radau_basis", "radau_iteration", "events", "erk", "radau",
             "fixed", "outputs")
_HEADER = '"""The shared integrator loops, joined from ``mechsim.integrators.compiled``."""'


def _without_own_imports(text: str) -> str:
    """A fragment's text without its imports of the other fragments."""
    dropped: set[int] = set()
    for node in ast.parse(text).body:
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith(__name__):
            dropped.update(range(node.lineno, (node.end_lineno or node.lineno) + 1))
    return "\n".join(line for i, line in enumerate(text.splitlines(), 1) if i not in dropped)


def source() -> str:
    """The text of the loops' module: the fragments joined, the stage sums written out."""
    parts = [_HEADER]
    for name in FRAGMENTS:
        if name == "stages":
            parts.append(f"{dop853_tableau.loop_source()}\n\n{dopri5_tableau.loop_source()}")
        else:
            parts.append(_without_own_imports(Path(__file__).with_name(f"{name}.py").read_text()))
    return "\n\n\n".join(parts) + "\n"


@functools.cache
def load() -> ModuleType:
    """The shared compiled loops, loaded under a name that hashes their source and every module
    they read (see ``mechsim.codegen``); compiled on first use per machine, then loaded from
    numba's cache."""
    text = source()
    key = codegen.fingerprint(text, codegen.source_fingerprint([dop853_tableau, dopri5_tableau,
                                                                state]))
    return codegen.load_module("loops", key, lambda: text)


def _runs_source(loops_module: str) -> str:
    """The text of the whole-run module (``runs``): its imports of the other fragments read
    from the loaded loops module ``loops_module``."""
    text = Path(__file__).with_name("runs.py").read_text()
    lines = text.splitlines()
    for node in ast.parse(text).body:
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith(__name__):
            lines[node.lineno - 1] = lines[node.lineno - 1].replace(node.module or "",
                                                                    loops_module, 1)
    return "\n".join(lines) + "\n"


@functools.cache
def load_runs() -> ModuleType:
    """The whole-run loops (``runs``: one run in one call, and ensembles in parallel),
    a generated module of their own on top of the shared loops (which it imports), under a
    name that hashes its text, which names the loops' module."""
    text = _runs_source(load().__name__)
    return codegen.load_module("runs", codegen.fingerprint(text), lambda: text)


#: ``precompile``'s two halves, of about equal compile time (DOP853's loop, the largest, with
#: the small ones; radau15's with DOPRI5's), for set-up to compile on two cores.
PRECOMPILE_PARTS = (("dop853_advance", "erk_initial_step",
                     "composition_advance", "gauss_advance", "evaluate_outputs"),
                    ("radau15_advance", "dopri5_advance"))


def loop_signatures() -> dict[Any, tuple[Any, ...]]:
    """Each shared loop and the numba types of the arguments the steppers pass it: the one
    specialization set-up compiles. An argument of another type (a read-only array, another
    integer width) would make numba compile a second one at run time, in every new
    environment, and nothing would say so."""
    from numba import typeof

    from mechsim.codegen.contract import KERNEL_SET

    L = load()
    v, m2, m3 = np.zeros(2), np.zeros((2, 2)), np.zeros((2, 2, 2))
    dop, fixed = new_state(DOP853_STATE, 0.0), new_state(FIXED_STATE, 0.0)
    iv = np.zeros(1, dtype=np.int64)
    signatures = {
        L.erk_initial_step: (KERNEL_SET, 0.0, v, v, v, 0.0, 0.0, 0.0, 0),
        **{loop: (KERNEL_SET, dop, v, v, m2, m2, v, v, m2, 0.0, 0.0, 0.0, 0, v, iv, v, 0)
           for loop in (L.dop853_advance, L.dopri5_advance)},
        L.composition_advance: (KERNEL_SET, fixed, v, v, 0, 0, 0.0, v, m2, v, v),
        L.gauss_advance: (KERNEL_SET, fixed, v, v, 0, 0, 0.0, m2, m2, v),
        L.evaluate_outputs: (KERNEL_SET, v, m2, v, True, True, True, True, m2, m2, m2, m3),
        L.radau15_advance: (KERNEL_SET, new_state(RADAU_STATE, 0.0), v, v, v, m2, 0.0, 0, v, m2,
                            m2, m2, v, v, v, iv, 0.0, 0.0, 0.0),
    }
    stray = {loop.__name__ for loop in signatures} ^ {n for p in PRECOMPILE_PARTS for n in p}
    if stray:  # a loop added or renamed without its part: set-up would not compile it
        raise RuntimeError(f"PRECOMPILE_PARTS out of step with the loops: {sorted(stray)}")
    return {loop: tuple(a if a is KERNEL_SET else typeof(a) for a in args)
            for loop, args in signatures.items()}


#: The whole-run loops (``runs``) each half of ``precompile`` compiles after its shared loops.
PRECOMPILE_RUNS = (("erk_call", "erk_many", "closed_call"),
                   ("radau15_call", "radau15_many", "outputs_many"))


def run_signatures() -> dict[Any, tuple[Any, ...]]:
    """The whole-run loops (``load_runs``) and the numba types of the arguments
    ``integrators.runs`` and ``integrators.ensemble`` pass them (see ``loop_signatures``)."""
    from numba import typeof

    from mechsim.codegen.contract import KERNEL_SET, MOTION

    R = load_runs()
    v, m2, m3 = np.zeros(2), np.zeros((2, 2)), np.zeros((2, 2, 2))
    m4 = np.zeros((2, 2, 2, 2))
    iv = np.zeros(1, dtype=np.int64)
    dop, radau = np.zeros(1, DOP853_STATE), np.zeros(1, RADAU_STATE)
    signatures = {
        R.erk_call: (KERNEL_SET, iv, v, m2),
        R.radau15_call: (KERNEL_SET, iv, v, m2),
        R.closed_call: (MOTION, KERNEL_SET, iv, v, m2),
        R.erk_many: (KERNEL_SET, 0, iv, dop, m2, m2, m3, m3, m2, v, iv, m3, v, v, 0.0, 0, m2,
                     iv, m2, iv, iv),
        R.radau15_many: (KERNEL_SET, iv, radau, m2, m2, v, iv, m3, v, 0, m2, m3, m3, m3, m2, m2,
                         m2, iv, m2, v, v, 0.0, v, v, iv, iv),
        R.outputs_many: (KERNEL_SET, v, m3, m2, True, True, True, True, m3, m3, m3, m4),
    }
    return {loop: tuple(a if a in (KERNEL_SET, MOTION) else typeof(a) for a in args)
            for loop, args in signatures.items()}


def precompile(part: int | None = None) -> None:
    """Compile the shared loops for the argument types the steppers pass (once per machine;
    ``tools/bootstrap.py`` calls this so that the first run of any system only compiles that
    system's small kernels), then the whole-run loops: all of them, or
    ``PRECOMPILE_PARTS[part]`` and ``PRECOMPILE_RUNS[part]``."""
    wanted = None if part is None else set(PRECOMPILE_PARTS[part])
    for loop, types in loop_signatures().items():
        if wanted is None or loop.__name__ in wanted:
            loop.compile(types)
    wanted = None if part is None else set(PRECOMPILE_RUNS[part])
    for loop, types in run_signatures().items():
        if wanted is None or loop.__name__ in wanted:
            loop.compile(types)
