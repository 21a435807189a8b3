"""``mechsim record``: run a scene through the real node graph and record every message.

The scene runs in-process (``run_scene(..., fast=True, sinks=[BagWriter])``): every message any
node publishes (state, energy, invariants, observables, /tf, /tf_static, /clock, system_info,
/diagnostics) goes through its Outlet to the bag writer, so the bag holds exactly what was
published (per-topic counts equal ``SceneRun.messages``).

Files. The bag directory must be new or empty; strftime fields in the path are expanded
(default ``runs/<scene>_%Y%m%d-%H%M%S``; the scene name can never make it leave ``runs/``).
Ctrl-C / SIGTERM stop the run cleanly and the bag is completed (footer, summary,
metadata.yaml); a stop that arrives while the outputs are being opened or closed is held until
they are consistent. A recording is never deleted once it holds a message: on any error (disk
full, a failed node, a bug) the outputs are closed and completed with what was recorded, and the
error is reported with what was kept. Only an output that received nothing is removed. After a
hard kill the directory lacks metadata.yaml; ``mechsim bag repair DIR`` completes it from the
flushed chunks.
"""

from __future__ import annotations

import contextlib
import importlib.util
import sys
from dataclasses import dataclass, field
from typing import Any

from mechsim.errors import MechsimError, counted, one_line
from mechsim.runcore.stops import held_signals

DEFAULT_BAG = "runs/{scene}_%Y%m%d-%H%M%S"


def _msg(text: str) -> None:
    print(f"mechsim: {text}", file=sys.stderr)


def rerun_sink(path: str, replace: bool = False) -> Any | None:
    """The Rerun sink (``mechsim.outputs.rerun.RerunSink``) if that module exists, else None.
    An existing ``path`` is replaced only with ``replace`` (once the new one is complete)."""
    if importlib.util.find_spec("mechsim.outputs.rerun") is None:
        _msg(f"--rrd {path}: Rerun output unavailable (mechsim.outputs.rerun not installed); "
             "recording without it")
        return None
    from mechsim.outputs.rerun import RerunSink  # type: ignore[import-not-found,unused-ignore]

    return RerunSink(path, replace=replace)


@dataclass
class Outputs:
    """The sinks of one run (bag, rrd, live Rerun stream) and how to finish them."""

    bag: Any = None
    rrd: Any = None
    rrd_path: str | None = None
    live: Any = None  # RerunSink.live: what it sent stays in the viewer
    live_url: str | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def sinks(self) -> list[Any]:
        return [s for s in (self.bag, self.rrd, self.live) if s is not None]

    def close(self) -> list[str]:
        """Finish every output normally; lines describing them. A write error is raised (as
        OSError or MechsimError) after every output was closed."""
        lines = []
        error: BaseException | None = None
        if self.bag is not None:
            bag, self.bag = self.bag, None
            try:
                stats = bag.close()
                lines.append(f"bag {bag.path}: {counted(stats.message_count, 'message')} "
                             f"on {counted(len(stats.topics), 'topic')}")
            except Exception as e:  # noqa: BLE001 - the rrd is closed first, then raised
                self.bag = bag
                error = e
        if self.rrd is not None:
            rrd, self.rrd = self.rrd, None
            try:
                if hasattr(rrd, "close"):
                    rrd.close()
                lines.append(f"rrd {self.rrd_path}")
            except Exception as e:  # noqa: BLE001
                error = error or e
        if self.live is not None:
            live, self.live = self.live, None
            try:
                live.close()
                lines.append(f"live view {self.live_url}: {live.messages} messages sent")
            except Exception as e:  # noqa: BLE001
                error = error or e
        if error is not None:
            raise error
        return lines

    def finish_after_error(self) -> str:
        """Close and complete every output after an error, keeping what was recorded (an
        output that received nothing is removed). Returns what was kept, in one sentence."""
        kept = []
        if self.bag is not None:
            bag, self.bag = self.bag, None
            kept.append(_complete_bag(bag, bag.received))
        if self.rrd is not None:
            rrd, self.rrd = self.rrd, None
            try:
                if hasattr(rrd, "close"):
                    rrd.close()
                kept.append(f"rrd {self.rrd_path} closed with what was written")
            except Exception:  # noqa: BLE001 - the first error is the one reported
                kept.append(f"rrd {self.rrd_path} left as written")
        if self.live is not None:
            live, self.live = self.live, None
            with contextlib.suppress(Exception):  # the viewer keeps what it received
                live.close()
        return "; ".join(kept)


def _complete_bag(bag: Any, recorded: int) -> str:
    """Complete a bag after an error with what it holds; remove it only if it holds nothing."""
    if recorded == 0:
        try:
            bag.abort()
            return f"bag {bag.path}: nothing was recorded; removed"
        except Exception:  # noqa: BLE001
            return f"bag {bag.path}: nothing was recorded"
    try:
        stats = bag.close()
        return f"bag {bag.path}: completed with the {stats.message_count} messages recorded"
    except Exception:  # noqa: BLE001 - the writer failed: complete the file from its chunks
        pass
    try:
        from mechsim.outputs.bag import repair_bag

        r = repair_bag(bag.path)
        return f"bag {bag.path}: completed with the {r.messages} messages written"
    except Exception:  # noqa: BLE001 - e.g. still no space: leave it for `bag repair`
        return (f"bag {bag.path}: kept as written (complete it with `mechsim bag repair "
                f"{bag.path}`)")


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


def bag_path(template: str, scene: Any) -> str:
    """The bag path for ``scene``: ``{scene}`` replaced by its (checked) name."""
    from mechsim.params import check_text
    from mechsim.scene import scene_name

    check_text("--bag", template)
    return template.replace("{scene}", scene_name(scene.name))


def open_outputs(scene: Any, bag: str | None, rrd: str | None,
                 live: str | None = None) -> Outputs:
    """The run's sinks: a bag at ``bag``, a recording at ``rrd``, a live stream to the Rerun
    viewer or server at the URL ``live`` (``RerunSink.live``)."""
    from mechsim.environment import import_rclpy

    import_rclpy()
    from mechsim.outputs.bag import BagWriter
    from mechsim.params import check_text

    out = Outputs(rrd_path=rrd, live_url=live)
    path = bag_path(bag, scene) if bag is not None else None
    if rrd is not None:
        check_text("--rrd", rrd)
    if path is not None:
        from mechsim.outputs.batch import recorded

        out.bag = BagWriter(path, scene_custom_data(scene),
                            topics=recorded(getattr(scene, "bag_topics", "samples")))
    if rrd is not None:
        try:
            out.rrd = rerun_sink(rrd, replace=bool(getattr(scene, "force", False)))
        except BaseException:
            out.finish_after_error()
            raise
    if live is not None:
        try:
            from mechsim.outputs.rerun import RerunSink

            out.live = RerunSink.live(live)
        except BaseException:
            out.finish_after_error()
            raise
    return out


def _failure(where: str, e: BaseException, kept: str) -> MechsimError:
    """One line: what failed and why, then what was kept."""
    if isinstance(e, OSError):
        name = f"{e.filename}" if e.filename else where
        why = f"{name}: write failed ({e.strerror or e})"
    elif isinstance(e, MechsimError):
        why = str(e)
    else:
        why = f"the run failed ({type(e).__name__}: {(str(e).splitlines() or [''])[0]})"
    return MechsimError(one_line(f"{why}; {kept}" if kept else why)[:1000])


def run_with_outputs(scene: Any, *, fast: bool | None, duration: float | None,
                     bag: str | None, rrd: str | None = None, live: str | None = None,
                     progress: Any = None, lossless: bool = False) -> tuple[Any, list[str]]:
    """``run_scene`` with the bag / rrd / live Rerun sinks attached (``open_outputs``);
    returns (SceneRun, output lines).
    An error is a MechsimError (one line: the output, the reason, what was kept); Ctrl-C or
    SIGTERM outside the run loop completes the outputs and is raised as KeyboardInterrupt."""
    from mechsim.outputs.rerun.sink import INTERRUPTED_CLOSE_TIMEOUT
    from mechsim.ros.launch import run_scene

    out: Outputs | None = None
    try:
        with held_signals():
            out = open_outputs(scene, bag, rrd, live)
        run = run_scene(scene, fast=fast, duration=duration, sinks=out.sinks, lossless=lossless,
                        progress=progress)
        writer = out.bag
        if run.interrupted and out.live is not None:  # stopped: wait only briefly for a viewer
            out.live.close_timeout = INTERRUPTED_CLOSE_TIMEOUT
        with held_signals():
            try:
                lines = out.close()
            except MechsimError as e:
                if not run.interrupted:
                    raise
                # Stopped by Ctrl-C: the stop's exit status stands, the output's error is said.
                print(f"mechsim: {one_line(str(e))}", file=sys.stderr)
                lines = []
        if writer is not None:
            run.costs["write"] = writer.write_seconds
    except KeyboardInterrupt:
        if out is not None:
            if out.live is not None:  # a stopped run waits only briefly for a viewer
                out.live.close_timeout = INTERRUPTED_CLOSE_TIMEOUT
            with held_signals():
                try:
                    out.close()
                except Exception:  # noqa: BLE001 - stopping anyway; keep what can be kept
                    out.finish_after_error()
        raise
    except Exception as e:
        if out is None:
            raise
        where = (f"bag {out.bag.path}" if out.bag is not None else
                 f"rrd {rrd}" if rrd is not None else f"live view {live}")
        with held_signals():
            kept = out.finish_after_error()
        raise _failure(where, e, kept) from None
    return run, lines
