"""`mechsim cache info|clear|warm`: the cache of generated, compiled kernel modules."""

from __future__ import annotations

import argparse
import json
from typing import Any

from mechsim.errors import counted


def _size(n: int) -> str:
    return f"{n / 1e6:.1f} MB" if n >= 100_000 else f"{n / 1e3:.1f} kB"


def warm(systems: list[str], quiet: bool) -> int:
    """Derive and compile the kernels of every formulation of ``systems`` (all when empty) and
    take one short run of each (its closed form too, where it has one), so that a first run
    later loads everything from the cache. A formulation its default parameters do not allow
    is skipped with its reason. Returns how many were made or found."""
    from mechsim.cli.common import say
    from mechsim.errors import MechsimError
    from mechsim.simulate import simulate
    from mechsim.systems import system_class, system_ids

    done = 0
    for sid in systems or system_ids():
        cls = system_class(sid)
        forms = cls.formulations if len(cls.formulations) > 1 else (None,)
        for form in forms:
            label = sid if form is None else f"{sid} ({form})"
            try:
                model = cls() if form is None else cls(formulation=form)
                simulate(model, 0.02, 0.01, method="auto", closed_form=True)
            except MechsimError as e:
                if not quiet:
                    say(f"cache warm: {label}: skipped: {e}")
                continue
            done += 1
            if not quiet:
                say(f"cache warm: {label}")
    return done


def cmd_cache_warm(a: argparse.Namespace) -> int:
    from mechsim import codegen

    n = warm(a.systems, a.quiet)
    if not a.quiet:
        print(f"{counted(n, 'model')} ready in {codegen.cache_dir()}")
    return 0


def cmd_cache_clear(a: argparse.Namespace) -> int:
    from mechsim import codegen

    removed = codegen.cache_clear()
    print(f"removed {removed} generated module{'s' if removed != 1 else ''} from "
          f"{codegen.cache_dir()}")
    return 0


def cmd_cache_info(a: argparse.Namespace) -> int:
    from mechsim import codegen

    info = codegen.cache_info()
    if a.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"cache: {info['path']}\n"
          f"  modules: {info['modules']} (shared loops: {info['loops']}; at most "
          f"{info['limit']}, least recently used removed first)\n"
          f"  model summaries: {info['summaries']} (set-up without sympy)\n"
          f"  size on disk: {_size(info['bytes'])}")
    return 0


def add_parser(sub: Any) -> None:
    c = sub.add_parser("cache", help="show, empty or fill the cache of generated kernel modules",
                       description="Each model's derived and compiled kernels and the shared "
                       "integrator loops are kept on disk ($MECHSIM_CACHE_DIR, else "
                       "$XDG_CACHE_HOME/mechsim), keyed on every input.")
    csub = c.add_subparsers(dest="cache_command", required=True)
    i = csub.add_parser("info", help="where the cache is, what it holds and its bound")
    i.add_argument("--json", action="store_true", help="as JSON")
    i.set_defaults(func=cmd_cache_info)
    r = csub.add_parser("clear", help="remove every generated module (the next run derives "
                        "and compiles again); nothing else in the directory is touched")
    r.set_defaults(func=cmd_cache_clear)
    w = csub.add_parser("warm", help="derive and compile every formulation of the systems "
                        "now (all by default), so that their first runs load from the cache")
    w.add_argument("systems", nargs="*", metavar="SYSTEM", help="only these systems")
    w.add_argument("--quiet", action="store_true", help="no line per model")
    w.set_defaults(func=cmd_cache_warm)
