"""`mechsim systems [ID ...]`: systems, their parameters, coordinates, laws and sources."""

from __future__ import annotations

import argparse
import json
from typing import Any


def cmd_systems(a: argparse.Namespace) -> int:
    from mechsim.errors import UnknownSystemError
    from mechsim.systems import system_class, system_ids

    known = system_ids()
    for sid in a.ids:
        if sid not in known:
            raise UnknownSystemError(sid, known)
    if a.ids or a.json:
        described = []
        for sid in a.ids or known:
            cls = system_class(sid)
            d = cls().describe()
            d["oracles"] = cls.oracles
            described.append(d)
    if a.json:
        print(json.dumps(described, indent=2, ensure_ascii=False))
        return 0
    if not a.ids:  # the overview: one line a system
        width = max(len(s) for s in known)
        for sid in known:
            print(f"{sid:<{width}}  {system_class(sid).title}")
        print("\n`mechsim systems ID` shows one system's parameters, coordinates, laws and source.")
        return 0
    for d in described:
        coords = ", ".join(f"{c['name']} [{c['unit']}]" for c in d["coordinates"])
        print(f"{d['id']}: {d['title']}\n  source: {d['source']}\n  coordinates: {coords}")
        if len(d["formulations"]) > 1:
            print(f"  formulations: {', '.join(d['formulations'])}")
        print(f"  laws: {', '.join(d['laws'])}")
        for p in d["parameters"]:
            unit = f" [{p['unit']}]" if p["unit"] else ""
            print(f"    {p['name']} = {p['default']!r}{unit}  {p['description']}")
    return 0


def add_parser(sub: Any) -> None:
    s = sub.add_parser("systems", help="list the systems; with IDs, their parameters, "
                       "coordinates, laws and sources")
    s.add_argument("ids", nargs="*", metavar="ID", help="system ids to describe in full")
    s.add_argument("--json", action="store_true", help="machine-readable (all, or the IDs)")
    s.set_defaults(func=cmd_systems)
