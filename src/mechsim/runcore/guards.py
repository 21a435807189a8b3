"""Guards: what stops one system's run cleanly instead of publishing garbage.

- a non-finite state (checked on every sample before it is evaluated or released);
- a failed step (the stepper raises, also from an extreme parameter value; ``SystemRun``);
- an enforced constraint residual past the hard limit: the stepper projects the state onto the
  constraints, so residuals stay at round-off; one past ``constraint_limit`` relative to
  ``max(1, max|q|)`` (a residual of 1 % of the configuration's size by default) means the
  state is garbage.

A guard that fires keeps the samples before the bad one; the run releases them, then stops with
the reason (last good state kept).
"""

from __future__ import annotations

import numpy as np

from mechsim.systems.base import Model


def enforced_constraints(model: Model) -> list[int]:
    """Indices (among the invariants) of the residuals the stepper enforces: the hard-limit
    guard watches them."""
    if model.structure.n_constraints <= 0:
        return []
    names = [q.name for q in model.invariants]
    return [names.index(law.name) for law in model.laws()
            if law.is_constraint and law.name in names]


def finite_rows(times: np.ndarray, Y: np.ndarray) -> tuple[int, str | None]:
    """(rows before the first non-finite state, the reason to stop there or None)."""
    if np.isfinite(Y).all():
        return times.size, None
    good = int(np.argmin(np.all(np.isfinite(Y), axis=1)))
    return good, f"non-finite state at t = {times[good]:.6g}"


def within_limit(times: np.ndarray, q: np.ndarray, invariants: np.ndarray,
                 constraints: list[int], names: tuple[str, ...],
                 limit: float) -> tuple[int, str] | None:
    """The first row whose enforced residual (columns ``constraints`` of ``invariants``) is
    not finite or past ``limit · max(1, max|q|)``, with the reason; None if every row holds."""
    r = invariants[:, constraints]
    bound = limit * np.maximum(1.0, np.max(np.abs(q), axis=1))
    bad = ~np.all(np.isfinite(r) & (np.abs(r) <= bound[:, None]), axis=1)
    if not bad.any():
        return None
    good = int(np.argmax(bad))
    j = constraints[int(np.argmax(~(np.isfinite(r[good]) & (np.abs(r[good]) <= bound[good]))))]
    return good, (f"constraint residual {names[j]} = {invariants[good, j]:.3g} past the hard "
                  f"limit {bound[good]:.3g} at t = {times[good]:.6g} (projection cannot "
                  "restore the constraint)")
