"""Where mechsim's integration time goes: per-call cost of a model's generated kernels against
hand-written numba equivalents, and the share of a run spent outside the compiled loop.

``python -m mechsim.bench.kernel_profile [PROBLEM ...] [--out FILE.md]`` (benchmark problems
of :mod:`mechsim.bench.problems`; default kepler, pendulum).

Measured, per problem:
- ns per call of the model's ``rhs`` and ``accel_q`` (called N times from a compiled loop,
  so no Python dispatch), and of a hand-written kernel with the same physics;
- the cost of the two heap allocations the generated ``rhs`` makes (``np.empty`` for the
  multipliers and accelerations), and of ``x ** (3/2)`` against ``x * sqrt(x)``;
- for one benchmark run per method: total wall time, calls × ns/call of the force kernel,
  and the rest (step logic, dense output, Python set-up in ``make_stepper``).
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from typing import Any

import numpy as np
from numba import njit

from mechsim.files import write_atomic


@njit(cache=False)
def _loop4(f, t, y, p, out, n):  # type: ignore[no-untyped-def]
    s = 0.0
    for _ in range(n):
        y[0] += 1e-12  # defeat hoisting
        f(t, y, p, out)
        s += out[out.size - 1] if out.size > 0 else 0.0
    return s


@njit(cache=False)
def _alloc2(t, y, p, out):  # type: ignore[no-untyped-def]
    lam = np.empty(1)
    acc = np.empty(2)
    acc[0] = y[0]
    lam[0] = y[1]
    out[0] = acc[0] + lam[0]


@njit(cache=False)
def _pow15(t, y, p, out):  # type: ignore[no-untyped-def]
    r2 = y[0] * y[0] + y[1] * y[1]
    out[0] = p[0] / r2 ** (3 / 2)


@njit(cache=False)
def _sqrt15(t, y, p, out):  # type: ignore[no-untyped-def]
    r2 = y[0] * y[0] + y[1] * y[1]
    out[0] = p[0] / (r2 * math.sqrt(r2))


@njit(cache=False)
def _noop(t, y, p, out):  # type: ignore[no-untyped-def]
    out[0] = y[0]


def ns_per_call(f: Any, y: np.ndarray, p: np.ndarray, out: np.ndarray, n: int = 200_000,
                repeats: int = 7) -> float:
    _loop4(f, 0.0, y.copy(), p, out, 10)  # compile
    ts = []
    for _ in range(repeats):
        yy = y.copy()
        t0 = time.perf_counter()
        _loop4(f, 0.0, yy, p, out, n)
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts) / n * 1e9


def profile_system(name: str) -> dict[str, Any]:
    """Kernel costs and the split of one run per method, for benchmark problem ``name``; the
    hand-written kernels are the problem's own ``deriv`` and ``accel`` (the ones the
    hand-written peers run), compiled with numba."""
    from mechsim.bench.peers import _jit
    from mechsim.bench.problems import problem
    from mechsim.bench.run import stepper_counts
    from mechsim.errors import ParameterError
    from mechsim.integrators import choose_method, make_stepper
    from mechsim.systems import load_system

    pb = problem(name)
    model = load_system(pb.system, **pb.params)
    k = model.kernels
    y = model.initial_y()
    p = model.parameter_vector()
    nq = len(model.coordinates)
    dy = np.zeros(y.size)
    a = np.zeros(nq)
    hy, hq = pb.y0.copy(), pb.y0[: pb.y0.size // 2].copy()
    ns: dict[str, float] = {
        "model rhs": ns_per_call(k.rhs, y, p, dy),
        "hand rhs": ns_per_call(_jit(pb.deriv), hy, pb.p, np.zeros(hy.size))}
    if hasattr(k, "accel_q"):
        ns["model accel_q"] = ns_per_call(k.accel_q, y[:nq].copy(), p, a)
    if pb.accel is not None:
        ns["hand accel_q"] = ns_per_call(_jit(pb.accel), hq, pb.p, np.zeros(hq.size))
    ns.update({"2 × np.empty (as in generated rhs)": ns_per_call(_alloc2, y, p, dy),
               "x ** (3/2)": ns_per_call(_pow15, y, p, dy),
               "x * sqrt(x)": ns_per_call(_sqrt15, y, p, dy),
               "empty call (loop overhead)": ns_per_call(_noop, y, p, dy)})
    r: dict[str, Any] = {"system": name, "ns": ns}
    runs = []
    t = pb.times()
    for method, tol in (("dop853", 1e-10), ("yoshida8", 1e-10), ("yoshida6", 1e-10)):
        try:
            choose_method(model, method)
        except ParameterError:
            continue
        make_stepper(model, method, tol).advance(t)  # warm
        walls, setups = [], []
        for _ in range(5):
            t0 = time.perf_counter()
            st = make_stepper(model, method, tol)
            t1 = time.perf_counter()
            st.advance(t)
            walls.append(time.perf_counter() - t0)
            setups.append(t1 - t0)
        wall = statistics.median(walls)
        calls = stepper_counts(st) or 0
        kind = "rhs" if method == "dop853" else "accel_q"
        per = ns.get(f"model {kind}", math.nan)
        hand = ns.get(f"hand {kind}", math.nan)
        runs.append({"method": method, "tolerance": tol, "wall_ms": wall * 1e3,
                     "make_stepper_ms": statistics.median(setups) * 1e3,
                     "steps": st.n_steps, "force_calls": calls,
                     "in_force_kernel_ms": calls * per * 1e-6,
                     "with_hand_kernel_ms": calls * hand * 1e-6,
                     "rest_ms": wall * 1e3 - calls * per * 1e-6})
    r["runs"] = runs
    return r


def markdown(results: list[dict[str, Any]]) -> str:
    out = ["# Where mechsim's time goes", "",
           "ns per call from a compiled loop (median of 7 × 200k calls), and the split of one "
           "benchmark run (median of 5). All numbers measured in the run that wrote this file.",
           ""]
    for r in results:
        out += [f"## {r['system']}", "", "| kernel | ns/call |", "|---|---|"]
        out += [f"| {k} | {v:.1f} |" for k, v in r["ns"].items()]
        out += ["", "| method | tol | wall [ms] | make_stepper [ms] | steps | force calls | "
                "in force kernel [ms] | same calls, hand kernel [ms] | rest [ms] |",
                "|---|---|---|---|---|---|---|---|---|"]
        out += [f"| {x['method']} | {x['tolerance']:g} | {x['wall_ms']:.2f} | "
                f"{x['make_stepper_ms']:.3f} | {x['steps']} | {x['force_calls']} | "
                f"{x['in_force_kernel_ms']:.2f} | {x['with_hand_kernel_ms']:.2f} | "
                f"{x['rest_ms']:.2f} |" for x in r["runs"]]
        out.append("")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m mechsim.bench.kernel_profile")
    ap.add_argument("problems", nargs="*", default=["kepler", "pendulum"])
    ap.add_argument("--out")
    a = ap.parse_args(argv)
    text = markdown([profile_system(s) for s in a.problems])
    if a.out:
        write_atomic(a.out, text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
