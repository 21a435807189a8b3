#!/usr/bin/env python3
"""Write README.md's performance summary from the benchmark outputs in docs/bench/ (run with
the project's venv after `mechsim bench` has written them):

    python tools/readme_performance.py           # rewrite the block between the markers
    python tools/readme_performance.py --check   # exit 1 if the block is out of date

Every figure comes from the JSON a benchmark run wrote; nothing here is measured or typed in.
Each row names its page, whose header says when and on what machine it was measured.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "docs" / "bench"
BEGIN, END = "<!-- performance:begin -->", "<!-- performance:end -->"


def _load(name: str) -> dict[str, Any] | None:
    path = BENCH / name
    return json.loads(path.read_text()) if path.exists() else None


def _work_precision(name: str, page: str, what: str) -> Iterator[str]:
    """One row per target of a work-precision run: how many problems meet it, and the ones
    that do not with their detail."""
    res = _load(name)
    if res is None:
        return
    by_target: dict[str, list[dict[str, Any]]] = {}
    for t in res.get("targets", []):
        by_target.setdefault(t["target"], []).append(t)
    for target, rows in by_target.items():
        if all(str(r["detail"]).startswith("not measured") for r in rows):
            continue  # measured by another run of its own (its page says so)
        met = sum(1 for r in rows if r["passed"])
        missed = [r["system"] for r in rows if not r["passed"]]
        verdict = "met" if not missed else f"**missed** on {', '.join(missed)}"
        yield (f"| {what}: {target} | {met} of {len(rows)} problems | {verdict} | "
               f"[{page}](docs/bench/{page}) |")


def _streaming() -> Iterator[str]:
    """The target rows of docs/bench/streaming.md's summary (written by the same run)."""
    page = BENCH / "streaming.md"
    if not page.exists():
        return
    for line in page.read_text().splitlines():
        m = re.match(r"^\| (.+?) \| (.+?) \| (met|\*\*missed\*\*) \|$", line)
        if m:
            yield (f"| {m.group(1)} | {m.group(2)} | {m.group(3)} | "
                   f"[streaming.md](docs/bench/streaming.md) |")


def _throughput() -> Iterator[str]:
    res = _load("throughput.json")
    if res is None:
        return
    call = res["per_call"]
    one = next((v for k, v in call.items() if k.startswith("simulate")), None)
    link = "[throughput.md](docs/bench/throughput.md)"
    read = next((v for k, v in call.items() if "then reading" in k), None)
    median = next(iter(res.get("per_call_median", {}).values()), None)
    if one is not None:
        verdict = "met" if one <= 5.0 else "**missed**"
        notes = ["fastest batch"] + ([] if read is None else
                                     [f"{read:.1f} µs with reading its end state"])
        also = (f" ({', '.join(notes)}"
                + ("" if median is None else f"; median batch {median:.1f} µs") + ")")
        yield (f"| one `simulate()` call of one sample ≤ 5 µs | {one:.1f} µs{also} | {verdict} "
               f"| {link} |")
    e = res["ensembles"]
    speed = e["speedup_vs_rk4"]
    yield (f"| `simulate_many`, {e['members']} pendulums at tolerance {e['tolerance']:g} ≥ 1× a "
           f"hand-written numba prange RK4 at matched error | {speed:.2f}× | "
           f"{'met' if speed >= 1.0 else '**missed**'} | {link} |")
    yield (f"| the same, scaling from one core to {e['cores']} ≥ 1.8× | {e['scaling']:.2f}× "
           f"(the RK4 loop: {e['rk4_scaling']:.2f}×) | "
           f"{'met' if e['scaling'] >= 1.8 else '**missed**'} | {link} |")


def block() -> str:
    rows = ["| target | measured | | page |", "|---|---|---|---|"]
    rows += _work_precision("results.json", "results.md", "long problems")
    rows += _work_precision("short/results.json", "short/results.md", "short problems")
    rows += _throughput()
    rows += _streaming()
    return "\n".join(rows)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true")
    args = parser.parse_args(argv)
    readme = ROOT / "README.md"
    text = readme.read_text()
    if BEGIN not in text or END not in text:
        print("README.md has no performance markers", file=sys.stderr)
        return 1
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    new = f"{head}{BEGIN}\n{block()}\n{END}{tail}"
    if args.check:
        return 0 if new == text else 1
    readme.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
