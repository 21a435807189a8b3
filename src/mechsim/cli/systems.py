"""`mechsim systems`."""

from __future__ import annotations

import argparse
import json
from typing import Any


def cmd_systems(a: argparse.Namespace) -> int:
    from mechsim.systems import system_class, system_ids

    described = []
    for sid in system_ids():
        cls = system_class(sid)
        model = cls()
        d = model.describe()
        d["oracles"] = cls.oracles
        described.append(d)
    if a.json:
        print(json.dumps(described, indent=2, ensure_ascii=False))
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
    s = sub.add_parser("systems", help="list systems, parameters, coordinates and sources")
    s.add_argument("--json", action="store_true")
    s.set_defaults(func=cmd_systems)
