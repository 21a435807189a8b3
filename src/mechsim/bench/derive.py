"""Cold derivation cost (``mechsim bench --derive --out DIR``): the CPU seconds each system
takes to be derived and compiled the first time it runs on a machine whose shared loops were
compiled by set-up.

A new, empty kernel cache (``MECHSIM_CACHE_DIR``, with ``NUMBA_CACHE_DIR`` inside it) is made
and the shared loops are compiled into it in their own process, as set-up does
(``mechsim.integrators.precompile``). Then, for each system in turn, a new process builds the
model with its default parameters and runs what ``mechsim run`` does before its first message
(``make_stepper`` with ``auto``, the law scales, a 0.1 s run with every output) — cold: the
model not derived yet — and a second, identical process runs it again — warm: everything
loaded from the cache. A process's CPU (user + system, interpreter start-up included) is taken
from the operating system; cold minus warm is what deriving and compiling the model cost,
the imports and the run being the same in both. Inside each process the CPU is split into:

- ``import``: the interpreter and the modules (numpy, numba, sympy, mechsim);
- ``model``: the system's module, its declaration and the cache key of its kernels;
- ``derive``: sympy deriving the equations (``kernel_source`` less what follows);
- ``codegen``: common subexpressions and printing of the kernel source (``_emit``);
- ``compile``: numba compiling (or loading from its cache) the model's kernel functions, where
  a loop needs them or a call from Python, and making their kernel set;
- ``run``: the rest (the shared loops loaded from numba's cache, the integration);
- ``exit``: the process's total less the above (the interpreter's shut-down, mostly).

Systems share the one cache in a fixed (sorted) order, as a machine's runs would: a compiled
helper that several models call (the dense solver of constrained systems) is compiled by the
first of them. Writes ``derive.json`` and ``derive.md``.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from mechsim.files import write_atomic

PHASES = ("import", "model", "derive", "codegen", "compile", "run", "exit")

#: One system's cold or warm start in a fresh process: prints its CPU per phase as JSON.
_CHILD = r"""
import json, resource, sys

def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime

spent = {}
stack = ["import"]
mark = [cpu()]

def charge():
    now = cpu()
    spent[stack[-1]] = spent.get(stack[-1], 0.0) + now - mark[0]
    mark[0] = now

def phase(name):
    charge()
    stack[-1] = name

def timed(name, f):
    def wrapper(*a, **k):
        charge()
        stack.append(name)
        try:
            return f(*a, **k)
        finally:
            charge()
            stack.pop()
    return wrapper

import numpy, numba, sympy
import mechsim.codegen.contract as contract
from mechsim import codegen
from mechsim.integrators import loops
from mechsim.simulate import simulate
from mechsim.systems import lagrangian_kernels, system_class
from mechsim.systems.base import Model

from numba.core import event

class Compiling(event.Listener):
    # numba's compilations, wherever they start (a kernel called from Python compiles too)
    def on_start(self, ev):
        charge()
        stack.append("compile")
    def on_end(self, ev):
        charge()
        stack.pop()

event.register("numba:compile", Compiling())
codegen.Kernels._compile = timed("compile", codegen.Kernels._compile)
contract.make_kernel_set = timed("compile", contract.make_kernel_set)
lagrangian_kernels._emit = timed("codegen", lagrangian_kernels._emit)
phase("model")
cls = system_class(sys.argv[1])
if hasattr(cls, "kernel_source"):
    cls.kernel_source = timed("derive", cls.kernel_source)
model = cls()
model.kernels
phase("run")
simulate(model, 0.1, 0.01)
model.law_scales()
charge()
print(json.dumps(spent))
"""


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _run(code: str, args: list[str], env: dict[str, str]) -> tuple[float, str]:
    """CPU seconds of a new Python process running ``code`` (and its stdout)."""
    before = _children_cpu()
    p = subprocess.run([sys.executable, "-c", code, *args], env=env, capture_output=True,
                       text=True, timeout=1800)
    spent = _children_cpu() - before
    if p.returncode != 0:
        tail = (p.stderr.strip().splitlines() or ["no output"])[-1]
        raise RuntimeError(f"{' '.join(args) or 'set-up'}: {tail}")
    return spent, p.stdout


def _start(system: str, env: dict[str, str]) -> dict[str, Any]:
    total, out = _run(_CHILD, [system], env)
    phases = json.loads(out.strip().splitlines()[-1])
    phases["exit"] = total - sum(phases.values())
    return {"cpu_s": total, "phases": {k: phases.get(k, 0.0) for k in PHASES}}


def measure(systems: list[str]) -> dict[str, Any]:
    """Cold and warm CPU of each of ``systems`` (see the module docstring)."""
    rows = []
    with tempfile.TemporaryDirectory(prefix="mechsim-derive-") as tmp:
        env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
        env.update(MECHSIM_CACHE_DIR=tmp, NUMBA_CACHE_DIR=os.path.join(tmp, "numba"))
        loops_s, _ = _run("import mechsim.integrators as i; i.precompile()", [], env)
        print(f"  shared loops compiled: {loops_s:.1f} s of CPU", file=sys.stderr)
        for s in systems:
            cold = _start(s, env)
            warm = _start(s, env)
            row = {"system": s, "cold": cold, "warm": warm,
                   "derive_s": cold["cpu_s"] - warm["cpu_s"]}
            rows.append(row)
            ph = cold["phases"]
            print(f"  {s:22s} cold {cold['cpu_s']:5.2f} s, warm {warm['cpu_s']:5.2f} s, "
                  f"difference {row['derive_s']:5.2f} s  (cold: "
                  + ", ".join(f"{k} {ph[k]:.2f}" for k in PHASES) + ")", file=sys.stderr)
    return {"schema": "mechsim-derive/1", "loops_cpu_s": loops_s, "systems": rows,
            "total": {"cold_s": sum(r["cold"]["cpu_s"] for r in rows),
                      "warm_s": sum(r["warm"]["cpu_s"] for r in rows),
                      "derive_s": sum(r["derive_s"] for r in rows),
                      "phases_cold": {k: sum(r["cold"]["phases"][k] for r in rows)
                                      for k in PHASES},
                      "phases_warm": {k: sum(r["warm"]["phases"][k] for r in rows)
                                      for k in PHASES}},
            "host": {"cores": os.cpu_count(), "loadavg_end": list(os.getloadavg())}}


def markdown(res: dict[str, Any]) -> str:
    tot = res["total"]
    n = len(res["systems"])
    lines = ["# Cold derivation and compilation", "",
             f"CPU seconds (user + system) of a new process per system: cold (model not "
             f"derived; shared loops compiled by set-up, {res['loops_cpu_s']:.1f} s) and warm "
             f"(everything from the cache); the difference is the derivation and compilation. "
             f"Load average at the end {res['host']['loadavg_end'][0]:.1f} on "
             f"{res['host']['cores']} cores.", "",
             f"**All {n} systems: {tot['derive_s']:.1f} s** (cold {tot['cold_s']:.1f} s, warm "
             f"{tot['warm_s']:.1f} s; {tot['derive_s'] / max(n, 1):.2f} s a system).", "",
             "| system | cold | warm | cold − warm | " + " | ".join(PHASES) + " |",
             "|---|---|---|---|" + "---|" * len(PHASES)]
    for r in res["systems"]:
        ph = r["cold"]["phases"]
        lines.append(f"| {r['system']} | {r['cold']['cpu_s']:.2f} | {r['warm']['cpu_s']:.2f} "
                     f"| {r['derive_s']:.2f} | " + " | ".join(f"{ph[k]:.2f}" for k in PHASES)
                     + " |")
    lines.append(f"| **total** | {tot['cold_s']:.1f} | {tot['warm_s']:.1f} | "
                 f"{tot['derive_s']:.1f} | "
                 + " | ".join(f"{tot['phases_cold'][k]:.1f}" for k in PHASES) + " |")
    lines.append("| warm phases | | | | "
                 + " | ".join(f"{tot['phases_warm'][k]:.1f}" for k in PHASES) + " |")
    lines += ["", "Phases (cold process): " + ", ".join(PHASES) + " — see "
              "`mechsim.bench.derive`."]
    return "\n".join(lines) + "\n"


def run_derive(out: Path, systems: list[str]) -> dict[str, Any]:
    """Measure ``systems`` (default: every registered one) and write derive.json/derive.md."""
    from mechsim.systems import system_ids

    ids = systems or sorted(system_ids())
    res = measure(ids)
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "derive.json", json.dumps(res, indent=1))
    text = markdown(res)
    write_atomic(out / "derive.md", text)
    print(text)
    return res
