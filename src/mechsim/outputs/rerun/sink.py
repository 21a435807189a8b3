"""The Rerun sink: a recording (a ``.rrd`` file, or a live stream to a viewer) fed by a run.

A run hands it each chunk of samples as evaluated values (``write_columns``) and the other
messages one by one (``write``), which turns a sample's message into one-row columns: both are
drawn by the same code (``drawing``), so a recording made live and one converted from the run's
bag are the same, row for row. Whatever changes how later samples are drawn (system_info,
/tf_static) draws what was gathered first.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
import threading
import time
import uuid
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mechsim.errors import MechsimError
from mechsim.files import publish
from mechsim.outputs.rerun.blueprint import blueprint
from mechsim.outputs.rerun.drawing import Drawing, transform_columns
from mechsim.outputs.rerun.entities import ENERGY_TERMS, stamp_ns
from mechsim.outputs.rerun.series import Buffers
from mechsim.outputs.rerun.world import World
from mechsim.outputs.sink import Capabilities, Takes

if TYPE_CHECKING:
    from mechsim.outputs.messages import Columns

#: Types the sink draws; messages of others are ignored.
HANDLED_TYPES = {
    "mechsim_msgs/msg/SystemInfo", "mechsim_msgs/msg/Energy", "mechsim_msgs/msg/NamedScalars",
    "sensor_msgs/msg/JointState", "tf2_msgs/msg/TFMessage",
    "diagnostic_msgs/msg/DiagnosticArray",
}
#: Topics published with every sample whose types nothing here draws: their messages are not
#: made for this sink (its ``wants``). (markers: the recording draws the model's look itself;
#: sample_batch: the same values as the per-sample topics it draws.)
_NOT_DRAWN = ("clock", "pose", "twist", "markers", "markers_static", "markers_trails",
              "sample_batch")
#: Live streams: buffered columns are sent at least this often [s of wall time].
LIVE_PERIOD = 0.1
#: Live streams: how long :meth:`RerunSink.close` waits for the viewer to take the rest [s].
LIVE_FLUSH_TIMEOUT = 10.0
#: Live streams: the whole close (the rest sent, taken, the connection shut) is bounded by
#: this [s]; a viewer that accepts a connection and never answers costs no more. After Ctrl-C
#: the bound is ``INTERRUPTED_CLOSE_TIMEOUT`` (``close_timeout``).
LIVE_CLOSE_TIMEOUT = LIVE_FLUSH_TIMEOUT + 5.0
INTERRUPTED_CLOSE_TIMEOUT = 2.0
#: Longest wait for Rerun to write what it buffered when a recording is closed [s] (a file
#: writer that died on a full disk can leave a flush waiting without a bound).
FLUSH_TIMEOUT = 120.0

#: Recordings whose file writer stopped or hung (a full disk): kept referenced, since dropping
#: one flushes it again without a bound, and Rerun's exit hook is unregistered for the same
#: reason; a command that saw one ends its process with ``os._exit`` (``writer_stuck``).
_STUCK: list[Any] = []


def writer_stuck() -> bool:
    """Whether a recording's file writer failed in this process: exiting normally would wait
    on it without a bound (Rerun's exit hook flushes every recording)."""
    return bool(_STUCK)


def drawn(topic: str) -> bool:
    """The topics a RerunSink wants: all but those of types never drawn (clock, pose,
    twist, markers, markers_static, markers_trails, sample_batch)."""
    return topic.rpartition("/")[2] not in _NOT_DRAWN


class RerunSink:
    """Sink writing a Rerun ``.rrd`` recording; call :meth:`close` to finish the file. It
    takes columns (``mechsim.outputs.sink``), and every topic but :data:`_NOT_DRAWN`'s.

    The recording is written into a private temporary directory (``mkdtemp``, mode 0700) beside
    ``path`` and renamed onto ``path`` by :meth:`close` once Rerun has flushed it completely, so
    a failed write (a full disk) never leaves a half-written ``path``, and the error names it.
    ``replace=False``: an existing ``path`` is never overwritten (MechsimError at close);
    :meth:`discard` drops the recording. After a hard kill the recording so far stays in the
    hidden ``.<name>.*.partial`` directory (Rerun reads it)."""

    #: The file written (None for a live stream); a live stream's viewer URL and the bound of
    #: its close.
    path: Path | None
    _tmpdir: Path | None
    url: str | None = None
    close_timeout: float = 0.0

    def __init__(self, path: str | Path, *, application_id: str = "mechsim",
                 recording_id: str | None = None, replace: bool = True) -> None:
        import rerun as rr

        self.path: Path | None = Path(path)
        self.replace = replace
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._tmpdir = Path(tempfile.mkdtemp(prefix=f".{self.path.name}.", suffix=".partial",
                                                 dir=self.path.parent))
        except OSError as e:
            raise MechsimError(f"rrd {self.path}: cannot write ({e.strerror or e})") from None
        self._tmp = self._tmpdir / self.path.name
        try:
            self.rec = rr.RecordingStream(
                application_id, recording_id=recording_id or f"mechsim-{uuid.uuid4()}")
            self.rec.save(str(self._tmp), default_blueprint=blueprint())
        except BaseException:
            self._remove_tmp()
            raise
        self._start(live=False)

    @classmethod
    def live(cls, url: str, *, application_id: str = "mechsim",
             recording_id: str | None = None) -> RerunSink:
        """A sink streaming to the Rerun viewer or server at ``url`` (``rerun+http://…/proxy``)
        instead of a file. The blueprint is sent once the systems are known and again, as the
        .rrd's, by :meth:`close`, which waits up to ``LIVE_FLUSH_TIMEOUT`` s for the rest to
        be taken; the viewer keeps what it received."""
        import rerun as rr

        self = cls.__new__(cls)
        self.path, self.replace, self._tmpdir = None, False, None
        self.url, self.close_timeout = url, LIVE_CLOSE_TIMEOUT
        self.rec = rr.RecordingStream(
            application_id, recording_id=recording_id or f"mechsim-{uuid.uuid4()}")
        self.rec.connect_grpc(url, default_blueprint=blueprint())
        self._start(live=True)
        return self

    def _start(self, *, live: bool) -> None:
        import rerun as rr

        from mechsim.outputs.messages import DEFAULT_TIME_OFFSET

        self.rec.set_log_time_enabled(False)
        self.rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self.world = World(self.rec, int(round(DEFAULT_TIME_OFFSET * 1e9)))
        self.buffers = Buffers(self.rec)
        self.drawing = Drawing(self.rec, self.world, self.buffers)
        self.messages = 0
        self.closed = False
        self._live_next: float | None = time.monotonic() + LIVE_PERIOD if live else None
        #: A live stream gets each sample as it is published.
        self.capabilities = Capabilities(Takes.COLUMNS, immediate=live, wants=drawn)
        self._live_blueprint: tuple[Any, ...] = ()

    # --- sink protocol ------------------------------------------------------------------------
    def write_columns(self, topic: str, ns: np.ndarray, values: Columns) -> None:
        """A chunk of samples stamped ``ns`` as evaluated values: energy terms, /tf
        transforms, or name -> values (state positions, invariants, observables). Gathered
        per stream and drawn in blocks of rows."""
        self.messages += len(ns)
        self.drawing.gather(topic, ns, values)
        self._maybe_send_live()

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        """One message. Samples (energy, state, invariants, observables, transforms) become
        one-row columns, drawn by the code :meth:`write_columns` uses; system_info,
        /tf_static and diagnostics apply to what follows them, so what was gathered before
        is drawn first."""
        if type_name not in HANDLED_TYPES:
            return
        self.messages += 1
        base, _, leaf = topic.rpartition("/")
        drawing = self.drawing
        if type_name == "tf2_msgs/msg/TFMessage":
            latched = leaf == "tf_static"
            if latched:
                drawing.settle()
            for stamp, columns in transform_columns(msg):
                stream = drawing.gather(topic, np.array([stamp], dtype=np.int64), columns)
                if latched:
                    drawing.draw(stream)
        elif type_name == "diagnostic_msgs/msg/DiagnosticArray":
            if not stamp_ns(msg.header.stamp):  # drawn at the latest sample time: known once
                drawing.settle()                # drawn
            drawing.diagnostics(msg)
        elif type_name == "mechsim_msgs/msg/SystemInfo":
            drawing.settle()
            self.world.on_info(base.strip("/"), msg)
        else:
            self._sample(topic, type_name, leaf, msg)
        self._maybe_send_live()

    def _sample(self, topic: str, type_name: str, leaf: str, msg: Any) -> None:
        """An Energy, NamedScalars or JointState message as one-row columns."""
        stamp = np.array([stamp_ns(msg.header.stamp)], dtype=np.int64)
        if type_name == "mechsim_msgs/msg/Energy":
            from mechsim.outputs.messages import EnergyColumns

            self.drawing.gather(topic, stamp, EnergyColumns(**{
                name: np.array([float(getattr(msg, name))]) for name in ENERGY_TERMS}))
        elif type_name == "mechsim_msgs/msg/NamedScalars":
            self.drawing.gather(topic, stamp, {s.name: np.array([float(s.value)])
                                               for s in msg.scalars})
        elif leaf == "state":  # JointState
            self.drawing.gather(topic, stamp, {name: np.array([float(value)]) for name, value
                                               in zip(msg.name, msg.position, strict=False)})

    def rows(self, entity: str) -> int:
        """Rows sent or buffered so far for ``entity`` (a path without leading '/')."""
        self.drawing.settle()
        return self.buffers.rows(entity)

    def _blueprint(self) -> Any:
        return blueprint(self.world.systems.values(), self.world.bbox, self.buffers.peaks,
                         self.buffers.series)

    # --- finishing ----------------------------------------------------------------------------
    def close(self) -> None:
        """Send the buffered columns and the final blueprint; finish the file and rename it
        onto ``path``. Idempotent. MechsimError naming the file if it could not be written
        (nothing is left at ``path`` then, nor a temporary)."""
        if self.closed:
            return
        self.closed = True
        if self._live_next is not None:
            self._close_live()
            return
        try:
            self._send_buffered()
            self.rec.send_blueprint(self._blueprint(), make_active=True, make_default=True)
            # RuntimeError if Rerun's file writer stopped (disk full, ...) or, bounded, hangs.
            self.rec.flush(timeout_sec=FLUSH_TIMEOUT)
            self.rec.disconnect()
            fd = os.open(self._tmp, os.O_RDONLY | os.O_NOFOLLOW)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
            assert self.path is not None  # a file sink
            publish(self._tmp, self.path, replace=self.replace)
        except FileExistsError:
            raise MechsimError(f"rrd {self.path}: exists (not replaced)") from None
        except OSError as e:
            raise MechsimError(f"rrd {self.path}: write failed ({e.strerror or e}); "
                               "nothing written") from None
        except RuntimeError as e:
            import rerun as rr

            _STUCK.append(self.rec)
            with contextlib.suppress(Exception):
                rr.unregister_shutdown()
            raise MechsimError(f"rrd {self.path}: write failed (Rerun's file writer stopped: "
                               f"{str(e).splitlines()[0] if str(e) else 'no reason given'}); "
                               "nothing written") from None
        finally:
            self._remove_tmp()

    def discard(self) -> None:
        """Stop and drop the recording: ``path`` is left as it was. Idempotent."""
        if not self.closed:
            self.closed = True
            with contextlib.suppress(Exception):
                self.rec.disconnect()
        self._remove_tmp()

    def _close_live(self) -> None:
        """Send the rest, wait for the viewer to take it, disconnect: in a worker thread,
        since Rerun's flush and disconnect can block in native code without a bound (and
        without Ctrl-C) on a peer that never answers; the caller waits ``close_timeout`` s at
        most, then gives the stream up (``_STUCK``) with a one-line MechsimError."""
        failure: list[BaseException] = []
        done = threading.Event()

        def finish() -> None:
            try:
                self._send_buffered()
                self.rec.send_blueprint(self._blueprint(), make_active=True, make_default=True)
                self.rec.flush(timeout_sec=min(LIVE_FLUSH_TIMEOUT, self.close_timeout))
            except BaseException as e:  # noqa: BLE001 - handed to the caller
                failure.append(e)
            finally:
                with contextlib.suppress(Exception):
                    self.rec.disconnect()
                done.set()

        threading.Thread(target=finish, name="rerun-live-close", daemon=True).start()
        if not done.wait(self.close_timeout):
            import rerun as rr

            _STUCK.append(self.rec)
            with contextlib.suppress(Exception):
                rr.unregister_shutdown()
            raise MechsimError(f"live view {self.url}: the viewer did not take the rest of the "
                               f"run within {self.close_timeout:g} s (it does not answer); what "
                               "it took is kept")
        if failure:
            raise failure[0]

    def _maybe_send_live(self) -> None:
        if self._live_next is not None and time.monotonic() >= self._live_next:
            self._send_live()

    def _send_live(self) -> None:
        """Send every buffered column; the blueprint too once the systems (or the 3D extent
        that places the camera) are first known."""
        self._send_buffered()
        shown = (tuple(st.key for st in self.world.systems.values()),
                 self.world.bbox[0] is not None)
        if shown != self._live_blueprint and shown[0]:
            self._live_blueprint = shown
            self.rec.send_blueprint(self._blueprint(), make_active=True, make_default=True)
        self._live_next = time.monotonic() + LIVE_PERIOD

    def _send_buffered(self) -> None:
        """Draw everything gathered and send every entity's buffered columns."""
        self.drawing.settle()
        self.buffers.flush_all()

    def _remove_tmp(self) -> None:
        if self._tmpdir is not None:
            shutil.rmtree(self._tmpdir, ignore_errors=True)

    def __enter__(self) -> RerunSink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
