"""What every stress case shares: its result record, the drifts of a run's laws as the
diagnostics node measures them, and a run that turns a refusal into an explanation."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mechsim.errors import MechsimError
from mechsim.simulate import SimulationResult, simulate
from mechsim.systems.base import LEVEL_NAMES, Law, Model

WARN_DRIFT = Law.WARN_DRIFT  # the diagnostics node's defaults
ERROR_DRIFT = Law.ERROR_DRIFT
ROUND_OFF = 1e-11  # drifts below this are round-off: no growth law to fit


@dataclass
class Result:
    case: str
    system: str
    variant: str
    passed: bool
    outcome: str  # one line: what happened and why it passes or fails
    criterion: str
    metrics: dict[str, Any] = field(default_factory=dict)
    series: dict[str, Any] = field(default_factory=dict)  # plots (downsampled)
    wall: float = 0.0

    def as_dict(self) -> dict[str, Any]:
        return {"case": self.case, "system": self.system, "variant": self.variant,
                "passed": self.passed, "outcome": self.outcome, "criterion": self.criterion,
                "metrics": _jsonable(self.metrics), "wall_s": round(self.wall, 3)}


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.generic):
        x = x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return repr(x)
    return x


def _down(t: np.ndarray, y: np.ndarray, n: int = 400) -> tuple[list[float], list[float]]:
    idx = np.unique(np.linspace(0, t.size - 1, min(n, t.size)).astype(int))
    return [float(v) for v in t[idx]], [float(v) for v in y[idx]]


# --- drift, as the diagnostics node measures it ---------------------------------------------
def law_values(model: Model, run: SimulationResult) -> dict[str, np.ndarray]:
    """Time series of the quantity each law of ``model`` keeps (``Law.value``)."""
    return {law.key: run.law_value(law) for law in model.laws()}


def drifts(model: Model, run: SimulationResult, growing: bool = False
           ) -> dict[str, np.ndarray]:
    """Relative drift of each law (``Law.drift``). ``growing``: the scale at each sample is
    also at least the running magnitude of the terms involved (energy, work terms, the value
    itself), so unbounded motions (a falling Atwood machine, a projectile) are judged against
    the numbers the integrator actually carries, not the initial energy alone."""
    scales = model.law_scales()
    out = {}
    terms = np.maximum.accumulate(np.maximum.reduce(
        [np.abs(run.kinetic), np.abs(run.potential), np.abs(run.work_external),
         np.abs(run.work_dissipated)])) if growing else 0.0
    for law in model.laws():
        v = run.law_value(law)
        s: float | np.ndarray = scales[law.key] if scales[law.key] > 0 else 1.0
        if growing:
            own = np.maximum.accumulate(np.abs(v))
            s = np.maximum(s, np.maximum(own, terms) if law.kind != "invariant" else own)
        d = law.drift(v, v[0], s)
        out[law.key] = np.where(np.isfinite(d), d, np.inf)
    return out


def worst(d: dict[str, np.ndarray], skip_constraints: bool = False) -> tuple[str, float]:
    items = [(k, float(np.max(v))) for k, v in d.items()
             if not (skip_constraints and Law.from_key(k).is_constraint)]
    if not items:
        return "", 0.0
    return max(items, key=lambda kv: kv[1])


def level_of(drift: float, key: str) -> str:
    """The level the diagnostics node gives law ``key`` at ``drift`` (default thresholds)."""
    return LEVEL_NAMES[Law.from_key(key).level(drift)] if key else LEVEL_NAMES[0]


def attempt(model: Model, t_end: float, output_dt: float, *, method: str = "auto",
            tolerance: float = 1e-10, step: float | None = None,
            outputs: tuple[str, ...] = ("energy", "invariants")
            ) -> tuple[SimulationResult | None, str | None, float]:
    """Run, turning a MechsimError into an explanation; anything else propagates (a bug)."""
    start = time.perf_counter()
    try:
        run = simulate(model, t_end=t_end, output_dt=output_dt, tolerance=tolerance,
                       method=method, outputs=outputs, step=step)
    except MechsimError as e:
        return None, f"{type(e).__name__}: {e}", time.perf_counter() - start
    return run, None, time.perf_counter() - start


def _variant(kw: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v}" for k, v in kw.items()) or "defaults"
