"""Time series and moving transforms of a recording, buffered per entity and sent as columns
(``send_columns``), a few thousand rows at a time: no per-message logging cost and no
``log_time`` timeline."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mechsim.outputs.rerun.entities import TIMELINE

#: Rows an entity buffers before they are sent.
FLUSH_ROWS = 4096


@dataclass
class Series:
    """Buffered rows of one entity: times [ns of sim time] and values, in pieces of rows."""

    kind: str  # "scalar" | "transform" (rows x y z qx qy qz qw) | "strip" (rows (2, 3))
    times: list[np.ndarray] = field(default_factory=list)
    values: list[np.ndarray] = field(default_factory=list)
    buffered: int = 0
    rows: int = 0


class Buffers:
    """Every entity's buffered rows, sent to the recording stream ``rec``."""

    def __init__(self, rec: Any) -> None:
        self.rec = rec
        self.series: dict[str, Series] = {}
        self.peaks: dict[str, float] = {}  # entity -> largest |value| sent (scalars)

    def scalars(self, entity: str, t: np.ndarray, values: np.ndarray) -> None:
        """Rows of a scalar entity (anything not finite drawn as NaN)."""
        self.append(entity, "scalar", t, np.where(np.isfinite(values), values, math.nan))

    def append(self, entity: str, kind: str, t: np.ndarray, values: np.ndarray) -> None:
        s = self.series.get(entity)
        if s is None:
            s = self.series[entity] = Series(kind)
        s.times.append(t)
        s.values.append(values)
        s.buffered += len(t)
        if s.buffered >= FLUSH_ROWS:
            self.flush(entity)

    def flush(self, entity: str) -> None:
        import rerun as rr

        s = self.series[entity]
        if not s.buffered:
            return
        times = np.concatenate(s.times)
        values = np.concatenate(s.values)
        index = [rr.TimeColumn(TIMELINE, duration=times.astype("timedelta64[ns]"))]
        if s.kind == "scalar":
            finite = np.abs(values[np.isfinite(values)])
            if finite.size:
                self.peaks[entity] = max(self.peaks.get(entity, 0.0), float(finite.max()))
            columns: Any = rr.Scalars.columns(scalars=values)
        elif s.kind == "transform":
            columns = rr.Transform3D.columns(translation=values[:, :3].astype(np.float32),
                                             quaternion=values[:, 3:].astype(np.float32))
        else:
            columns = rr.LineStrips3D.columns(strips=values.astype(np.float32))
        self.rec.send_columns(entity, indexes=index, columns=columns)
        s.rows += s.buffered
        s.times, s.values, s.buffered = [], [], 0

    def flush_all(self) -> None:
        for entity in list(self.series):
            self.flush(entity)

    def rows(self, entity: str) -> int:
        """Rows sent or buffered so far for ``entity`` (a path without leading '/')."""
        s = self.series.get(entity)
        return 0 if s is None else s.rows + s.buffered
