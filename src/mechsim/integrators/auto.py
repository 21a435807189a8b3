"""``auto``: the method a run gets when it names none. It chooses only among methods that meet
the tolerance over the horizon (the adaptive ones: their steps follow the tolerance), the
fastest first, and passes what it decides to the stepper's constructor:

- with ``closed_form``, ``exact`` wherever the model has a closed form;
- with dissipation, ``dop853`` (errors decay with the motion, and damping can make the
  equations stiff, where DOP853 notices and radau15's fixed-point iteration would crawl);
  ``dop853`` too for a state of momenta (a Hamiltonian formulation: not second order);
- ``radau15`` below ``RADAU_TOLERANCE`` (DOP853 would need local tolerances at round-off) or
  beyond ``LONG_HORIZON`` time scales (DOP853's error, growing with every step, outruns the
  tolerance while radau15 stays at round-off);
- else ``dop853``, unless a probe shows its error outgrowing the tolerance over the horizon
  (chaotic motion amplifying every error): then ``dop853`` at the loosest of the tighter
  tolerances τ/10, τ/100, ... (down to ``RADAU_TOLERANCE``) that the probe shows meeting its
  own tolerance, hence τ; where none does, ``radau15`` with the finest ε of its range
  (``dop853`` at ``FINEST_TOLERANCE`` for a state of momenta). A looser tolerance so never
  gets a costlier choice than a tighter one of the same ladder (no cliff where the probe
  judges one tolerance harder than the next tighter one).

The fixed-step symplectic methods are for whoever asks for their energy behaviour by name.
"""

from __future__ import annotations

import weakref
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
    #: The ratio of one tolerance of DOP853's ladder to the one before (a decade).
    LADDER_STEP: ClassVar[float] = 0.1
    #: DOP853's tolerance where the probe sees errors amplified and radau15 does not apply.
    FINEST_TOLERANCE: ClassVar[float] = 1e-14

    @classmethod
    def check(cls, model: Model) -> None:
        """``auto`` fits every model."""

    @classmethod
    def choose(cls, model: Model, closed_form: bool = False, tolerance: float = 1e-10,
               horizon: float | None = None) -> type[Stepper]:
        """The method for ``model`` before the probe (see the module docstring)."""
        if closed_form and model.has_closed_form():
            return ClosedForm
        if model.structure.dissipative or not model.structure.second_order:
            return DOP853
        long = horizon is not None and horizon > cls.LONG_HORIZON * model.time_scale()
        return Radau15 if tolerance < cls.RADAU_TOLERANCE or long else DOP853

    @classmethod
    def decide(cls, model: Model, y0: np.ndarray, t0: float, tolerance: float,
               request: Request) -> tuple[type[Stepper], float, dict[str, Any]]:
        """The method, the tolerance its stepper is made with and its options: what
        ``create`` makes."""
        chosen = cls.choose(model, request.closed_form, tolerance, request.horizon)
        if chosen is not DOP853 or model.structure.dissipative:
            return chosen, tolerance, chosen.options(request)
        local = tolerance
        while local >= cls.RADAU_TOLERANCE:
            if _dop853_meets(model, y0, t0, local, request.horizon, not request.given_state):
                return DOP853, local, DOP853.options(request)
            local *= cls.LADDER_STEP
        # Errors amplified by the motion: radau15 at its finest (round-off) setting; for a
        # state of momenta, which radau15 does not take, DOP853 at the finest tolerance.
        if not model.structure.second_order:
            return DOP853, cls.FINEST_TOLERANCE, {}
        return Radau15, tolerance, {"eps": Radau15.EPS_RANGE[0]}

    @classmethod
    def create(cls, model: Model, y0: np.ndarray, t0: float, tolerance: float,
               request: Request) -> Stepper:
        """The stepper of the chosen method, with the options ``auto`` decided."""
        method, local, options = cls.decide(model, y0, t0, tolerance, request)
        return method(model, y0, t0, local, **options)


#: Decisions of ``_dop853_meets`` for each model (by tolerance and horizon, from its initial
#: state): a model's parameters never change, so neither does the answer.
_DECISIONS: weakref.WeakKeyDictionary[Model, dict[tuple[float, float], bool]] = (
    weakref.WeakKeyDictionary())


def _dop853_meets(model: Model, y0: np.ndarray, t0: float, tolerance: float,
                  horizon: float | None, cacheable: bool) -> bool:
    """Whether DOP853 will end the horizon (ten time scales if not given) within the
    tolerance: two probe runs over four time scales (chaos in the double pendulum shows only
    after three), at the tolerance and a hundred times tighter, give DOP853's error and how
    it grows; linear growth is extrapolated linearly, faster growth (chaotic motion
    amplifying every error) exponentially. Costs about a run of ten time scales, once per
    model, tolerance and horizon."""
    tau = model.time_scale()
    H = horizon if horizon is not None else 10.0 * tau
    key = (tolerance, H)
    if cacheable and key in _DECISIONS.get(model, {}):
        return _DECISIONS[model][key]
    span = min(4.0 * tau, H)
    probe = t0 + span * np.arange(1, 17) / 16
    try:
        a = DOP853(model, y0, t0, tolerance).advance(probe)
        b = DOP853(model, y0, t0, 0.01 * tolerance).advance(probe)
    except IntegrationError:
        return True  # let the run itself say what is wrong
    n = len(model.coordinates)
    err = np.zeros(probe.size)
    for lo, hi in ((0, n), (n, 2 * n)):
        scale = max(float(np.max(np.abs(b[:, lo:hi]))), 1e-300)
        err = np.maximum(err, np.max(np.abs(a[:, lo:hi] - b[:, lo:hi]), axis=1) / scale)
    # The largest error up to half the probe and up to its end (an oscillating error's
    # samples alone would misjudge its growth).
    e = (float(np.max(err[:8])), float(np.max(err)))
    if e[1] <= 2.5 * e[0] or e[0] == 0.0:
        projected = e[1] * H / span
    else:
        projected = e[1] * (e[1] / e[0]) ** ((H - span) / (0.5 * span))
    meets = bool(projected <= 0.5 * tolerance)
    if cacheable:
        _DECISIONS.setdefault(model, {})[key] = meets
    return meets
