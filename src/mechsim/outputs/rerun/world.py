"""The systems of a recording and their frames in the 3D world.

A system is learned from its ``<ns>/system_info`` message: system id and parameters give the
model (``mechsim.load_system``), hence its frames and visuals, logged once as static entities;
its time offset is that message's stamp, which is always simulation time 0. Each frame is an
entity under its parent's; a frame's origin in world is composed along its chain of parents.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from mechsim.errors import MechsimError
from mechsim.outputs.rerun.entities import ENERGY_TERMS, path, stamp_ns
from mechsim.systems.base import Law


@dataclass
class Frame:
    parent: str
    entity: str
    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)
    known: bool = False  # a transform has been received


@dataclass
class System:
    ns: str
    instance: str
    offset_ns: int
    system: str = ""
    key: tuple[str, ...] = ()
    links: list[tuple[str, str, str]] = field(default_factory=list)  # entity, frame a, frame b
    trails: list[tuple[str, str]] = field(default_factory=list)  # entity, frame
    last_trail: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    balance0: float | None = None  # the work balance's value at the epoch's first sample
    invariants0: dict[str, float] = field(default_factory=dict)
    laws: dict[str, Law] = field(default_factory=dict)  # invariant laws from system_info
    last_t: int = 0
    #: "<stream>/<name>" (state, invariants, drift, observables) -> unit, from the model: the
    #: blueprint draws one unit per plot
    units: dict[str, str] = field(default_factory=dict)
    #: (entity, title) of each of the model's curves (``Model.curves``), drawn as 2D plots
    curves: list[tuple[str, str]] = field(default_factory=list)

    def rebase(self) -> None:
        """A new epoch: drifts, the balance and trails start again."""
        self.balance0 = None
        self.invariants0.clear()
        self.last_trail.clear()

    def frame_id(self, frame: str) -> str:
        """The frame id of a model frame (name without namespace)."""
        return "world" if frame == "world" else f"{self.instance}/{frame}"


def _qmul(a: tuple[float, ...], b: tuple[float, ...]) -> tuple[float, float, float, float]:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw,
            aw * bw - ax * bx - ay * by - az * bz)


def _qrot(q: tuple[float, ...], v: tuple[float, ...]) -> tuple[float, float, float]:
    """Rotate v by the unit quaternion q (xyzw)."""
    x, y, z, w = q
    vx, vy, vz = v
    # t = 2 q_vec × v; v' = v + w t + q_vec × t
    tx, ty, tz = 2 * (y * vz - z * vy), 2 * (z * vx - x * vz), 2 * (x * vy - y * vx)
    return (vx + w * tx + y * tz - z * ty, vy + w * ty + z * tx - x * tz,
            vz + w * tz + x * ty - y * tx)


class World:
    """The systems and frames known so far, logged to the recording stream ``rec``, and the
    bounding box of what was drawn (it places the default 3D camera)."""

    def __init__(self, rec: Any, default_offset_ns: int) -> None:
        self.rec = rec
        self.default_offset_ns = default_offset_ns
        self.systems: dict[str, System] = {}
        self.frames: dict[str, Frame] = {"world": Frame("", "world", known=True)}
        self.bbox: tuple[np.ndarray | None, np.ndarray | None] = (None, None)

    def system(self, ns: str) -> System:
        st = self.systems.get(ns)
        if st is None:
            st = self.systems[ns] = System(ns, ns.rpartition("/")[2], self.default_offset_ns)
        return st

    def on_info(self, ns: str, info: Any) -> None:
        """A system_info of namespace ``ns``: the system's offset, laws, plots and visuals."""
        import yaml

        st = self.system(ns)
        st.instance = info.instance or st.instance
        st.offset_ns = stamp_ns(info.header.stamp)  # system_info is stamped at sim time 0
        key = (info.system, info.parameters_yaml, *info.laws)
        if key == st.key:
            return
        first = not st.key
        st.key, st.system = key, info.system
        st.rebase()
        st.laws = {}
        for law_key in info.laws:
            try:
                law = Law.from_key(law_key)
            except ValueError:
                continue
            if law.stream == "invariants":
                st.laws[law.name] = law
        if first:
            self._label_plots(st, info)
        try:
            from mechsim import load_system

            params = yaml.safe_load(info.parameters_yaml) or {}
            model = load_system(info.system, **params)
        except (MechsimError, yaml.YAMLError, TypeError):
            return  # not a system this mechsim knows: transforms and plots only
        self._log_visuals(st, model)
        self._label_units(st, model)
        self._log_curves(st, model)

    def _log_curves(self, st: System, model: Any) -> None:
        """The model's curves for these parameters, static under ``curves/<ns>/<curve>``: the
        curve, each level as a horizontal line labelled with its value, and the points where
        the curve meets it (the turning points)."""
        import rerun as rr

        root = path("curves", st.ns)
        if st.curves:
            self.rec.log(root, rr.Clear(recursive=True), static=True)
        st.curves.clear()
        for curve in model.curves():
            x, y = np.asarray(curve.x, dtype=float), np.asarray(curve.y, dtype=float)
            keep = np.isfinite(x) & np.isfinite(y)
            if not keep.any():
                continue
            x, y = x[keep], y[keep]
            base = path("curves", st.ns, curve.name)
            title = (f"{st.ns}: {curve.y_label} [{curve.y_unit}] against {curve.x_label} "
                     f"[{curve.x_unit}]")
            self.rec.log(f"{base}/curve", rr.LineStrips2D(
                [np.column_stack([x, y])], labels=[curve.y_label],
                colors=[(60, 150, 255)]), static=True)
            for k, level in enumerate(curve.levels):
                label = f"{level.label} = {level.value:.6g} {curve.y_unit}"
                self.rec.log(f"{base}/level_{k}", rr.LineStrips2D(
                    [[[x[0], level.value], [x[-1], level.value]]], labels=[label],
                    colors=[(255, 130, 30)]), static=True)
                if level.crossings:
                    self.rec.log(f"{base}/level_{k}/crossings", rr.Points2D(
                        [[c, level.value] for c in level.crossings],
                        colors=[(255, 130, 30)], radii=[-4.0]), static=True)
            st.curves.append((base, title))

    def _label_plots(self, st: System, info: Any) -> None:
        import rerun as rr

        for term in ENERGY_TERMS:
            self.rec.log(path("plots", st.ns, "energy", term),
                         rr.SeriesLines(names=f"{term} [J]"), static=True)
        self.rec.log(path("plots", st.ns, "balance_residual"),
                     rr.SeriesLines(names="(E − E₀) − (W_ext − W_diss) [J]"), static=True)
        for name, unit in zip(info.coordinates, info.coordinate_units, strict=False):
            self.rec.log(path("plots", st.ns, "state", name),
                         rr.SeriesLines(names=f"{name} [{unit}]" if unit else name), static=True)

    def _label_units(self, st: System, model: Any) -> None:
        """Units of the model's coordinates, invariants (and their drifts) and observables
        (its ``Quantity.unit``): legend names "name [unit]", and ``st.units`` for the
        blueprint. Coordinates are labelled from system_info by :meth:`_label_plots`."""
        import rerun as rr

        st.units.clear()
        for q in model.coordinates:
            st.units[f"state/{q.name}"] = q.unit
        for stream, quantities in (("invariants", model.invariants),
                                   ("drift", model.invariants),
                                   ("observables", model.observables)):
            for q in quantities:
                st.units[f"{stream}/{q.name}"] = q.unit
                law = st.laws.get(q.name) or Law.for_invariant(q.name)
                name = (f"{q.name} − {q.name}₀" if stream == "drift" and not law.is_constraint
                        else q.name)
                self.rec.log(path("plots", st.ns, stream, q.name), rr.SeriesLines(
                    names=f"{name} [{q.unit}]" if q.unit else name), static=True)

    def _frame_entity(self, st: System, frame: str) -> str:
        """Entity of a model frame (name without namespace), known from model.frames."""
        fid = st.frame_id(frame)
        fr = self.frames.get(fid)
        return fr.entity if fr is not None else path("world", fid)

    def _log_visuals(self, st: System, model: Any) -> None:
        # Entities of the model's frames (parents declared before children).
        for spec in model.frames:
            self.declare_frame(f"{st.instance}/{spec.child}", st.frame_id(spec.parent))
        st.links.clear()
        st.trails.clear()
        counts: dict[tuple[str, str], int] = {}
        for vis in model.visuals():
            n = counts[(vis.frame, vis.kind)] = counts.get((vis.frame, vis.kind), 0) + 1
            suffix = "" if n == 1 else f"_{n}"
            base = self._frame_entity(st, vis.frame)
            if vis.frame == "world":
                base = path("world", st.ns)
            if vis.kind in ("link", "trail"):
                self._log_path_visual(st, vis)
            else:
                self._log_shape(vis, base, suffix)

    def _log_shape(self, vis: Any, base: str, suffix: str) -> None:
        """A visual drawn in its frame: sphere, box, polyline, arrow, axes."""
        import rerun as rr

        color = list(vis.color)
        if vis.kind == "sphere":
            self.rec.log(f"{base}/sphere{suffix}", rr.Points3D(
                [[0.0, 0.0, 0.0]], radii=vis.radius, colors=[color]), static=True)
        elif vis.kind == "box":
            self.rec.log(f"{base}/box{suffix}", rr.Boxes3D(
                half_sizes=[list(vis.size)], colors=[color],
                fill_mode=rr.components.FillMode.Solid), static=True)
        elif vis.kind == "polyline":
            if vis.frame == "world" and vis.points:
                self.extend(tuple(np.min(vis.points, axis=0)))
                self.extend(tuple(np.max(vis.points, axis=0)))
            self.rec.log(f"{base}/polyline{suffix}", rr.LineStrips3D(
                [list(vis.points)], radii=vis.radius, colors=[color]), static=True)
        elif vis.kind == "arrow" and vis.points:
            self.rec.log(f"{base}/arrow{suffix}", rr.Arrows3D(
                vectors=[list(vis.points[0])], origins=[[0.0, 0.0, 0.0]],
                radii=vis.radius * 0.2, colors=[color]), static=True)
        elif vis.kind == "axes":
            self.rec.log(base, rr.TransformAxes3D(vis.radius), static=True)

    def _log_path_visual(self, st: System, vis: Any) -> None:
        """A visual drawn in world at every sample: a link between two frame origins, or a
        trail of one."""
        import rerun as rr

        color = list(vis.color)
        if vis.kind == "link" and vis.to_frame:
            entity = path("world", st.ns, "visuals", f"link_{vis.frame}_{vis.to_frame}")
            st.links.append((entity, st.frame_id(vis.frame), st.frame_id(vis.to_frame)))
            self.rec.log(entity, rr.LineStrips3D.from_fields(
                radii=vis.radius, colors=[color]), static=True)
        elif vis.kind == "trail":
            entity = path("world", st.ns, "visuals", f"trail_{vis.frame}")
            st.trails.append((entity, st.frame_id(vis.frame)))
            self.rec.log(entity, rr.LineStrips3D.from_fields(
                radii=min(vis.radius, 0.01), colors=[color]), static=True)

    def declare_frame(self, child: str, parent: str) -> Frame:
        fr = self.frames.get(child)
        if fr is not None and fr.parent == parent:
            return fr
        if parent not in self.frames:
            self.frames[parent] = Frame("world", path("world", parent))
        parent_entity = self.frames[parent].entity
        local = child.rpartition("/")[2] if parent != "world" else child
        fr = Frame(parent, f"{parent_entity}/{path(local)}")
        self.frames[child] = fr
        return fr

    def positions(self, fid: str, columns: dict[str, int],
                  values: np.ndarray) -> np.ndarray | None:
        """Origin of frame ``fid`` in world at each row of a block of transforms (``values``,
        frame -> index ``columns``; a frame not in the block at its latest pose), composed
        along its chain; None until the whole chain has been posed."""
        chain = []
        while fid != "world":
            fr = self.frames.get(fid)
            if fr is None or not (fr.known or fid in columns):
                return None
            chain.append((fid, fr))
            fid = fr.parent
        p: tuple[Any, Any, Any] = (0.0, 0.0, 0.0)
        q: tuple[Any, ...] = (0.0, 0.0, 0.0, 1.0)
        for fid, fr in reversed(chain):
            k = columns.get(fid)
            if k is None:
                translation, rotation = fr.translation, fr.rotation
            else:
                translation = tuple(values[:, k, j] for j in range(3))  # type: ignore[assignment]
                rotation = tuple(values[:, k, j] for j in range(3, 7))  # type: ignore[assignment]
            d = _qrot(q, translation)
            p = (p[0] + d[0], p[1] + d[1], p[2] + d[2])
            q = _qmul(q, rotation)
        out = np.empty((values.shape[0], 3))
        out[:] = np.stack(np.broadcast_arrays(*p), axis=-1)
        return out

    def extend(self, points: Any) -> None:
        """Grow the bounding box of drawn points (rows of x y z)."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        lo, hi = self.bbox
        if lo is None or hi is None:
            self.bbox = (points.min(axis=0), points.max(axis=0))
        else:
            self.bbox = (np.minimum(lo, points.min(axis=0)), np.maximum(hi, points.max(axis=0)))
