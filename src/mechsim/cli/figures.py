"""`mechsim figures`."""

from __future__ import annotations

import argparse
from typing import Any


def cmd_figures(a: argparse.Namespace) -> int:
    from mechsim.figures import describe, make_figures

    if a.list:
        for f in describe():
            print(f"{f['name']:28s} {'quick ' if f['quick'] else '      '}{f['document']}")
        return 0
    if a.out is None:
        from mechsim.errors import MechsimError

        raise MechsimError("--out DIR is required (or --list)")
    make_figures(a.out, force=a.force, quick=a.quick, only=a.only, gallery=a.gallery)
    return 0


def add_parser(sub: Any) -> None:
    f = sub.add_parser("figures", help="redraw the source documents' figures as PNG files")
    f.add_argument("--out", metavar="DIR", help="directory for the PNGs and figures.json")
    f.add_argument("--force", action="store_true", help="replace existing files")
    f.add_argument("--quick", action="store_true",
                   help="a fast subset at lower resolution (about half a minute)")
    f.add_argument("--only", action="append", metavar="NAME",
                   help="only this figure (repeatable; see --list)")
    f.add_argument("--gallery", metavar="FILE",
                   help="also write a Markdown page showing the figures with their captions")
    f.add_argument("--list", action="store_true", help="list the figures and exit")
    f.set_defaults(func=cmd_figures)
