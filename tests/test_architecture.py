"""The layers of ``src/mechsim``: every import points down, and no module imports itself back.

The import graph is read from the source with ``ast`` (every ``import``/``from`` statement,
module level or inside a function, so lazy imports count too) and checked against the layer
order the README draws. ``from mechsim import codegen`` names the module ``mechsim.codegen``;
``from mechsim.errors import X`` the module ``mechsim.errors``."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parent.parent / "src"
PACKAGE = SRC / "mechsim"

#: Rank of each room, lowest first. A module may import its own room and rooms below it.
LAYERS: dict[str, int] = {
    "errors": 0, "params": 0, "codegen": 0, "environment": 0, "data": 0, "files": 0,
    "systems": 1,
    "integrators": 2,
    "simulate": 3, "ensemble": 3, "scene": 3,
    "mechsim": 3,  # "mechsim": the package's public API
    "runcore": 4,  # one system run sample by sample, without ROS
    "outputs": 5,
    "ros": 6,
    "bench": 7, "stress": 7, "experiments": 7, "figures": 7, "testing": 7,
    "cli": 8,
}
#: Rooms that must not see each other although the ranks would allow it.
FORBIDDEN = {("integrators", "systems")}  # stepping sees a model only through its protocol


def module_name(path: Path) -> str:
    parts = path.relative_to(SRC).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def room(module: str) -> str:
    parts = module.split(".")
    return "mechsim" if len(parts) == 1 else parts[1]


def imports(path: Path, known: set[str], mod: str | None = None) -> set[str]:
    """The mechsim modules ``path`` imports (read as module ``mod``, default its own name)."""
    mod = mod or module_name(path)
    package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.split(".")[0] == "mechsim")
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            if target.split(".")[0] != "mechsim":
                continue
            for alias in node.names:  # `from pkg import submodule` imports the submodule
                sub = f"{target}.{alias.name}"
                found.add(sub if sub in known else target)
    found.discard(mod)
    return found


def graph() -> dict[str, set[str]]:
    files = sorted(PACKAGE.rglob("*.py"))
    known = {module_name(f) for f in files}
    return {module_name(f): imports(f, known) for f in files}


def test_every_room_has_a_layer() -> None:
    rooms = {room(m) for m in graph()}
    assert rooms <= set(LAYERS), f"rooms without a layer: {sorted(rooms - set(LAYERS))}"


def test_every_import_points_down() -> None:
    wrong = []
    for mod, deps in graph().items():
        for dep in deps:
            a, b = room(mod), room(dep)
            if LAYERS[b] > LAYERS[a] or (a, b) in FORBIDDEN:
                wrong.append(f"{mod} ({a}) imports {dep} ({b})")
    assert not wrong, "\n".join(sorted(wrong))


def test_no_import_cycles() -> None:
    g = graph()
    # The package itself re-exports the API; its __init__ is the top of the API layer and is
    # imported implicitly by every submodule, so edges *into* "mechsim" are left out.
    edges = {m: {d for d in deps if d != "mechsim"} for m, deps in g.items()}
    state: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def visit(m: str) -> None:
        state[m] = 1
        stack.append(m)
        for d in sorted(edges.get(m, ())):
            if state.get(d) == 1:
                cycles.append(stack[stack.index(d):] + [d])
            elif d not in state:
                visit(d)
        stack.pop()
        state[m] = 2

    for m in sorted(edges):
        if m not in state:
            visit(m)
    assert not cycles, "\n".join(" -> ".join(c) for c in cycles)


@pytest.mark.parametrize("source,bad", [
    ("from mechsim.cli import main\n", "mechsim.cli"),
    ("from mechsim import cli\n", "mechsim.cli"),
    ("from ..ros import simulator\n", "mechsim.ros.simulator"),
    ("def f():\n    import mechsim.outputs.bag\n", "mechsim.outputs.bag"),
])
def test_the_checker_sees_an_upward_import(tmp_path: Path, source: str, bad: str) -> None:
    """The checker itself: an upward import, read as a module of systems/, is found."""
    probe = tmp_path / "probe.py"
    probe.write_text(source)
    known = {module_name(f) for f in PACKAGE.rglob("*.py")}
    deps = imports(probe, known, mod="mechsim.systems.probe")
    assert bad in deps
    assert LAYERS[room(bad)] > LAYERS["systems"]
