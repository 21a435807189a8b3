"""Where each part of a model's two vectors sits: the state (``StateLayout``) and the kernels'
parameter vector (``ParameterLayout``). Each is the one place that knows its places; the
generated kernels and the models' vectors follow them."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np


@dataclass(frozen=True)
class StateLayout:
    """Where each part of the state vector sits:
    ``y = [q (n), v = q̇ (n), work_external, work_dissipated, modes (n_modes)]``.

    The index attributes work on one state ``y[layout.q]`` and, with ``[..., index]``, on rows
    of states ``Y[..., layout.q]``; :meth:`compose` builds a state.
    """

    n: int
    n_modes: int = 0

    @property
    def size(self) -> int:
        return 2 * self.n + 2 + self.n_modes

    @property
    def q(self) -> slice:
        return slice(0, self.n)

    @property
    def v(self) -> slice:
        return slice(self.n, 2 * self.n)

    @property
    def work_external(self) -> int:
        return 2 * self.n

    @property
    def work_dissipated(self) -> int:
        return 2 * self.n + 1

    @property
    def modes(self) -> slice:
        return slice(2 * self.n + 2, self.size)

    def compose(self, q: Any, v: Any, work_external: float = 0.0, work_dissipated: float = 0.0,
                modes: Any = ()) -> np.ndarray:
        y = np.concatenate([np.asarray(q, dtype=np.float64), np.asarray(v, dtype=np.float64),
                            [work_external, work_dissipated],
                            np.asarray(modes, dtype=np.float64)]).astype(np.float64)
        if y.size != self.size:
            raise ValueError(f"state of size {y.size}, layout needs {self.size}")
        return y


@dataclass(frozen=True)
class ParameterLayout:
    """Where each entry of the kernels' parameter vector sits:
    ``p = [block (offset), parameters, efforts (n_efforts), parameter constants (n_constants)]``.

    ``parameters`` are the model's numeric parameters in the order of its ``parameter_spec``;
    ``offset`` entries of derived data may come first (a direct model's, see
    ``DirectModel.parameter_offset``); a Lagrangian model's effort (one generalized force per
    coordinate) and its parameter constants (what the derivation computes once per parameter
    vector) follow. The kernel source is generated from these places, and the model's
    parameter vector is filled by them: this class is the one place that knows them.
    """

    parameters: tuple[str, ...]
    n_efforts: int = 0
    n_constants: int = 0
    offset: int = 0

    def index(self, name: str) -> int:
        """The place of numeric parameter ``name``."""
        return self.offset + self.parameters.index(name)

    def indices(self) -> dict[str, int]:
        """Every numeric parameter's place, by name."""
        return {name: self.offset + i for i, name in enumerate(self.parameters)}

    @property
    def values(self) -> slice:
        """The numeric parameters."""
        return slice(self.offset, self.offset + len(self.parameters))

    @property
    def efforts(self) -> slice:
        return slice(self.values.stop, self.values.stop + self.n_efforts)

    def effort(self, i: int) -> int:
        """The place of the effort on coordinate ``i``."""
        return self.efforts.start + i

    @property
    def constants(self) -> slice:
        return slice(self.efforts.stop, self.efforts.stop + self.n_constants)

    def constant(self, i: int) -> int:
        """The place of parameter constant ``i``."""
        return self.constants.start + i

    @property
    def size(self) -> int:
        return self.constants.stop

    def with_constants(self, n_constants: int) -> ParameterLayout:
        """This layout with ``n_constants`` parameter constants (known once derived)."""
        return replace(self, n_constants=n_constants)
