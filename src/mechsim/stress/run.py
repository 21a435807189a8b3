"""Run the stress catalogue and write the report: ``stress.json``, ``stress.md`` and PNG plots
(drift against time for the long horizons, separations for chaos, sweep errors, action
variations)."""

from __future__ import annotations

import json
import math
import platform
import sys
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np

from mechsim.errors import MechsimError, UnknownSystemError
from mechsim.files import write_atomic


def _log(text: str) -> None:
    print(f"mechsim stress: {text}", file=sys.stderr, flush=True)


def run_stress(systems: list[str] | None, *, quick: bool, out: str | Path,
               cases: list[str] | None = None) -> dict[str, Any]:
    from mechsim.stress.cases import Result, plan
    from mechsim.systems import system_ids

    known = system_ids()
    for s in systems or []:
        if s not in known:
            raise UnknownSystemError(s, known)
    out_dir = Path(out)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        probe = out_dir / ".write_test"
        probe.write_text("")
        probe.unlink()
    except OSError as e:
        raise MechsimError(f"--out {out_dir}: cannot write ({e.strerror or e})") from None
    todo = plan(systems, quick, cases)
    results: list[Result] = []
    start = time.perf_counter()
    for i, (case, system) in enumerate(todo, 1):
        t0 = time.perf_counter()
        try:
            from mechsim.stress.cases import CASES
            got = CASES[case].run(system, quick)
        except Exception as e:  # noqa: BLE001 - a crash is a failed case, reported with its cause
            tb = traceback.format_exception_only(type(e), e)[-1].strip()
            got = [Result(case, system, "?", False, f"crashed: {tb}", "no crash")]
        for r in got:
            r.wall = r.wall or (time.perf_counter() - t0)
            results.append(r)
            _log(f"[{i}/{len(todo)}] {case} {system} ({r.variant}): "
                 f"{'PASS' if r.passed else 'FAIL'} — {r.outcome}")
    report = build_report(results, quick=quick, wall=time.perf_counter() - start)
    write_report(report, results, out_dir)
    s = report["summary"]
    _log(f"{s['passed']}/{s['results']} passed ({s['failed']} failed) in "
         f"{report['wall_s']:.1f} s; report in {out_dir}")
    return report


def build_report(results: list[Any], *, quick: bool, wall: float) -> dict[str, Any]:
    long = [r for r in results if r.case == "long_horizon" and "steps" in r.metrics]
    steps = sum(int(r.metrics.get("steps", 0)) for r in results)
    worst = sorted(((r.metrics["worst_drift"], r.system, r.metrics.get("worst_law", ""))
                    for r in long if isinstance(r.metrics.get("worst_drift"), float)),
                   reverse=True)
    summary = {
        "results": len(results), "passed": sum(r.passed for r in results),
        "failed": sum(not r.passed for r in results),
        "cases": sorted({r.case for r in results}),
        "systems": sorted({r.system for r in results}),
        "steps_total": steps,
        "long_horizon_min_steps": min((int(r.metrics["steps"]) for r in long), default=0),
        "long_horizon_max_steps": max((int(r.metrics["steps"]) for r in long), default=0),
        "worst_long_horizon_drifts": [{"system": s, "law": k, "drift": d}
                                      for d, s, k in worst[:5]],
    }
    return {"quick": quick, "wall_s": wall, "python": platform.python_version(),
            "machine": platform.machine(), "summary": summary,
            "results": [r.as_dict() for r in results]}


def write_report(report: dict[str, Any], results: list[Any], out: Path) -> None:
    write_atomic(out / "stress.json", json.dumps(report, indent=1, ensure_ascii=False,
                                                 allow_nan=False, default=str) + "\n")
    figures = plot(results, out)
    write_atomic(out / "stress.md", markdown(report, figures))


def _fmt(x: Any) -> str:
    if isinstance(x, float):
        return "∞" if math.isinf(x) else f"{x:.3g}"
    return str(x)


def markdown(report: dict[str, Any], figures: list[str]) -> str:
    s = report["summary"]
    lines = [f"# mechsim stress report{' (quick)' if report['quick'] else ''}", "",
             f"{s['passed']} of {s['results']} results pass ({s['failed']} fail); "
             f"{len(s['cases'])} cases on {len(s['systems'])} systems; "
             f"{s['steps_total']:,} integration steps; {report['wall_s']:.0f} s wall "
             f"(Python {report['python']}, {report['machine']}).", ""]
    if s["worst_long_horizon_drifts"]:
        lines += ["Worst long-horizon drifts (relative, as the diagnostics node measures):", ""]
        lines += [f"- {w['system']} {w['law']}: {w['drift']:.3g}"
                  for w in s["worst_long_horizon_drifts"]]
        lines.append("")
    by_case: dict[str, list[dict[str, Any]]] = {}
    for r in report["results"]:
        by_case.setdefault(r["case"], []).append(r)
    for case, rs in by_case.items():
        lines += [f"## {case}", "", f"Criterion: {rs[0]['criterion']}", "",
                  "| system | variant | result | outcome |", "|---|---|---|---|"]
        for r in rs:
            outcome = r["outcome"].replace("|", "\\|").replace("\n", " ")
            lines.append(f"| {r['system']} | {r['variant']} | "
                         f"{'pass' if r['passed'] else '**FAIL**'} | {outcome} |")
        lines.append("")
    if figures:
        lines += ["## Figures", ""] + [f"![{f}]({f})" for f in figures] + [""]
    return "\n".join(lines)


#: The figure each case draws (``plot``), by case name.
FIGURES = {"long_horizon": "long_horizon_drift.png", "chaos": "chaos.png",
           "sweeps": "sweeps.png", "hamilton": "hamilton.png"}


def plot(results: list[Any], out: Path) -> list[str]:
    """Draw the figure of each case that has results with series; the names written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    drawers = {"long_horizon": _plot_long_horizon, "chaos": _plot_chaos,
               "sweeps": _plot_sweeps, "hamilton": _plot_hamilton}
    written = []
    for case, draw in drawers.items():
        mine = [r for r in results if r.case == case and r.series]
        if not mine:
            continue
        fig = draw(plt, mine)
        _save(fig, out / FIGURES[case])
        plt.close(fig)
        written.append(FIGURES[case])
    return written


def _save(fig: Any, path: Path) -> None:
    """The figure as PNG, written through a temporary and an atomic rename."""
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    write_atomic(path, buf.getvalue())


def _plot_long_horizon(plt: Any, long: list[Any]) -> Any:
    n = len(long)
    cols = min(4, n)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4 * cols, 2.8 * rows), squeeze=False)
    for ax, r in zip(axes.flat, long, strict=False):
        t = list(r.series["t"])
        d = [max(x, 1e-17) for x in r.series["drift"]]
        ax.loglog(t[1:], d[1:], lw=1, label=f"{r.series['law']} ({r.metrics.get('method')})")
        ax.set_title(f"{r.system} ({r.metrics.get('method')}, "
                     f"{r.metrics.get('steps', 0):.2g} steps)", fontsize=8)
        ax.set_xlabel("simulated time t [s]", fontsize=7)
        ax.set_ylabel("largest relative drift so far [1]", fontsize=7)
        ax.tick_params(labelsize=6)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, loc="lower right")
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    fig.tight_layout()
    return fig


def _plot_chaos(plt: Any, chaos: list[Any]) -> Any:
    fig, axes = plt.subplots(1, len(chaos), figsize=(6 * len(chaos), 3.5), squeeze=False)
    for ax, r in zip(axes.flat, chaos, strict=False):
        # The series hold log10 of values floored at 1e-300 (separations) or 1e-17
        # (drifts): a floored point is an exact zero, not a number to draw.
        for key, label, floor in (("log_sep_ic", "ICs 1e-9 apart: |Δy|", -299.0),
                                  ("log_sep_tol", "tolerance 1e-10 vs 1e-13: |Δy|", -299.0),
                                  ("log_drift", f"{r.metrics['law']}: relative drift",
                                   -16.9)):
            y = np.asarray(r.series[key], dtype=float)
            ax.plot(r.series["t"], np.where(y > floor, y, np.nan), label=label)
        ax.set_title(f"{r.system}: λ ≈ {r.metrics['lyapunov_exponent']:.3f}/s", fontsize=9)
        ax.set_xlabel("simulated time t [s]")
        ax.set_ylabel("log10 (|Δy| in state units; drift relative)")
        ax.legend(fontsize=7)
        ax.grid(True, alpha=0.3)
    fig.tight_layout()
    return fig


#: Colours of the diagnostics levels and markers of the methods in the sweeps' figure.
_LEVEL_COLOURS = {"OK": "tab:green", "WARN": "tab:orange", "ERROR": "tab:red",
                  "ERROR (guard)": "tab:purple"}
_METHOD_MARKERS = {"dop853": "o", "verlet": "s", "yoshida8": "^"}


def _plot_sweeps(plt: Any, sw: list[Any]) -> Any:
    """Per system: the end error of the state against DOP853's tolerance (left) and against
    the fixed step of the symplectic methods (right); each point's colour is the level the
    diagnostics node gave that run, its marker the method."""
    from matplotlib.lines import Line2D

    fig, axes = plt.subplots(len(sw), 2, figsize=(10, 3.0 * len(sw) + 0.8), squeeze=False)
    for row, r in zip(axes, sw, strict=True):
        drawn = set()
        for meth, marker in _METHOD_MARKERS.items():
            ax = row[0] if meth == "dop853" else row[1]
            knob = "tolerance" if meth == "dop853" else "step"
            pts = [p for p in r.series["points"] if p["method"] == meth and "state_error" in p]
            if not pts:
                continue
            drawn.add(ax)
            x = [p[knob] for p in pts]
            y = [max(p["state_error"], 1e-17) if math.isfinite(p["state_error"]) else 1e3
                 for p in pts]
            ax.loglog(x, y, "-", color="gray", lw=0.5)
            for xi, yi, p in zip(x, y, pts, strict=True):
                ax.loglog(xi, yi, marker, color=_LEVEL_COLOURS.get(p["level"], "k"))
        for ax, what in ((row[0], "DOP853 tolerance [1]"), (row[1], "fixed step h [s]")):
            ax.set_title(f"{r.system}: end error against {what.split(' [')[0]}", fontsize=8)
            if ax not in drawn:
                ax.axis("off")
                ax.text(0.5, 0.5, f"{r.system}: no fixed-step method\n(not a separable "
                        "Hamiltonian)", ha="center", va="center", fontsize=8,
                        transform=ax.transAxes)
                continue
            ax.axhline(1e-2, color="k", ls=":", lw=0.8)
            ax.set_xlabel(what)
            ax.set_ylabel("end error of the state,\nrelative to its scale [1]")
            ax.grid(True, which="both", alpha=0.3)
    handles = [Line2D([], [], ls="", marker=m, color="k", label=meth)
               for meth, m in _METHOD_MARKERS.items()]
    handles += [Line2D([], [], ls="", marker="o", color=c, label=f"diagnostics: {lv}")
                for lv, c in _LEVEL_COLOURS.items()]
    handles.append(Line2D([], [], ls=":", color="k", label="error 1e-2 (must be WARN or ERROR)"))
    fig.legend(handles=handles, loc="upper center", ncol=4, fontsize=7,
               title="marker: method; colour: level on /diagnostics", title_fontsize=7)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.8 / (3.0 * len(sw) + 0.8)))
    return fig


def _plot_hamilton(plt: Any, ham: list[Any]) -> Any:
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    palette = plt.get_cmap("tab20").colors
    styles = ("-", "--", ":", "-.")
    for i, r in enumerate(ham):  # distinct colour (and dash once the 20 colours repeat)
        look = {"color": palette[i % len(palette)], "ls": styles[i // len(palette) % 4]}
        axes[0].loglog(r.series["eps"], [max(x, 1e-300) for x in r.series["dS"]],
                       marker="o", ms=3, label=r.system, **look)
        axes[1].loglog(r.series["eps"], [max(x, 1e-300) for x in r.series["dS_control"]],
                       marker="o", ms=3, label=r.system, **look)
    axes[0].set_title("trajectory: |ΔS| ∝ ε²", fontsize=9)
    axes[1].set_title("bent path (control): |ΔS| ∝ ε", fontsize=9)
    for ax in axes:
        ax.set_xlabel("variation amplitude ε (state units)")
        ax.set_ylabel("|ΔS| [J s]")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=5, ncol=2)
    fig.tight_layout()
    return fig
