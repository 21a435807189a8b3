"""The names of the kernel contract (numba-free, so that they can be imported cheaply; the
signatures and the kernel set are in ``contract.py``)."""

from __future__ import annotations

#: The functions of the kernel contract, in the order of the kernel set.
FUNCTIONS = ("rhs", "project", "accel_q", "energy", "invariants", "observables", "frames",
             "event", "to_momenta", "from_momenta", "canonical_rhs")
#: Called from the loops through raw pointers (see ``contract.POINTER_SIGNATURE``).
HOT = ("rhs", "canonical_rhs")
#: The model's sizes, as module constants of a kernel module (upper case) and fields of the
#: kernel set (lower case): coordinates, state entries (2 N_Q + 2 + N_MODE), constraints,
#: invariants, observables, frames, events, discrete modes, parameters.
SIZES = ("N_Q", "N_Y", "N_C", "N_INV", "N_OBS", "N_FRAMES", "N_EV", "N_MODE", "N_P")
