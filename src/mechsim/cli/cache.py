"""`mechsim cache info|clear`: the cache of generated, compiled kernel modules."""

from __future__ import annotations

import argparse
import json
from typing import Any


def _size(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 100_000 else f"{n / 1e3:.1f} kB"


def cmd_cache(a: argparse.Namespace) -> int:
    from mechsim import codegen

    if a.action == "clear":
        removed = codegen.cache_clear()
        print(f"removed {removed} generated module{'s' if removed != 1 else ''} from "
              f"{codegen.cache_dir()}")
        return 0
    info = codegen.cache_info()
    if a.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"cache: {info['path']}\n"
          f"  modules: {info['modules']} (shared loops: {info['loops']}; at most "
          f"{info['limit']}, least recently used removed first)\n"
          f"  size on disk: {_size(info['bytes'])}")
    return 0


def add_parser(sub: Any) -> None:
    s = sub.add_parser("cache", help="show or empty the cache of generated kernel modules",
                       description="Each model's derived and compiled kernels and the shared "
                       "integrator loops are kept on disk ($MECHSIM_CACHE_DIR, else "
                       "$XDG_CACHE_HOME/mechsim), keyed on every input; `clear` removes "
                       "them (the next run derives and compiles again).")
    s.add_argument("action", choices=("info", "clear"))
    s.add_argument("--json", action="store_true", help="info as JSON")
    s.set_defaults(func=cmd_cache)
