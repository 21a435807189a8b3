"""`mechsim stress`."""

from __future__ import annotations

import argparse
from typing import Any

from mechsim.cli.common import add_force, refuse_existing


def cmd_stress(a: argparse.Namespace) -> int:
    from mechsim.stress.run import FIGURES, run_stress

    refuse_existing(a.out, ["stress.json", "stress.md",
                            *(FIGURES[c] for c in (a.case or CASES) if c in FIGURES)], a.force)
    report = run_stress(a.systems, quick=a.quick, out=a.out, cases=a.case)
    return 0 if report["summary"]["failed"] == 0 else 1


CASES = ("long_horizon", "chaos", "stiffness", "singular", "sweeps", "hamilton")


def add_parser(sub: Any) -> None:
    s = sub.add_parser("stress", help="numerical stress tests with pass criteria and a report")
    s.add_argument("systems", nargs="*", metavar="SYSTEM", help="system ids (default: all)")
    s.add_argument("--quick", action="store_true", help="reduced catalogue (about a minute)")
    s.add_argument("--out", required=True, metavar="DIR",
                   help="report directory (stress.json, stress.md, PNG plots)")
    s.add_argument("--case", action="append", choices=list(CASES), default=None,
                   help="only this case (repeatable)")
    add_force(s, "replace the report and plots in --out (other files there are kept); "
              "without it an existing one is refused before anything runs")
    s.set_defaults(func=cmd_stress)

