"""The resonance sweep (PHYS0500 – Advanced Classical Mechanics, §1.5 and §1.5.1): the driven
oscillator integrated at each drive frequency until its transient has died out, then its steady
amplitude and mean kinetic energy measured over whole drive periods, to be read against the
closed-form curves D(ω) and ⟨T⟩(ω) (``mechsim.systems.curves.resonance_curves``). An
experiment run on a system, so it lives above the physics and stepping layers."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mechsim.errors import ParameterError
from mechsim.simulate import simulate
from mechsim.systems.base import Model

#: Samples per drive period of the measuring window.
SAMPLES_PER_PERIOD = 128


@dataclass(frozen=True)
class ResonanceSweep:
    """Measured steady amplitude D (m) and mean kinetic energy ⟨T⟩ (J) at each drive
    frequency ω (rad/s), both from means over whole periods sampled uniformly (exact for a
    sinusoid, unlike the peak of the samples): D = √(2⟨x²⟩), ⟨T⟩ = ⟨½mẋ²⟩."""

    omega: np.ndarray
    amplitude: np.ndarray
    kinetic: np.ndarray


def settling_time(model: Model, decades: float = 10.0) -> float:
    """Time after which the transient e^{−βt} is below 10^−decades of its start."""
    beta = model.beta()  # type: ignore[attr-defined]
    if beta <= 0.0:
        raise ParameterError("damping", "must be > 0 for a steady state to be reached")
    return decades * math.log(10.0) / beta


def sweep(model: Model, omegas: np.ndarray, periods: int = 4, tolerance: float = 1e-10,
          method: str = "auto") -> ResonanceSweep:
    """Integrate ``model`` (a ``driven_oscillator``) from its initial state at each ω of
    ``omegas`` (> 0) past ``settling_time``, then measure over ``periods`` whole periods."""
    t_settle = settling_time(model)
    amp, kin = [], []
    m = model.value("mass")
    for w in np.asarray(omegas, dtype=float):
        if not w > 0.0:
            raise ParameterError("omegas", f"drive frequencies must be > 0 (got {w:g})")
        period = 2 * math.pi / w
        n_settle = math.ceil(t_settle / period)
        run = simulate(model.with_values(drive_frequency=float(w)),
                       (n_settle + periods) * period, period / SAMPLES_PER_PERIOD,
                       tolerance=tolerance, method=method, outputs=(), work_terms=False)
        tail = slice(-periods * SAMPLES_PER_PERIOD - 1, None)
        x, v = run.q[tail, 0], run.v[tail, 0]
        amp.append(float(np.sqrt(2 * np.mean(x[:-1] ** 2))))  # whole periods, endpoint once
        kin.append(float(np.mean(0.5 * m * v[:-1] ** 2)))
    return ResonanceSweep(np.asarray(omegas, dtype=float), np.array(amp), np.array(kin))
