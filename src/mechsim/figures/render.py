"""What every figure shares: a matplotlib figure made without pyplot's global state (Agg), the
caption printed under the axes, and the PNG written atomically (never over an existing file
unless asked)."""

from __future__ import annotations

import io
import textwrap
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from mechsim.files import write_atomic
from mechsim.systems import Model, load_system

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

#: Characters per caption line (at the width of a two-panel figure).
CAPTION_WIDTH = 165
DPI = 100


@dataclass
class Drawn:
    """A drawn figure, its caption (document, section, parameters) and the numbers behind it
    that a reader (or a test) can check against closed forms."""

    figure: Figure
    caption: str
    numbers: dict[str, float] = field(default_factory=dict)


_System = TypeVar("_System", bound=Model)


def load_as(kind: type[_System], system_id: str, **values: Any) -> _System:
    """``load_system(system_id, **values)`` typed as the class whose analyses a figure draws
    (a TypeError if the registry gives another)."""
    model = load_system(system_id, **values)
    if not isinstance(model, kind):
        raise TypeError(f"{system_id}: a {type(model).__name__}, not a {kind.__name__}")
    return model


def new_figure(rows: int = 1, cols: int = 1, width: float = 11.0,
               height: float = 4.2, **kw: Any) -> tuple[Figure, Any]:
    """A figure with a grid of axes (``axes[i][j]``; always 2-D), no pyplot state."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height * rows), dpi=DPI)
    axes = fig.subplots(rows, cols, squeeze=False, **kw)
    return fig, axes


def label(ax: Axes, title: str, x: str, y: str, legend: bool = True) -> None:
    """Title, axis labels (with units) and a legend (if anything is labelled), with a grid."""
    ax.set_title(title, fontsize=10)
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    ax.grid(True, alpha=0.3)
    if legend and ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8)


def constant_scale(ax: Axes, *series: Any) -> None:
    """Where every series is constant to round-off, show it on a scale around its value
    rather than magnifying the round-off (matplotlib's default)."""
    import numpy as np

    values = np.concatenate([np.ravel(s) for s in series])
    span, size = float(np.ptp(values)), float(np.max(np.abs(values)))
    if span <= 1e-9 * max(size, 1e-300):
        centre = float(np.mean(values))
        half = 0.5 * abs(centre) if centre else 1.0
        ax.set_ylim(centre - half, centre + half)
    ax.ticklabel_format(axis="y", useOffset=False)


def caption(fig: Figure, text: str) -> None:
    """Print ``text`` under the axes, wrapped, and lay the axes out above it."""
    lines = textwrap.wrap(text, int(CAPTION_WIDTH * fig.get_figwidth() / 11.0))
    height = (0.12 + 0.15 * len(lines)) / fig.get_figheight()
    fig.text(0.01, 0.01, "\n".join(lines), fontsize=8.5, va="bottom", ha="left")
    fig.tight_layout(rect=(0.0, height, 1.0, 1.0))


def write_png(drawn: Drawn, path: Path, replace: bool) -> int:
    """The figure with its caption as a PNG at ``path`` (atomic; with ``replace`` false an
    existing file is refused, FileExistsError); returns the size in bytes."""
    caption(drawn.figure, drawn.caption)
    buf = io.BytesIO()
    drawn.figure.savefig(buf, format="png", dpi=DPI)
    data = buf.getvalue()
    write_atomic(path, data, replace=replace)
    return len(data)
