"""What a stepper needs of a model: the protocol the integrators define and every system
satisfies. The integrators never import the physics layer; they see a model through this, and
its compiled kernels through the kernel contract (``mechsim.codegen.names.KernelContract``)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

if TYPE_CHECKING:
    from mechsim.codegen import Kernels


class StructureLike(Protocol):
    @property
    def separable(self) -> bool:
        """H = T(p) + V(q): compositions of velocity Verlet apply."""
    @property
    def dissipative(self) -> bool:
        """A Rayleigh function acts: errors decay, damping may be stiff."""
    @property
    def second_order(self) -> bool:
        """q̇ is the state's v part (not momenta): radau15 applies."""


class SteppableModel(Protocol):
    # Read-only: a model may hold them as attributes or compute them as properties.
    @property
    def id(self) -> str: ...
    @property
    def formulation(self) -> str: ...
    @property
    def chosen_formulation(self) -> str: ...
    @property
    def coordinates(self) -> Sequence[Any]: ...
    @property
    def events(self) -> Sequence[Any]: ...
    @property
    def structure(self) -> StructureLike: ...
    @property
    def kernels(self) -> Kernels: ...

    def parameter_vector(self) -> np.ndarray: ...
    def complete_parameters(self, p: np.ndarray) -> np.ndarray: ...
    def initial_y(self) -> np.ndarray: ...
    def time_scale(self) -> float: ...
    def has_closed_form(self) -> bool: ...
    def has_canonical_form(self) -> bool: ...
    def propagate(self, t0: float, y0: np.ndarray, t: np.ndarray,
                  work_terms: bool = True) -> np.ndarray | None: ...
    def closed_form_kernel(self, y0: np.ndarray) -> tuple[Any, np.ndarray] | None: ...
    def handle_event(self, index: int, t: float, y: np.ndarray) -> np.ndarray: ...
