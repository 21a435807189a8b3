"""The benchmark problem (``Problem``: an initial-value problem of one mechsim system with its
reference solution and errors, described in ``mechsim.bench.problems``) and the
extended-precision references of the problems without a closed form."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mechsim.simulate import output_times

Array = np.ndarray
Deriv = Callable[[float, Array, Array, Array], None]


@dataclass
class Problem:
    """One IVP of one system (see the module docstring for states and errors)."""

    name: str
    system: str
    params: dict[str, Any]
    t_end: float
    n_samples: int
    description: str
    deriv: Deriv  # deriv(t, y, p, dy): dy = dy/dt, scalar math (plain Python and numba)
    p: Array
    y0: Array
    reference: Callable[[Array], Array]  # times (m,) -> problem states (m, len(y0))
    reference_kind: str
    period: float  # a characteristic period: fixed-step peers count steps per period
    conserved: Callable[[Array, Array], Array] | None = None  # (t, C) -> quantity per row
    conserved_name: str | None = None
    peers: tuple[str, ...] = ("scipy", "handwritten")
    accel: Deriv | None = None  # accel(t, q, p, a): q̈ when it does not depend on q̇
    linear: Array | None = None  # A with dy/dt = A y
    compare: Callable[[Array], Array] | None = None  # problem states -> compared states
    from_mechsim: Callable[[Any, Array, Array], Array] | None = None  # (model, t, rows) -> C
    sign_free: slice | None = None  # columns of C that may flip sign as a block (quaternion)
    extra: dict[str, Any] = field(default_factory=dict)
    _ref_cache: Array | None = None

    def rhs(self, t: float, y: Array) -> Array:
        """dy/dt as a new array: the signature scipy's ``solve_ivp`` expects."""
        dy = np.empty(y.shape)
        self.deriv(t, y, self.p, dy)
        return dy

    def times(self) -> Array:
        return output_times(self.t_end, self.t_end / self.n_samples)

    def compared(self, Y: Array) -> Array:
        """Problem states -> compared states."""
        return Y if self.compare is None else self.compare(Y)

    def mechsim_compared(self, model: Any, t: Array, rows: Array) -> Array:
        """mechsim's output rows ``[q, v, work terms, ...]`` -> compared states."""
        if self.from_mechsim is not None:
            return self.from_mechsim(model, t, rows)
        return self.compared(rows[:, : self.y0.size])

    def reference_states(self) -> Array:
        """The reference in compared states at the sample times (computed once)."""
        if self._ref_cache is None:
            self._ref_cache = self.compared(self.reference(self.times()))
        return self._ref_cache

    def state_scale(self) -> float:
        """Largest ‖C_ref(t)‖ over the samples: state errors are relative to it."""
        return float(np.max(np.linalg.norm(self.reference_states(), axis=1)))

    def errors(self, Y: Array) -> dict[str, float | None]:
        """Errors of a run given in problem states."""
        if Y.shape != (self.times().size, self.y0.size) or not np.all(np.isfinite(Y)):
            return self._diverged()
        return self.compared_errors(self.compared(Y))

    def compared_errors(self, C: Array) -> dict[str, float | None]:
        """End-point and max-over-run state error (relative to ``state_scale``) and the max
        relative drift of the conserved quantity (None if the problem has none), of a run
        given in compared states."""
        ref = self.reference_states()
        if C.shape != ref.shape or not np.all(np.isfinite(C)):
            return self._diverged()
        if self.sign_free is not None:
            flip = np.sum(C[:, self.sign_free] * ref[:, self.sign_free], axis=1) < 0
            C = C.copy()
            C[flip, self.sign_free] *= -1.0
        d = np.linalg.norm(C - ref, axis=1) / self.state_scale()
        out: dict[str, float | None] = {"end_error": float(d[-1]), "max_error": float(d.max()),
                                        "invariant_error": None}
        if self.conserved is not None:
            c = self.conserved(self.times(), C)
            c_ref = self.conserved(self.times()[:1], ref[:1])[0]
            scale = float(self.extra.get("conserved_scale", abs(c_ref) or 1.0))
            out["invariant_error"] = float(np.max(np.abs(c - c_ref)) / scale)
        return out

    def _diverged(self) -> dict[str, float | None]:
        return {"end_error": math.inf, "max_error": math.inf,
                "invariant_error": math.inf if self.conserved else None}


# --- extended-precision reference -------------------------------------------------------------
EXTENDED = bool(np.finfo(np.longdouble).eps < 1e-18)


def _fixed_dop853_longdouble(rhs: Callable[[Array], Array], y0: Array, t: Array,
                             h_max: float) -> Array:
    """States at ``t`` (as ``np.longdouble``) from a fixed-step run of the DOP853 tableau on an
    autonomous ``rhs(y)`` written with numpy functions (so that it keeps ``np.longdouble``);
    a whole number of steps of at most ``h_max`` between samples."""
    from scipy.integrate._ivp import dop853_coefficients as dc

    L = np.longdouble
    A, B = dc.A.astype(L), dc.B.astype(L)
    ns = dc.N_STAGES
    y = np.asarray(y0, dtype=L)
    K = np.empty((ns, y.size), dtype=L)
    out = np.empty((t.size, y.size), dtype=L)
    out[0] = y
    for i in range(1, t.size):
        gap = L(t[i]) - L(t[i - 1])
        k = max(1, math.ceil(float(gap) / h_max))
        h = gap / k
        for _ in range(k):
            K[0] = rhs(y)
            for j in range(1, ns):
                K[j] = rhs(y + h * (A[j, :j] @ K[:j]))
            y = y + h * (B @ K)
        out[i] = y
    return out


def _radau_tight(rhs: Callable[[float, Array], Array], y0: Array, t: Array) -> Array:
    """scipy Radau at rtol = atol = 1e-14: the fallback where long double is plain double."""
    import warnings

    from scipy.integrate import solve_ivp

    with warnings.catch_warnings():  # rtol below 100 ε is raised to it: fine here
        warnings.simplefilter("ignore")
        sol = solve_ivp(rhs, (0.0, float(t[-1])), y0, method="Radau", t_eval=t,
                        rtol=1e-14, atol=1e-14)
    if not sol.success:
        raise RuntimeError(sol.message)
    return sol.y.T.copy()


_FALLBACK = "scipy Radau @ rtol=atol=1e-14 (error ~1e-12: no long double here)"
