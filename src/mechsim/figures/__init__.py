"""``mechsim figures``: the figures of the four source documents that a simulator can make,
each redrawn from mechsim's own runs and curves, as PNG files with labelled axes, units,
legends and a caption naming the document, the section and the parameters.

``FIGURES`` lists them in gallery order (``Spec``: a name, the document and section, the
function that draws it, whether ``--quick`` draws it). ``make_figures`` draws them into a
directory, refusing to overwrite an existing file unless asked, and writes ``figures.json``
(name, file, caption, bytes, seconds and the numbers behind each figure, for a reader or a test
to check against closed forms) and, if asked, a gallery page in Markdown. The figures are in
the harness layer: they run systems through ``mechsim.simulate`` and ``mechsim.experiments``.
"""

from __future__ import annotations

import json
import os
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mechsim.errors import MechsimError
from mechsim.figures import blog, bodies, orbits, oscillations
from mechsim.figures.render import Drawn, write_png
from mechsim.files import write_atomic


@dataclass(frozen=True)
class Spec:
    """A figure: its file stem, the document and section it reproduces, how to draw it
    (``draw(quick)``), and whether the quick set includes it."""

    name: str
    document: str
    draw: Callable[[bool], Drawn]
    quick: bool = False


FIGURES: tuple[Spec, ...] = (
    Spec("bead_on_wire", "Dynamical Systems and Constraints: Part 2 – Bead on a Wire",
         blog.bead_on_wire),
    Spec("pendulum_multipliers", "Dynamical Systems and Constraints: Part 3 – Simple Pendulum",
         blog.pendulum_multipliers, quick=True),
    Spec("pendulum_small_angle", "Dynamical Systems and Constraints: Part 3 – Simple Pendulum",
         blog.pendulum_small_angle, quick=True),
    Spec("energy_and_energy_function", "Energy and Hamiltonians: Part 3 – Examples",
         blog.energy_and_energy_function),
    Spec("jacobi_drift", "Action and Reaction, Case 2", blog.jacobi_drift),
    Spec("twisted_cubic_frames", "Moving Frames and the Twisted Cubic", blog.twisted_cubic,
         quick=True),
    Spec("orbit_frames", "Minimal Frames", blog.orbit_frames),
    Spec("effective_potentials", "Introduction to analytical mechanics; PHYS0500 §4.5",
         orbits.effective_potentials, quick=True),
    Spec("kepler_orbits", "PHYS0500 §4.6", orbits.kepler_orbits),
    Spec("power_law_orbits", "PHYS0500 §4.4", orbits.power_law_orbits),
    Spec("radial_oscillations", "PHYS0500 §4.5.1", orbits.radial_oscillations),
    Spec("damped_regimes", "PHYS0500 §1.3", oscillations.damped_regimes),
    Spec("resonance_curves", "PHYS0500 §1.5, §1.5.1", oscillations.resonance, quick=True),
    Spec("coupled_beats", "PHYS0500 §8.2", oscillations.coupled_beats),
    Spec("chain_frequencies", "PHYS0500 §8.1", oscillations.chain_frequencies),
    Spec("double_pendulum_modes", "Introduction to analytical mechanics, Double pendulum",
         oscillations.double_pendulum_modes),
    Spec("phase_portraits", "Simple Pendulum post; PHYS0500 §1.3",
         oscillations.phase_portraits),
    Spec("top_nutation", "PHYS0500 §7.8.1–7.8.2", bodies.top_nutation),
    Spec("fictitious_forces", "PHYS0500 §6.1", bodies.fictitious_forces),
)

#: The index every run writes beside the PNGs.
INDEX = "figures.json"


@dataclass(frozen=True)
class Written:
    """A figure written: its spec, file, caption, size, drawing time and numbers."""

    spec: Spec
    path: Path
    caption: str
    size: int
    seconds: float
    numbers: dict[str, float]


def select(only: list[str] | None, quick: bool) -> list[Spec]:
    """The figures to draw: those named (in gallery order), else all (the quick set with
    ``quick``). An unknown name is a one-line error with the names known."""
    names = [s.name for s in FIGURES]
    for name in only or []:
        if name not in names:
            import difflib

            near = difflib.get_close_matches(name, names, n=1)
            hint = f"did you mean {near[0]!r}? " if near else ""
            raise MechsimError(f"--only: unknown figure {name!r} ({hint}known: "
                               f"{', '.join(names)})")
    if only:
        return [s for s in FIGURES if s.name in only]
    return [s for s in FIGURES if s.quick or not quick]


def _check_targets(out: Path, specs: list[Spec], extra: list[Path], force: bool) -> None:
    """Refuse before drawing anything: ``out`` must be a directory (made if missing) and,
    without ``force``, none of the files to write may exist."""
    if out.exists() and not out.is_dir():
        raise MechsimError(f"--out {out}: exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise MechsimError(f"--out {out}: cannot create ({e.strerror or e})") from None
    if not os.access(out, os.W_OK):
        raise MechsimError(f"--out {out}: not writable")
    if force:
        return
    for path in [out / f"{s.name}.png" for s in specs] + [out / INDEX, *extra]:
        if os.path.lexists(path):
            raise MechsimError(f"{path} exists (use --force to replace it)")


def make_figures(out: str | Path, *, force: bool = False, quick: bool = False,
                 only: list[str] | None = None, gallery: str | Path | None = None,
                 log: Callable[[str], None] | None = None) -> list[Written]:
    """Draw the selected figures into ``out`` (see the module docstring); a progress line per
    figure to ``log`` (stderr by default)."""
    log = log or (lambda text: print(f"mechsim figures: {text}", file=sys.stderr, flush=True))
    specs = select(only, quick)
    out = Path(out)
    page = Path(gallery) if gallery is not None else None
    _check_targets(out, specs, [page] if page else [], force)
    written = []
    start = time.perf_counter()
    for i, spec in enumerate(specs, 1):
        t0 = time.perf_counter()
        drawn = spec.draw(quick)
        path = out / f"{spec.name}.png"
        try:
            size = write_png(drawn, path, replace=force)
        except FileExistsError:
            raise MechsimError(f"{path} exists (use --force to replace it)") from None
        seconds = time.perf_counter() - t0
        written.append(Written(spec, path, drawn.caption, size, seconds, drawn.numbers))
        log(f"[{i}/{len(specs)}] {spec.name}: {path} ({size / 1024:.0f} kB, {seconds:.1f} s)")
    index = [{"name": w.spec.name, "file": w.path.name, "document": w.spec.document,
              "caption": w.caption, "bytes": w.size, "seconds": round(w.seconds, 3),
              "numbers": w.numbers} for w in written]
    write_atomic(out / INDEX, json.dumps(index, indent=1, ensure_ascii=False) + "\n",
                 replace=force)
    if page is not None:
        write_atomic(page, gallery_page(written, page.parent), replace=force)
    log(f"{len(written)} figure{'s' if len(written) != 1 else ''} in "
        f"{time.perf_counter() - start:.1f} s; index {out / INDEX}"
        + (f"; gallery {page}" if page else ""))
    return written


def gallery_page(written: list[Written], base: Path) -> str:
    """Markdown: every figure with its caption, images linked relative to ``base``."""
    lines = ["# Gallery", "",
             "The figures of the four source documents (see the [bibliography](bibliography.md))",
             "that a simulator can make, redrawn from mechsim's runs. Generated by",
             "`mechsim figures --out docs/gallery --gallery docs/gallery.md --force`; the numbers",
             "behind each figure are in `docs/gallery/figures.json`.", ""]
    for w in written:
        rel = Path(os.path.relpath(w.path, base))
        lines += [f"## {w.spec.name.replace('_', ' ').capitalize()}", "",
                  f"![{w.spec.name}]({rel.as_posix()})", "", w.caption, ""]
    return "\n".join(lines)


def describe() -> list[dict[str, Any]]:
    """Name, document and quick flag of every figure (``mechsim figures --list``)."""
    return [{"name": s.name, "document": s.document, "quick": s.quick} for s in FIGURES]
