"""The layout a recording opens with: the 3D world beside one tab of plots per system.

Every plot is on the same time axis, from simulation time 0 (not from each plot's first
sample), one unit per plot, no colour twice in a plot; residuals and drifts say their
magnitude in the title (their axis shows round-off around 0 without one). Trails are shown
over all past time (a growing path); the camera looks at everything drawn so far.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from mechsim.outputs.rerun.entities import ENERGY_TERMS, TIMELINE, path
from mechsim.outputs.rerun.world import System

#: Line colours within one plot, in order (Tableau 10: distinguishable, also in print).
_PALETTE = ((31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
            (140, 86, 75), (227, 119, 194), (127, 127, 127), (188, 189, 34), (23, 190, 207))


def _colours(n: int) -> list[tuple[int, int, int]]:
    """``n`` line colours, all different: the palette, else hues evenly around the circle."""
    import colorsys

    if n <= len(_PALETTE):
        return list(_PALETTE[:n])
    colours = []
    for k in range(n):
        r, g, b = colorsys.hsv_to_rgb(k / n, 0.8, 0.85)
        colours.append((int(255 * r), int(255 * g), int(255 * b)))
    return colours


def _eye(bbox: tuple[np.ndarray | None, np.ndarray | None]) -> Any:
    """An orbital camera looking at the bounding box ``bbox`` (None before anything is
    drawn)."""
    import rerun.blueprint as rrb

    lo, hi = bbox
    if lo is None or hi is None:
        return None
    center = (lo + hi) / 2
    size = max(float(np.max(hi - lo)), 1.0)
    direction = np.array([1.0, 0.35, 0.45]) / np.linalg.norm([1.0, 0.35, 0.45])
    return rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital,
                             position=(center + 1.5 * size * direction).tolist(),
                             look_target=center.tolist(), eye_up=[0.0, 0.0, 1.0])


class _Plots:
    """Time-series views on one time axis, titled with the peaks of what they show."""

    def __init__(self, peaks: dict[str, float]) -> None:
        import rerun.blueprint as rrb

        self.peaks = peaks
        self.axis_x = rrb.TimeAxis(view_range=rrb.TimeRange(
            start=rrb.TimeRangeBoundary.absolute(seconds=0.0),
            end=rrb.TimeRangeBoundary.infinite()))

    def plot(self, name: str, origin: str, contents: Any = "$origin/**",
             entities: list[str] | None = None, **kw: Any) -> Any:
        import rerun as rr
        import rerun.blueprint as rrb

        entities = entities or []
        colours: dict[Any, Any] = {e: rr.SeriesLines.from_fields(colors=[c])
                   for e, c in zip(entities, _colours(len(entities)), strict=True)}
        return rrb.TimeSeriesView(name=name, origin=origin, contents=contents,
                                  axis_x=self.axis_x, overrides=colours, **kw)

    def peak(self, root: str, keys: list[str]) -> str:
        peaks = self.peaks
        values = [peaks[e] for e in (f"{root[1:]}/{path(k)}" for k in keys) if e in peaks]
        return f", max |·| = {max(values):.1e}" if values else ""

    def by_unit(self, st: System, root: str, streams: tuple[str, ...], what: str
                ) -> list[Any]:
        """One plot per unit of the quantities of ``streams``."""
        groups: dict[str, list[str]] = {}
        for key, unit in st.units.items():
            if key.partition("/")[0] in streams:
                groups.setdefault(unit, []).append(key)
        views = []
        for unit, keys in groups.items():
            names = [k.partition("/")[2] for k in keys]
            shown = ", ".join(names) if len(names) <= 3 else f"{names[0]}, … ({len(names)})"
            views.append(self.plot(f"{st.ns}: {what}{shown} [{unit or '1'}]"
                                   f"{self.peak(root, keys) if what else ''}", root,
                                   [f"$origin/{path(k)}" for k in keys],
                                   [f"{root}/{path(k)}" for k in keys]))
        return views

    def system(self, st: System, entities: Iterable[str]) -> Any:
        """The tab of one system: energy, residual and drifts, values, diagnostics."""
        import rerun.blueprint as rrb

        root = f"/{path('plots', st.ns)}"
        residual = self.plot(f"{st.ns}: balance residual [J]"
                             f"{self.peak(root, ['balance_residual'])}", root,
                             ["$origin/balance_residual"])
        if st.units:
            values = self.by_unit(st, root, ("state", "observables"), "")
            drifts = self.by_unit(st, root, ("drift",), "drift of ")
        else:  # units unknown (not a model this mechsim has): by stream
            values = [self.plot(f"{st.ns}: coordinates, observables", root,
                                ["$origin/state/**", "$origin/observables/**"])]
            drifts = [self.plot(f"{st.ns}: invariant drifts", root, ["$origin/drift/**"])]
        diagnostics = sorted(f"/{e}" for e in entities
                             if f"/{e}".startswith(f"{root}/diagnostics/"))
        curves = [rrb.Spatial2DView(name=title, origin=f"/{entity}")
                  for entity, title in st.curves]
        return rrb.Vertical(
            self.plot(f"{st.ns}: energy [J]", f"{root}/energy",
                      entities=[f"{root}/energy/{t}" for t in ENERGY_TERMS]),
            _row([residual, *drifts]),
            _row(values),
            self.plot(f"{st.ns}: diagnostics (0 OK … 3 STALE)", f"{root}/diagnostics",
                      entities=diagnostics, axis_y=rrb.ScalarAxis(range=(-0.2, 3.2))),
            *([_row(curves)] if curves else []),
            name=st.ns)


def _row(views: list[Any]) -> Any:
    import rerun.blueprint as rrb

    return views[0] if len(views) == 1 else rrb.Tabs(*views)


def blueprint(systems: Iterable[System] = (),
              bbox: tuple[np.ndarray | None, np.ndarray | None] = (None, None),
              peaks: dict[str, float] | None = None, entities: Iterable[str] = ()) -> Any:
    """The blueprint for ``systems`` (those learned from a system_info), the bounding box of
    what was drawn, the peaks of the scalars sent and the entities with rows."""
    import rerun.blueprint as rrb

    shown = [st for st in systems if st.key]
    trails = [e for st in shown for e, _ in st.trails]
    growing = rrb.VisibleTimeRanges([rrb.VisibleTimeRange(
        TIMELINE, start=rrb.TimeRangeBoundary.infinite(),
        end=rrb.TimeRangeBoundary.cursor_relative())])
    view3d = rrb.Spatial3DView(name="world", origin="/world", eye_controls=_eye(bbox),
                               overrides={f"/{e}": growing for e in trails})
    if not shown:
        plots: Any = rrb.TimeSeriesView(name="plots", origin="/plots")
    else:
        views = _Plots(peaks or {})
        entities = list(entities)
        tabs = [views.system(st, entities) for st in shown]
        plots = tabs[0] if len(tabs) == 1 else rrb.Tabs(*tabs)
    return rrb.Blueprint(rrb.Horizontal(view3d, plots, column_shares=[3, 2]),
                         rrb.BlueprintPanel(state="collapsed"),
                         rrb.SelectionPanel(state="collapsed"),
                         rrb.TimePanel(state="collapsed", timeline=TIMELINE,
                                       play_state="following"))
