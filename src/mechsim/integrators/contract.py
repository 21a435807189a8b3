"""Names a kernel module's model part must define; the integrator loops call them as globals.

This module only documents the contract (and lets linters see the names in ``kernels.py``);
the generated module defines the real ones. Sizes: N_Q coordinates, N_Y = 2 N_Q + 2 + N_MODE
state entries, N_C constraints, N_INV invariants, N_OBS observables, N_FRAMES frames, N_EV
events, N_MODE discrete mode entries.

Events (optional; N_EV = 0 and a no-op ``event`` by default): ``event(t, y, p, out)`` writes
N_EV values; event ``i`` happens where ``out[i]`` changes sign in the direction the model
declares (``mechsim.systems.base.Event``). ``dop853_advance`` evaluates them after every
accepted step, locates the earliest crossing on the dense output by bracketed root finding
(to ~1e-14 relative in t), writes the outputs up to it, leaves the state there and returns
status EVENT with the event's index in ``st[8]``; the Python stepper calls the model's
``handle_event`` and restarts. Discrete modes: the last N_MODE state entries, with zero
derivative (``rhs`` leaves them untouched); kernel functions read them as ``y[2 * N_Q + 2 + i]``
to switch their equations (e.g. a constraint that is active only in contact).
"""

from __future__ import annotations

import numpy as np

N_Q = 1
N_Y = 4
N_C = 0
N_INV = 0
N_OBS = 0
N_FRAMES = 0
N_EV = 0
N_MODE = 0


def rhs(t: float, y: np.ndarray, p: np.ndarray, dy: np.ndarray) -> None:
    """dy = d/dt [q, v, work_external, work_dissipated]."""


def project(t: float, y: np.ndarray, p: np.ndarray) -> None:
    """Move q and v onto the constraint manifold in place (no-op without constraints)."""


def accel_q(t: float, q: np.ndarray, p: np.ndarray, a: np.ndarray) -> None:
    """Acceleration of a separable system, a function of q only."""


def energy(t: float, y: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """out = [kinetic, potential, energy_function]."""


def invariants(t: float, y: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """out[N_INV] = invariant values (constraint residuals included)."""


def observables(t: float, y: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """out[N_OBS] = observable values."""


def frames(t: float, y: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """out[N_FRAMES, 7] = translation xyz and quaternion xyzw of each frame in its parent."""


def event(t: float, y: np.ndarray, p: np.ndarray, out: np.ndarray) -> None:
    """out[N_EV] = event functions; a sign change (in the declared direction) is an event."""


def to_momenta(t: float, y: np.ndarray, p: np.ndarray, z: np.ndarray) -> None:
    """z = [q, ∂L/∂q̇, rest of y]: canonical variables of an unconstrained system."""


def from_momenta(t: float, z: np.ndarray, p: np.ndarray, y: np.ndarray) -> None:
    """The inverse of to_momenta: q̇ from M(q, t) q̇ = p − ∂L/∂q̇|_{q̇=0}."""


def canonical_rhs(t: float, z: np.ndarray, p: np.ndarray, dz: np.ndarray) -> None:
    """Hamilton's equations of a conservative system: q̇ = q̇(q, p), ṗ = ∂L/∂q at (q, q̇)."""
