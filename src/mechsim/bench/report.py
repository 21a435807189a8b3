"""Markdown tables, the summary and the work-precision plots of a benchmark result."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

from mechsim.files import write_atomic


def _e(x: float | None) -> str:
    return "—" if x is None else f"{x:.1e}"


def _ms(x: float | None) -> str:
    if x is None:
        return "—"
    return f"{x * 1e3:.3g}" if x < 1 else f"{x * 1e3:,.0f}"


def summary_rows(res: dict[str, Any]) -> list[list[str]]:
    rows = []
    for sid, s in res["systems"].items():
        for lv, m in s["matched"].items():
            ms, pe, sc = m["mechsim"], m["peer"], m["scipy"]
            if not (ms or pe):
                continue

            def who(x: dict[str, Any] | None) -> str:
                if not x:
                    return "not reached"
                return f"{x['contestant']} {'≤' if x['bound'] else ''}{_ms(x['time_s'])} ms"
            rows.append([sid, lv, who(ms), who(pe),
                         "—" if m["speedup_vs_peer"] is None else f"{m['speedup_vs_peer']:.2f}×",
                         who(sc) if sc and pe and sc["contestant"] != pe["contestant"] else
                         ("(same)" if sc else "not reached"),
                         "—" if m["speedup_vs_scipy"] is None
                         else f"{m['speedup_vs_scipy']:.1f}×"])
    return rows


SUMMARY_HEAD = ["problem", "end error", "mechsim fastest", "best peer", "peer/mechsim",
                "best scipy", "scipy/mechsim"]


def _table(head: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def summary_text(res: dict[str, Any]) -> str:
    rows = summary_rows(res)
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h)
              for i, h in enumerate(SUMMARY_HEAD)]
    out = ["", "Speed at matched end-point error (time to reach it; ratios > 1: mechsim faster)"]
    out.append("  ".join(h.ljust(w) for h, w in zip(SUMMARY_HEAD, widths, strict=True)))
    out += ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    if res.get("targets"):
        out.append("\nTargets:")
        for t in res["targets"]:
            mark = {True: "PASS", False: "MISS", None: "n/a "}[t["passed"]]
            out.append(f"  {mark} {t['system']}: {t['target']} — {t['detail']}")
    if res["peers"]["missing"]:
        out.append("Peers missing (see above): " + ", ".join(res["peers"]["missing"]))
    return "\n".join(out)


def markdown(res: dict[str, Any]) -> str:
    h = res["host"]
    st = res["settings"]
    out = ["# mechsim work-precision benchmark", "",
           f"Run {res['created']}{' (--quick)' if res['quick'] else ''} on {h['cpu']} "
           f"({h['cores']} cores), Python {h['python']}, numpy {h['numpy']}, scipy "
           f"{h['scipy']}, numba {h['numba']}; env {h['env'] or '{}'}; load average "
           f"{h['loadavg_start'][0]:.1f} at start, {h.get('loadavg_end', ['?'])[0]} at end "
           "(1 min; the machine is shared, so times are noisy). Peers found: "
           + (", ".join(f"{k} {v}" for k, v in res["peers"]["found"].items()) or "none")
           + ". " + "".join(f"Missing: {k} ({v}). " for k, v in res["peers"]["missing"].items())
           + f"Time: median of {st['repeats']} runs (up to 21 for runs under 0.1 s) after a "
           "warm-up run (a run over "
           f"{st['budget_s']:g} s is timed once and ends its sweep); then the runs each "
           "matched-error comparison is read from are timed again together, in rounds of a "
           "burst of each in turn (the last run of each burst timed), and their time is the "
           "median over the rounds. Errors: ‖[q, v] − ref‖ / "
           "max‖ref‖ at the last sample (end) and over all samples (max); invariant: max "
           "relative drift of the conserved quantity. All numbers are from this run.", "",
           "## Summary: time to reach an end-point error", "",
           _table(SUMMARY_HEAD, summary_rows(res)), "",
           "`≤`: the contestant's loosest run was already more accurate than the level (its time "
           "is an upper bound). Times are interpolated log-log on each contestant's Pareto front.",
           ""]
    if res.get("targets"):
        out += ["## Targets", ""]
        out += [f"- **{ {True: 'PASS', False: 'MISS', None: 'n/a'}[t['passed']] }** "
                f"{t['system']}: {t['target']} — {t['detail']}" for t in res["targets"]]
        out.append("")
    for sid, s in res["systems"].items():
        pb = s["problem"]
        c = s["compile"]
        cold = c["cold_s"]
        out += [f"## {sid}", "", f"mechsim system `{pb.get('system', sid)}`: "
                f"{pb['description']}; {pb['n_samples']} samples; reference: "
                f"{pb['reference']}; conserved: {pb['conserved'] or 'none'}.", "",
                f"Model build in the benchmark process: {c['load_s']:.2f} s; first call "
                "per contestant (kernel load or JIT, imports; not in the sweep): "
                + ", ".join(f"{k} {v:.3f} s" for k, v in c["first_call_s"].items())
                + (". Cold (empty kernel cache, new process, imports included): "
                   + ", ".join(f"{k} {v:.1f} s" for k, v in cold.items()) if cold else "")
                + ".", "", f"![work-precision]({sid}.png)", ""]
        head = ["contestant", "knob", "setting", "time [ms]", "warm-up [ms]", "end error",
                "max error", "invariant", "steps", "f evals", "status"]
        rows = []
        shown: set[str] = set()
        for r in s["runs"]:
            same = [x for x in s["runs"] if x["contestant"] == r["contestant"]]
            if all(x["status"] == same[0]["status"] != "ok" for x in same):
                if r["contestant"] not in shown:  # one line for a method that never applies
                    shown.add(r["contestant"])
                    rows.append([r["contestant"], r["knob"], "all"] + ["—"] * 7
                                + [r["status"]])
                continue
            rows.append([r["contestant"] + (f" ({r['method']})" if r.get("method") and
                                            r["contestant"].endswith("auto") else ""),
                         r["knob"], f"{r['setting']:g}", _ms(r["time_s"]), _ms(r["warmup_s"]),
                         _e(r["end_error"]), _e(r["max_error"]), _e(r["invariant_error"]),
                         "—" if r["n_steps"] is None else str(r["n_steps"]),
                         "—" if r["n_rhs"] is None else str(r["n_rhs"]),
                         (f"ok (same run as {r['same_as']})" if r.get("same_as")
                          else r["status"] if r["repeats"] != 1 else "ok (timed once)")])
        out += [_table(head, rows), ""]
    return "\n".join(out)


FAMILY_STYLE = {  # (line style, marker, line width) per family; colours are per contestant
    "mechsim": ("-", "o", 2.0), "scipy": ("--", "s", 1.0), "handwritten": (":", "^", 1.3),
    "expm": ("", "*", 1.0), "rebound": ("-.", "D", 1.0), "mujoco": ("--", "v", 1.0),
    "drake": ("-.", "P", 1.0)}


ZERO_AT = 1e-17  # an error of exactly 0 (a closed form) is drawn here: a log axis has no 0


def palette(n: int) -> list[Any]:
    """``n`` distinct colours (qualitative maps first, then evenly spaced hues)."""
    from matplotlib import colormaps

    cols: list[Any] = []
    for name in ("tab10", "Dark2", "Set1", "tab20b"):
        for c in colormaps[name].colors:  # type: ignore[attr-defined]
            if c not in cols:
                cols.append(c)
    if n > len(cols):
        hsv = colormaps["hsv"]
        cols += [hsv(i / (n - len(cols) + 1)) for i in range(n - len(cols))]
    return cols[:n]


def plot(res: dict[str, Any], sid: str, path: Path) -> None:
    """Write :func:`figure` of problem ``sid`` to ``path``."""
    import matplotlib.pyplot as plt

    fig = figure(res, sid)
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    write_atomic(path, buf.getvalue())


def figure(res: dict[str, Any], sid: str) -> Any:
    """Work-precision figure of one problem: wall time against end-point error (top) and
    against the conserved quantity's drift (bottom). Each contestant keeps one colour, used
    by no other contestant, and each panel's legend lists exactly its own lines."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = res["systems"][sid]
    conserved = s["problem"].get("conserved")
    names = list(dict.fromkeys(r["contestant"] for r in s["runs"]))
    colour = dict(zip(names, palette(len(names)), strict=True))
    fig, axes = plt.subplots(2, 1, figsize=(10, 9), dpi=80)
    panels = ((axes[0], "end_error", "end-point state error, relative to the state scale "
               "(dimensionless)", "time to reach an end-point error"),
              (axes[1], "invariant_error", f"max relative drift of the {conserved or 'invariant'}"
               " (dimensionless)", f"time against the drift of the {conserved or 'invariant'}"))
    for ax, key, xlabel, title in panels:
        for name in names:
            rows = [r for r in s["runs"] if r["contestant"] == name]
            pts = sorted((max(r[key], ZERO_AT), r["time_s"]) for r in rows
                         if r["status"] == "ok" and r[key] is not None and 0 <= r[key] <= 10)
            if not pts:
                continue
            label = name + (f" (error 0 drawn at {ZERO_AT:g})" if pts[0][0] == ZERO_AT
                            else "")
            ls, marker, lw = (("", "x", 1.0) if name == "mechsim:auto"  # marks on its pick
                              else FAMILY_STYLE.get(rows[0]["family"], ("-", ".", 1.0)))
            ax.loglog([p[0] for p in pts], [p[1] * 1e3 for p in pts], linestyle=ls or "none",
                      marker=marker, lw=lw, ms=5, color=colour[name], label=label)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("wall time [ms]")
        ax.set_title(f"{sid}: {title}", fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
        if ax.lines:
            ax.invert_xaxis()
            ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize=7,
                      title="contestant", title_fontsize=7)
        else:
            ax.text(0.5, 0.5, "no conserved quantity" if key == "invariant_error"
                    else "no run", ha="center", va="center", transform=ax.transAxes)
            ax.set_xticks([])
            ax.set_yticks([])
    fig.tight_layout()
    return fig
