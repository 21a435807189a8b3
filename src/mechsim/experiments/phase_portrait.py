"""Phase portraits: one system integrated from several initial conditions, each trajectory kept
as (q, q̇) of one coordinate, for plots of the phase plane (the pendulum's librations,
separatrix and rotations; the damped oscillator's spirals). An experiment run on a system, so
it lives above the physics and stepping layers."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from mechsim.simulate import simulate
from mechsim.systems.base import Model


@dataclass(frozen=True)
class PhaseTrajectory:
    """One trajectory in the phase plane: its parameters, times, q and q̇ of the coordinate."""

    parameters: dict[str, Any]
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray


def phase_portrait(model: Model, starts: Iterable[Mapping[str, Any]], t_end: float,
                   output_dt: float, coordinate: str | None = None, tolerance: float = 1e-10,
                   method: str = "auto") -> list[PhaseTrajectory]:
    """``model`` with each parameter change of ``starts`` (initial conditions, usually),
    integrated to ``t_end``; the phase trajectory of ``coordinate`` (the first by default)."""
    out = []
    for change in starts:
        m = model.with_values(**change)
        names = [c.name for c in m.coordinates]
        k = names.index(coordinate) if coordinate is not None else 0
        run = simulate(m, t_end, output_dt, tolerance=tolerance, method=method, outputs=(),
                       work_terms=False)
        out.append(PhaseTrajectory(dict(change), run.t, run.q[:, k], run.v[:, k]))
    return out
