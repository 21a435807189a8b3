"""Rerun recordings of a run: the same ROS messages a run publishes (or a bag holds), drawn.

``RerunSink(path)`` is a sink taking columns (``mechsim.outputs.sink``): a run hands it each
chunk of samples as evaluated values (``write_columns(topic, ns, values)``: energy terms, /tf
transforms, state positions, invariants, observables) and the other messages one by one
(``write``); ``convert_bag(bag, path)`` feeds a rosbag2 MCAP bag's messages through ``write``,
which turns a sample's message into one-row columns: both are drawn by the same code, so a
recording made live and one converted from the run's bag are the same, row for row.

Layout of the recording (Rerun 0.41, one timeline ``sim_time``: duration = stamp − time_offset):

  world                                  ViewCoordinates RIGHT_HAND_Z_UP (REP-103), static
  world/<ns>/<frame>[/<frame>...]        Transform3D of each /tf, /tf_static frame relative to its
                                         parent entity (quaternions xyzw, as in ROS)
  <frame entity>/sphere|box|arrow|polyline_<k>   the model's ``Visual`` shapes, static, in the frame
  <frame entity>                         TransformAxes3D for "axes" visuals
  world/<ns>/visuals/link_<a>_<b>        segment between two frame origins, in world coordinates
  world/<ns>/visuals/trail_<frame>       one segment per sample (previous → current origin); the
                                         blueprint shows it over all past time, i.e. a growing path
  plots/<ns>/energy/<term>               kinetic, potential, total, energy_function,
                                         work_external, work_dissipated [J]
  plots/<ns>/balance_residual            (total − total₀) − (W_ext − W_diss) [J]
  plots/<ns>/drift/<invariant>           I − I₀ (a constraint residual as it is: it should be 0),
                                         as the invariant's ``Law`` (from system_info) says
  plots/<ns>/invariants/<name>, plots/<ns>/observables/<name>, plots/<ns>/state/<coordinate>
  plots/<ns>/diagnostics/<law>           level 0 OK, 1 WARN, 2 ERROR, 3 STALE from /diagnostics
                                         statuses named ``mechsim/<ns>/<law>``

``RerunSink.live(url)`` streams the same entities and blueprint to a Rerun viewer or server
(gRPC, ``rerun+http://HOST:PORT/proxy``; ``mechsim.outputs.rerun_live`` serves one on loopback)
instead of writing a file: the buffered columns are sent every ``LIVE_PERIOD`` s of wall time.

One module per job: :mod:`.sink` (the sink: file or live stream, messages to columns),
:mod:`.world` (systems, frames, visuals), :mod:`.drawing` (samples gathered per stream and
drawn in blocks), :mod:`.series` (rows buffered and sent as columns), :mod:`.blueprint` (the
layout), :mod:`.convert` (bag to recording, the viewer), :mod:`.entities` (shared names).

Rerun's own log lines about a failed file write or a stalled viewer are silenced (``RUST_LOG``,
unless the user set it): the sink reports either itself, in one line naming the output.
"""

import os

os.environ.setdefault("RUST_LOG", "warn,re_log_encoding=off,re_grpc_client=off")

from mechsim.outputs.rerun.convert import convert_bag, viewer_command  # noqa: E402
from mechsim.outputs.rerun.entities import ENERGY_TERMS, TIMELINE
from mechsim.outputs.rerun.sink import (
    FLUSH_TIMEOUT,
    HANDLED_TYPES,
    LIVE_FLUSH_TIMEOUT,
    LIVE_PERIOD,
    RerunSink,
    drawn,
    writer_stuck,
)

__all__ = [
    "ENERGY_TERMS", "FLUSH_TIMEOUT", "HANDLED_TYPES", "LIVE_FLUSH_TIMEOUT", "LIVE_PERIOD",
    "TIMELINE", "RerunSink", "convert_bag", "drawn", "viewer_command", "writer_stuck",
]
