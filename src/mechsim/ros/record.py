"""``mechsim record``: run a scene through the real node graph and record every message.

The scene runs in-process (``run_scene(..., fast=True, sinks=[BagWriter])``): every message any
node publishes (state, energy, invariants, observables, /tf, /tf_static, /clock, system_info,
/diagnostics) goes through its Outlet to the bag writer, so the bag holds exactly what was
published (per-topic counts equal ``SceneRun.messages``).

Files. The bag directory must be new or empty; strftime fields in the path are expanded
(default ``runs/<scene>_%Y%m%d-%H%M%S``). Ctrl-C / SIGTERM stop the run cleanly and the bag is
completed (footer, summary, metadata.yaml). A write error (disk full, ...) stops the run and the
partial bag is removed: an error bag is never left looking complete. After a hard kill, the
directory lacks metadata.yaml; ``mechsim bag repair DIR`` completes it from the flushed chunks.
"""

from __future__ import annotations

import importlib.util
import sys
from dataclasses import dataclass, field
from typing import Any

from mechsim.errors import MechsimError

DEFAULT_BAG = "runs/{scene}_%Y%m%d-%H%M%S"


def _msg(text: str) -> None:
    print(f"mechsim: {text}", file=sys.stderr)


def rerun_sink(path: str) -> Any | None:
    """The Rerun sink (``mechsim.outputs.rerun.RerunSink``) if that module exists, else None."""
    if importlib.util.find_spec("mechsim.outputs.rerun") is None:
        _msg(f"--rrd {path}: Rerun output unavailable (mechsim.outputs.rerun not installed); "
             "recording without it")
        return None
    from mechsim.outputs.rerun import RerunSink  # type: ignore[import-not-found,unused-ignore]

    return RerunSink(path)


@dataclass
class Outputs:
    """The recording sinks of one run (bag and/or rrd) and how to finish or drop them."""

    bag: Any = None
    rrd: Any = None
    rrd_path: str | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def sinks(self) -> list[Any]:
        return [s for s in (self.bag, self.rrd) if s is not None]

    def close(self) -> list[str]:
        lines = []
        if self.bag is not None:
            bag, self.bag = self.bag, None
            stats = bag.close()
            lines.append(f"bag {bag.path}: {stats.message_count} messages on "
                         f"{len(stats.topics)} topics")
        if self.rrd is not None:
            rrd, self.rrd = self.rrd, None
            if hasattr(rrd, "close"):
                rrd.close()
            lines.append(f"rrd {self.rrd_path}")
        return lines

    def abort(self) -> None:
        if self.bag is not None:
            bag, self.bag = self.bag, None
            bag.abort()
        if self.rrd is not None:
            rrd, self.rrd = self.rrd, None
            if hasattr(rrd, "close"):
                try:
                    rrd.close()
                except Exception:  # noqa: BLE001 - already failing; the bag error is reported
                    pass


def scene_custom_data(scene: Any) -> dict[str, str]:
    """Run-level ``custom_data`` of the bag (per-instance entries come from system_info)."""
    from mechsim import __version__
    from mechsim.outputs.messages import DEFAULT_TIME_OFFSET

    data = {"mechsim.version": __version__, "mechsim.scene": scene.name,
            "mechsim.instances": ",".join(i.name for i in scene.systems),
            "mechsim.systems": ",".join(i.system for i in scene.systems),
            "mechsim.publish_rate": repr(float(scene.publish_rate)),
            "mechsim.time_offset": repr(float(DEFAULT_TIME_OFFSET))}
    if scene.source is not None:
        data["mechsim.scene_file"] = str(scene.source)
    for inst in scene.systems:
        data[f"mechsim.{inst.name}.method"] = inst.method
        data[f"mechsim.{inst.name}.origin"] = ",".join(repr(float(x)) for x in inst.origin)
    return data


def open_outputs(scene: Any, bag: str | None, rrd: str | None) -> Outputs:
    from mechsim.environment import import_rclpy

    import_rclpy()
    from mechsim.outputs.bag import BagWriter

    out = Outputs(rrd_path=rrd)
    if bag is not None:
        out.bag = BagWriter(bag.replace("{scene}", scene.name), scene_custom_data(scene))
    if rrd is not None:
        try:
            out.rrd = rerun_sink(rrd)
        except BaseException:
            out.abort()
            raise
    return out


def run_with_outputs(scene: Any, *, fast: bool | None, duration: float | None,
                     bag: str | None, rrd: str | None = None,
                     progress: Any = None) -> tuple[Any, list[str]]:
    """``run_scene`` with the bag / rrd sinks attached; returns (SceneRun, output lines).
    Write errors: the partial outputs are removed and MechsimError names the path."""
    from mechsim.ros.launch import run_scene

    out = open_outputs(scene, bag, rrd)
    where = f"bag {out.bag.path}" if out.bag is not None else f"rrd {rrd}"
    try:
        run = run_scene(scene, fast=fast, duration=duration, sinks=out.sinks, progress=progress)
        lines = out.close()
    except OSError as e:
        out.abort()
        raise MechsimError(f"{where}: write failed ({e.strerror or e}); partial output "
                           "removed") from None
    except MechsimError:
        out.abort()
        raise
    except BaseException:
        out.close()  # Ctrl-C outside the run loop: keep what was recorded, complete
        raise
    return run, lines
