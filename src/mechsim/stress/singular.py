"""Stress case 4: singular and near-singular configurations (an inverted pendulum,
pericentre passages and a fall to the centre, a top at θ = 0, frames at a curve's cusp, steep
wires, a spring through zero length, a −a/r³ fall): each run either keeps its laws or stops
with an explanation, never silently wrong."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from mechsim.ensemble import simulate_many
from mechsim.errors import MechsimError
from mechsim.simulate import SimulationResult
from mechsim.stress.common import (
    WARN_DRIFT,
    Result,
    _variant,
    attempt,
    drifts,
    level_of,
    worst,
)
from mechsim.systems import load_system
from mechsim.systems.base import Model


def _generic(system: str, kw: dict[str, Any], t_end: float, dt: float, crit: str,
             check: Callable[[Model, SimulationResult], tuple[bool, str, dict[str, Any]]],
             method: str = "auto", tolerance: float = 1e-10,
             error_ok: bool = False) -> Result:
    try:
        model = load_system(system, **kw)
    except MechsimError as e:
        return Result("singular", system, _variant(kw), error_ok,
                      f"rejected at load: {e}", crit, {"error": str(e)})
    run, err, wall = attempt(model, t_end, dt, method=method, tolerance=tolerance,
                             outputs=("energy", "invariants", "frames"))
    if run is None:
        return Result("singular", system, f"{_variant(kw)}; {method}", error_ok,
                      f"stopped with an explanation: {err}", crit, {"error": err}, wall=wall)
    ok, why, m = check(model, run)
    m.setdefault("steps", run.n_steps)
    return Result("singular", system, f"{_variant(kw)}; {run.method}", ok, why, crit, m,
                  wall=wall)


def _laws_kept(limit: float) -> Callable[[Model, SimulationResult],
                                         tuple[bool, str, dict[str, Any]]]:
    def check(model: Model, run: SimulationResult) -> tuple[bool, str, dict[str, Any]]:
        key, w = worst(drifts(model, run))
        return w < limit, f"laws kept: worst drift {w:.1e} [{key}] ({run.n_steps:,} steps)", \
            {"worst_law": key, "worst_drift": w}
    return check


def _pendulum(quick: bool) -> list[Result]:
    out: list[Result] = []
    crit = ("inverted (angle = π): stays up until round-off tips it, falls, laws kept "
            "(worst drift < 1e-8); the tipping time is reported")
    for form in ("reduced", "multiplier"):
        def check(model: Model, run: SimulationResult) -> tuple[bool, str, dict[str, Any]]:
            ang = run.coordinate("angle") if "angle" in [c.name for c in
                                                          model.coordinates] else None
            if ang is None:  # Cartesian (y, z): the bob's height
                z = run.coordinate("z")
                off = np.abs(z - z[0]) / model.value("length")
            else:
                off = np.abs(np.abs(ang) - math.pi)
            t_tip = float(run.t[np.argmax(off > 1e-3)]) if np.any(off > 1e-3) else math.inf
            key, w = worst(drifts(model, run))
            how = (f"balanced until t = {t_tip:.2f} s (round-off grows as e^(t√(g/l))), "
                   "then swings" if math.isfinite(t_tip) else
                   "balanced for the whole run (sin π = 1.2e-16 is the only push, and a "
                   "symmetric step keeps it from growing within 20 s)")
            return w < 1e-8, f"{how}; worst drift {w:.1e} [{key}]", \
                {"t_tip": t_tip, "worst_drift": w, "worst_law": key}
        out.append(_generic("pendulum", {"formulation": form, "initial.angle": math.pi},
                             20.0, 0.01, crit, check))
    return out


def _references(models: list[Model], t_end: float, dt: float
                ) -> dict[Model, tuple[SimulationResult | None, str | None, float]]:
    """DOP853 runs at tolerance 1e-12 of ``models`` (one system, different parameters) as
    ``attempt`` gives them: in one ensemble (``simulate_many``; each member is its single run
    bit for bit), or one by one where a member stops (its own explanation)."""
    try:
        many = simulate_many(models[0], t_end, dt, method="dop853", tolerance=1e-12,
                             parameters=[m.values for m in models],
                             outputs=("energy", "invariants"))
    except MechsimError:
        return {m: attempt(m, t_end, dt, method="dop853", tolerance=1e-12) for m in models}
    runs = [many.member(i) for i in range(len(models))]
    for m, run in zip(models, runs, strict=True):
        run.model = m
    return {m: (run, None, run.wall_time) for m, run in zip(models, runs, strict=True)}


def _kepler(quick: bool) -> list[Result]:
    system = "kepler"
    out: list[Result] = []
    crit = ("pericentre passages r_p = a(1 − e): DOP853 keeps E, L, A (worst drift < 1e-6); "
            "auto's fixed step is either accurate or flagged (drift ≥ warn): a silent wrong "
            "orbit (position off the DOP853 reference by > 1 % with drift < warn) fails")
    es = (0.99, 0.999) if quick else (0.99, 0.999, 0.9999)
    auto_es = (0.99,) if quick else (0.99, 0.999)  # auto's fixed step: 57 M steps at 0.999
    t_end = 5 * 2 * math.pi
    refs = _references([load_system("kepler", eccentricity=e) for e in es], t_end, 0.01)
    for e, (model, (ref, err, wall)) in zip(es, refs.items(), strict=True):
        if ref is None:
            out.append(Result("singular", system, f"e={e}; dop853", False, f"{err}", crit))
            continue
        key, w = worst(drifts(model, ref))
        out.append(Result("singular", system, f"e={e}; dop853", w < 1e-6,
                          f"5 orbits, {ref.n_steps:,} steps: worst drift {w:.1e} [{key}]",
                          crit, {"worst_drift": w, "worst_law": key, "steps": ref.n_steps},
                          wall=wall))
        if e not in auto_es:
            continue
        run, err, wall = attempt(model, t_end, 0.01, method="auto")
        if run is None:
            out.append(Result("singular", system, f"e={e}; auto", True,
                              f"stopped with an explanation: {err}", crit))
            continue
        key, w = worst(drifts(model, run))
        pos = float(np.max(np.linalg.norm(run.q - ref.q, axis=1)))
        silent = pos > 1e-2 and w < WARN_DRIFT
        out.append(Result("singular", system, f"e={e}; {run.method}", not silent,
                          f"{run.n_steps:,} fixed steps: worst drift {w:.1e} [{key}] → "
                          f"{level_of(w, key)}; position error {pos:.1e} vs DOP853"
                          + (" (silent garbage)" if silent else ""), crit,
                          {"worst_drift": w, "level": level_of(w, key), "position_error": pos,
                           "steps": run.n_steps}, wall=wall))
    crit2 = ("fall to the centre (−μ/r² with e → 1, r_p = 1e-10 a): a graceful stop with "
             "a reason, or laws kept")
    model = load_system("kepler", eccentricity=1 - 1e-10)
    run, err, wall = attempt(model, 2 * math.pi, 0.01, method="dop853")
    if run is None:
        out.append(Result("singular", system, "e=1-1e-10; dop853", True,
                          f"stopped with an explanation: {err}", crit2, {"error": err},
                          wall=wall))
    else:
        key, w = worst(drifts(model, run))
        out.append(Result("singular", system, "e=1-1e-10; dop853", bool(np.isfinite(w)),
                          f"survived the near-collision ({run.n_steps:,} steps): worst "
                          f"drift {w:.1e} [{key}] → {level_of(w, key)}", crit2,
                          {"worst_drift": w, "level": level_of(w, key), "steps": run.n_steps},
                          wall=wall))
    return out


def _symmetric_top(quick: bool) -> list[Result]:
    out: list[Result] = []
    crit = ("heavy top near θ = 0: the quaternion form has no singularity (laws kept, "
            "drift < 1e-6); the Euler-angle form may stop, but only with an explanation, "
            "or keep its laws")
    for theta in (1e-6, 0.0):
        out.append(_generic("symmetric_top", {"formulation": "quaternion",
                                              "initial.theta": theta}, 2.0, 0.01, crit,
                            _laws_kept(1e-6)))

        def check_e(model: Model, run: SimulationResult) -> tuple[bool, str, dict[str, Any]]:
            key, w = worst(drifts(model, run))
            return bool(np.isfinite(w)), (f"integrated through θ ≈ 0: worst drift {w:.1e} "
                                          f"[{key}] → {level_of(w, key)}"), \
                {"worst_drift": w, "level": level_of(w, key)}
        out.append(_generic("symmetric_top", {"formulation": "euler_angles",
                                              "initial.theta": theta}, 2.0, 0.01, crit,
                            check_e, error_ok=True))
    return out


def _moving_frames(quick: bool) -> list[Result]:
    out: list[Result] = []
    crit = ("twisted cubic through the origin (u = 0, r = 0: RIC radial axis undefined): "
            "frames stay finite unit quaternions, or the model explains")

    def check_f(model: Model, run: SimulationResult) -> tuple[bool, str, dict[str, Any]]:
        fr = run.outputs.frames
        assert fr is not None
        finite = bool(np.all(np.isfinite(fr)))
        norms = np.linalg.norm(fr[..., 3:], axis=-1) if fr.size else np.ones(1)
        unit = bool(np.all(np.abs(norms - 1) < 1e-9)) if finite else False
        key, w = worst(drifts(model, run))
        return finite and unit, (f"frames at u = 0 finite: {finite}, unit quaternions: "
                                 f"{unit}; worst drift {w:.1e} [{key}]"), \
            {"frames_finite": finite, "unit_quaternions": unit, "worst_drift": w}
    for u0 in (0.0, -1e-9):
        out.append(_generic("moving_frames", {"initial.curve_parameter": u0}, 1.0, 0.01,
                            crit, check_f))
    return out


def _bead_on_wire(quick: bool) -> list[Result]:
    out: list[Result] = []
    crit = ("steep wire (slope 10³ line, 100-curvature parabola from a 200:1 wall): laws "
            "kept (worst drift < 1e-6), constraint at round-off in the multiplier form")
    for kw in ({"shape": "line", "slope": -1e3},
               {"shape": "parabola", "curvature": 100.0},
               {"formulation": "multiplier", "shape": "parabola", "curvature": 100.0}):
        out.append(_generic("bead_on_wire", kw, 2.0, 0.005, crit, _laws_kept(1e-6)))
    return out


def _central_force(quick: bool) -> list[Result]:
    out: list[Result] = []
    crit = ("−a/r³ fall to the centre (a > L²/μ): a graceful end (capture event, or a stop "
            "with a reason), never non-finite numbers published")

    def check_c(model: Model, run: SimulationResult) -> tuple[bool, str, dict[str, Any]]:
        finite = bool(np.all(np.isfinite(np.hstack([run.q, run.v]))))
        key, w = worst(drifts(model, run))
        return finite, (f"events {[n for _, n in run.events]}; worst drift {w:.1e} "
                        f"[{key}] → {level_of(w, key)}"), {"events": len(run.events),
                                                     "worst_drift": w, "finite": finite}
    for form in ("cartesian", "polar"):
        out.append(_generic("central_force", {"formulation": form,
                                              "potential": "inverse_cube",
                                              "inverse_cube_strength": 2.0}, 10.0, 0.01,
                            crit, check_c, error_ok=True))
    return out


def _spring_pendulum(quick: bool) -> list[Result]:
    out: list[Result] = []
    crit = "spring through zero length (l + x → 0, polar r = 0 singular): explained or kept"

    def check_s(model: Model, run: SimulationResult) -> tuple[bool, str, dict[str, Any]]:
        key, w = worst(drifts(model, run))
        return bool(np.isfinite(w)), (f"passed r ≈ 0: worst drift {w:.1e} [{key}] → "
                                      f"{level_of(w, key)}"), {"worst_drift": w,
                                                          "level": level_of(w, key)}
    out.append(_generic("spring_pendulum", {"initial.extension": -1.0, "initial.angle": 0.0,
                                            "initial_rate.extension": 0.5}, 1.0, 0.01,
                        crit, check_s, error_ok=True))
    return out


#: Each system's singular configurations, by system.
_CASES: dict[str, Callable[[bool], list[Result]]] = {
    "pendulum": _pendulum,
    "kepler": _kepler,
    "symmetric_top": _symmetric_top,
    "moving_frames": _moving_frames,
    "bead_on_wire": _bead_on_wire,
    "spring_pendulum": _spring_pendulum,
    "central_force": _central_force,
}
SINGULAR = tuple(_CASES)


def singular(system: str, quick: bool) -> list[Result]:
    """The singular and near-singular configurations of ``system`` (none for a system
    without them)."""
    case = _CASES.get(system)
    return case(quick) if case is not None else []
