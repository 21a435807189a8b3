"""What a stepper needs of a model: the protocol the integrators define and every system
satisfies. The integrators never import the physics layer; they see a model through this."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, Protocol

import numpy as np


class StructureLike(Protocol):
    separable: bool  # H = T(p) + V(q): compositions of velocity Verlet apply


class KernelsLike(Protocol):
    """A model's compiled kernels (``mechsim.codegen.Kernels``): the functions of the kernel
    contract (``mechsim.codegen.contract``), its sizes, and ``kernel_set(*needed)``, the
    compiled record of both that the shared loops take."""

    rhs: Callable[..., None]
    project: Callable[..., None]
    accel_q: Callable[..., None]
    energy: Callable[..., None]
    event: Callable[..., None]
    to_momenta: Callable[..., None]
    from_momenta: Callable[..., None]
    canonical_rhs: Callable[..., None]
    n_q: int
    n_y: int
    n_ev: int

    def kernel_set(self, *needed: str) -> Any: ...


class SteppableModel(Protocol):
    id: str
    formulation: str
    coordinates: Sequence[Any]
    events: Sequence[Any]
    structure: StructureLike
    kernels: KernelsLike

    def parameter_vector(self) -> np.ndarray: ...
    def complete_parameters(self, p: np.ndarray) -> np.ndarray: ...
    def initial_y(self) -> np.ndarray: ...
    def time_scale(self) -> float: ...
    def has_closed_form(self) -> bool: ...
    def has_canonical_form(self) -> bool: ...
    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray) -> np.ndarray | None: ...
    def handle_event(self, index: int, t: float, y: np.ndarray) -> np.ndarray: ...
