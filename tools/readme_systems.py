#!/usr/bin/env python3
"""Regenerate the systems list of README.md (between the systems-table markers) from the
systems themselves, id and title, two to a row: `python tools/readme_systems.py` (run with the
project's venv). The full table (formulations, laws, oracles) is docs/systems.md."""

from __future__ import annotations

import sys
from pathlib import Path

from mechsim.systems import system_class, system_ids

BEGIN, END = "<!-- systems-table:begin -->", "<!-- systems-table:end -->"


def table() -> str:
    entries = [f"`{sid}` | {system_class(sid).title}" for sid in system_ids()]
    half = (len(entries) + 1) // 2
    rows = ["| system | title | system | title |", "|---|---|---|---|"]
    for left, right in zip(entries[:half], entries[half:] + [" | "], strict=False):
        rows.append(f"| {left} | {right} |")
    return "\n".join(rows)


def main() -> int:
    readme = Path(__file__).resolve().parent.parent / "README.md"
    text = readme.read_text()
    if BEGIN not in text or END not in text:
        print("README.md has no systems-table markers", file=sys.stderr)
        return 1
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    readme.write_text(f"{head}{BEGIN}\n{table()}\n{END}{tail}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
