"""The drift of conservation laws over epochs: one :class:`LawState` per law of a system, and
its tracking over consecutive samples, vectorised over the laws and the samples
(:func:`track`), or over a run of samples reported piece by piece (:func:`track_prefixes`).

A law's drift is its ``Law.drift`` from the epoch's first finite value, relative to the law's
scale; the worst drift of a finite sample this epoch sets the level, a non-finite sample is
counted and never taken as the initial value or a drift.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from mechsim.systems.base import Law


@dataclass
class LawState:
    """One law of one system, over the current epoch."""

    law: Law
    scale: float
    initial: float | None = None
    current: float = 0.0
    drift: float = 0.0
    max_drift: float = 0.0  # worst drift of a finite sample this epoch
    samples: int = 0  # all epochs
    nonfinite: int = 0  # non-finite samples this epoch
    finite_now: bool = True  # the latest sample is finite

    @property
    def key(self) -> str:
        return self.law.key

    @property
    def worst(self) -> float:
        """Worst drift of the epoch, infinite if a sample was not finite."""
        return math.inf if self.nonfinite else self.max_drift

    def rebase(self) -> None:
        self.initial = None
        self.drift = self.max_drift = 0.0
        self.nonfinite = 0
        self.finite_now = True

    def update(self, values: Any) -> None:
        """Take the law's values of consecutive samples of one epoch (a float or an array):
        the drift of each finite one from the epoch's first finite value."""
        v = np.asarray(values, dtype=float).reshape(1, -1)
        if v.size:
            track([self], v)


def track(laws: list[LawState], values: np.ndarray) -> None:
    """Take consecutive samples of one epoch for several laws at once: row i of ``values``
    (laws × samples, float) holds law i's values; each finite one drifts from its law's first
    finite value of the epoch. Vectorised over the laws and the samples; a non-finite sample
    is counted, never taken as the initial value or a drift."""
    m = values.shape[1]
    finite = np.isfinite(values)
    all_finite = bool(finite.all())
    if any(law.initial is None for law in laws):
        if all_finite:
            first = values[:, 0].tolist()
            present = [True] * len(laws)
        else:
            present = finite.any(axis=1).tolist()
            first = values[np.arange(len(laws)), finite.argmax(axis=1)].tolist()
        for i, law in enumerate(laws):
            if law.initial is None and present[i]:
                law.initial = first[i]
    drifts = _drifts(laws, values)
    if all_finite:
        worst = drifts.max(axis=1).tolist()
        last_finite = [True] * len(laws)
        nonfinite = [0] * len(laws)
    else:
        worst = np.where(finite, drifts, -math.inf).max(axis=1).tolist()
        last_finite = finite[:, -1].tolist()
        nonfinite = (m - finite.sum(axis=1)).tolist()
    last = drifts[:, -1].tolist()
    current = values[:, -1].tolist()
    for i, law in enumerate(laws):
        law.samples += m
        law.current = current[i]
        law.finite_now = last_finite[i]
        law.nonfinite += nonfinite[i]
        law.drift = last[i] if last_finite[i] else math.inf
        if worst[i] > -math.inf:  # some sample was finite
            law.max_drift = max(law.max_drift, worst[i])


def _drifts(laws: list[LawState], values: np.ndarray) -> np.ndarray:
    """The drift of every sample (laws × samples) from its law's initial value; -inf for a
    law without one yet. Law.drift depends on the law only through is_constraint (a residual
    has no initial value): one call per such group, on its rows, initial values and scales
    as columns."""
    drifts = np.empty_like(values)
    groups: dict[bool, list[int]] = {}
    for i, law in enumerate(laws):
        if law.initial is None:
            drifts[i] = -math.inf  # no finite value yet: no drift to take
        else:
            groups.setdefault(law.law.is_constraint, []).append(i)
    for rows in groups.values():
        kind = laws[rows[0]].law
        if len(rows) == 1:
            i = rows[0]
            drifts[i] = kind.drift(values[i], laws[i].initial, laws[i].scale)
            continue
        initial = np.array([[laws[i].initial] for i in rows])
        scale = np.array([[laws[i].scale] for i in rows])
        if len(rows) == len(laws):
            drifts[:] = kind.drift(values, initial, scale)
        else:
            drifts[rows] = kind.drift(values[rows], initial, scale)
    return drifts


def track_prefixes(laws: list[LawState], values: np.ndarray, ends: list[int]
                   ) -> Iterator[None] | None:
    """:func:`track` of the pieces ``values[:, a:b]`` for consecutive ends b in ``ends``
    (increasing, the last at most the number of samples), each piece taken when the iterator
    is advanced (a report in between sees the laws as after that piece), computed once for
    all of them: the drifts of every sample, and their running maximum. The same values as
    piece by piece. None where that shortcut does not apply (a non-finite sample, a law
    without an initial value yet): then take the pieces with :func:`track`."""
    if not laws or any(law.initial is None for law in laws) \
            or not bool(np.isfinite(values).all()):
        return None
    drifts = _drifts(laws, values)
    worst = np.maximum.accumulate(drifts, axis=1)
    at = np.maximum(np.asarray(ends, dtype=np.int64) - 1, 0)  # (a first piece may be empty)
    return _prefixes(laws, ends, values[:, at].T.tolist(), drifts[:, at].T.tolist(),
                     worst[:, at].T.tolist())


def _prefixes(laws: list[LawState], ends: list[int], current: list[list[float]],
              drift: list[list[float]], worst: list[list[float]]) -> Iterator[None]:
    done = 0
    max0 = [law.max_drift for law in laws]
    for k, end in enumerate(ends):
        m, done = end - done, end
        if m == 0:
            yield
            continue
        for i, law in enumerate(laws):
            law.samples += m
            law.current = current[k][i]
            law.finite_now = True
            law.drift = drift[k][i]
            law.max_drift = max(max0[i], worst[k][i])
        yield
