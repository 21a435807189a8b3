#!/usr/bin/env python3
"""Regenerate the systems table of README.md (between the systems-table markers) from the
systems themselves: `python tools/readme_systems.py` (run with the project's venv)."""

from __future__ import annotations

import sys
from pathlib import Path

from mechsim.systems import system_class, system_ids

BEGIN, END = "<!-- systems-table:begin -->", "<!-- systems-table:end -->"


def table() -> str:
    rows = ["| system | source | coordinates | conserved (checked live) | oracles tested |",
            "|---|---|---|---|---|"]
    for sid in system_ids():
        cls = system_class(sid)
        model = cls()
        forms = f" ({', '.join(cls.formulations)})" if len(cls.formulations) > 1 else ""
        coords = ", ".join(c.name for c in model.coordinates)
        laws = ", ".join(law.key.replace("invariant:", "").replace("constraint:", "")
                         for law in model.laws())
        rows.append(f"| `{sid}`{forms} | {cls.source} | {coords} | {laws} | {cls.oracles} |")
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
