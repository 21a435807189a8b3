"""``auto``: the method a run gets when it names none. It chooses only among methods that meet
the tolerance over the horizon (the adaptive ones: their steps follow the tolerance), the
fastest first, and passes what it decides to the stepper's constructor:

- with ``closed_form``, ``exact`` wherever the model has a closed form;
- with dissipation, ``dop853`` (errors decay with the motion, and damping can make the
  equations stiff, where DOP853 notices and radau15's fixed-point iteration would crawl);
- ``radau15`` below ``RADAU_TOLERANCE`` (DOP853 would need local tolerances at round-off) or
  beyond ``LONG_HORIZON`` time scales (DOP853's error, growing with every step, outruns the
  tolerance while radau15 stays at round-off);
- else ``dop853``, unless a probe shows its error outgrowing the tolerance over the horizon
  (chaotic motion amplifying every error): then ``radau15`` with the finest ε of its range.

The fixed-step symplectic methods are for whoever asks for their energy behaviour by name.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from mechsim.errors import IntegrationError
from mechsim.integrators.base import Request, Stepper
from mechsim.integrators.closed_form import ClosedForm
from mechsim.integrators.dop853 import DOP853
from mechsim.integrators.model import SteppableModel as Model
from mechsim.integrators.radau15 import Radau15


class Auto:
    """The choice of ``auto`` (see the module docstring); not a stepper itself: ``create``
    makes the stepper of the method it chooses."""

    method: ClassVar[str] = "auto"
    #: radau15 below this tolerance.
    RADAU_TOLERANCE: ClassVar[float] = 1e-10
    #: radau15 for horizons longer than this many time scales.
    LONG_HORIZON: ClassVar[float] = 100.0

    @classmethod
    def check(cls, model: Model) -> None:
        """``auto`` fits every model."""

    @classmethod
    def choose(cls, model: Model, closed_form: bool = False, tolerance: float = 1e-10,
               horizon: float | None = None) -> type[Stepper]:
        """The method for ``model`` before the probe (see the module docstring)."""
        if closed_form and model.has_closed_form():
            return ClosedForm
        if model.structure.dissipative:
            return DOP853
        long = horizon is not None and horizon > cls.LONG_HORIZON * model.time_scale()
        return Radau15 if tolerance < cls.RADAU_TOLERANCE or long else DOP853

    @classmethod
    def decide(cls, model: Model, y0: np.ndarray, t0: float, tolerance: float,
               request: Request) -> tuple[type[Stepper], float, dict[str, Any]]:
        """The method, the tolerance its stepper is made with and its options: what
        ``create`` makes (see the module docstring)."""
        chosen = cls.choose(model, request.closed_form, tolerance, request.horizon)
        if chosen is DOP853 and not model.structure.dissipative:
            pick = _dop853_ladder(model, y0, t0, tolerance, request.horizon,
                                  not request.given_state)
            if pick is None:
                # Errors amplified by the motion: radau15 at its finest (round-off) setting.
                return Radau15, tolerance, {"eps": Radau15.EPS_RANGE[0]}
            return DOP853, pick, DOP853.options(request)
        return chosen, tolerance, chosen.options(request)

    @classmethod
    def create(cls, model: Model, y0: np.ndarray, t0: float, tolerance: float,
               request: Request) -> Stepper:
        """The stepper of the chosen method, with the options ``auto`` decided."""
        method, local, options = cls.decide(model, y0, t0, tolerance, request)
        return method(model, y0, t0, local, **options)


#: What the probes found for each model (by start time, tolerance and horizon, from the
#: model's initial state): a model's parameters never change, so neither does the answer.
_DECISIONS: weakref.WeakKeyDictionary[Model, dict[tuple[float, float, float],
                                                  float | None]] = weakref.WeakKeyDictionary()


@dataclass(frozen=True)
class _Probe:
    """One probe run: its rows at the probe times and the evaluations it took."""

    rows: np.ndarray
    cost: int


def _probe_errors(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """The error of rows ``a`` against the better rows ``b`` at each probe time, relative to
    the scale of b's coordinates and of its rates."""
    err = np.zeros(a.shape[0])
    for lo, hi in ((0, n), (n, 2 * n)):
        scale = max(float(np.max(np.abs(b[:, lo:hi]))), 1e-300)
        err = np.maximum(err, np.max(np.abs(a[:, lo:hi] - b[:, lo:hi]), axis=1) / scale)
    return err


def projected_error(err: np.ndarray, span: float, horizon: float) -> float:
    """The error at the end of ``horizon`` from the errors at 16 probe times over ``span``:
    the largest error up to half the probe and up to its end (an oscillating error's samples
    alone would misjudge its growth); linear growth is extrapolated linearly, faster growth
    (chaotic motion amplifying every error) exponentially."""
    e = (float(np.max(err[:8])), float(np.max(err)))
    if e[1] <= 2.5 * e[0] or e[0] == 0.0:
        return e[1] * horizon / span
    return e[1] * (e[1] / e[0]) ** ((horizon - span) / (0.5 * span))


def _ladder(tolerance: float) -> list[float]:
    """The tolerances below ``tolerance`` the ladder tries, a decade apart down to
    ``RADAU_TOLERANCE``, rounded to 12 digits so that the ladders of tolerances a decade
    apart share their rungs (1e-4 / 10 is 1e-5, not 1.0000000000000002e-05)."""
    rungs = []
    k = 1
    while (s := float(f"{tolerance * 10.0**-k:.12g}")) >= Auto.RADAU_TOLERANCE:
        rungs.append(s)
        k += 1
    return rungs


def _dop853_ladder(model: Model, y0: np.ndarray, t0: float, tolerance: float,
                   horizon: float | None, cacheable: bool) -> float | None:
    """The tolerance DOP853 is to run at so that it ends the horizon (ten time scales if not
    given) within ``tolerance``, or None where radau15 at its finest is the cheaper way.

    Probe runs over four time scales (chaos in the double pendulum shows only after three):
    DOP853 at a tolerance s and at s/100 give the error of the run at s and how it grows
    (``projected_error``). First s = ``tolerance``: where that meets it (its projected error
    within half the tolerance), DOP853 runs at the tolerance. Otherwise the ladder goes on
    down the decades s = tolerance/10, /100, … to ``RADAU_TOLERANCE``, as long as a probe at
    s costs no more evaluations than radau15's at its finest (run once, as the alternative),
    and DOP853 runs at the first s that meets the tolerance, else radau15 does. A looser
    tolerance walks the same ladder from higher up, so its choice never costs more: the
    choice is monotone in the tolerance. Costs about a run of ten time scales, once per
    model, start, tolerance and horizon."""
    tau = model.time_scale()
    H = horizon if horizon is not None else 10.0 * tau
    key = (t0, tolerance, H)
    known = _DECISIONS.get(model, {}) if cacheable else {}
    if key in known:
        return known[key]
    span = min(4.0 * tau, H)
    probe = t0 + span * np.arange(1, 17) / 16
    n = len(model.coordinates)
    runs: dict[float, _Probe | None] = {}

    def run(s: float) -> _Probe | None:
        if s not in runs:
            try:
                st = DOP853(model, y0, t0, s)
                runs[s] = _Probe(st.advance(probe), st.n_evaluations)
            except IntegrationError:
                runs[s] = None
        return runs[s]

    def meets(s: float) -> bool | None:
        a, b = run(s), run(0.01 * s)
        if a is None or b is None:
            return None
        return projected_error(_probe_errors(a.rows, b.rows, n), span, H) <= 0.5 * tolerance

    first = meets(tolerance)
    pick: float | None = tolerance
    if first is False:
        pick = None
        try:
            radau = Radau15(model, y0, t0, tolerance, eps=Radau15.EPS_RANGE[0])
            radau.advance(probe)
            budget = radau.n_evaluations
        except IntegrationError:
            budget = None
        for s in _ladder(tolerance):
            got = run(s)
            if got is None or (budget is not None and got.cost > budget):
                break
            if meets(s):
                pick = s
                break
    # (a probe that fails lets the run itself say what is wrong: DOP853 at the tolerance)
    if cacheable:
        _DECISIONS.setdefault(model, {})[key] = pick
    return pick
