"""The diagnostics node: checks every system's conservation laws live, on /diagnostics.

It discovers systems by their ``<ns>/system_info`` topics (any process), learns from each which
laws hold and their scales (``SystemInfo.laws`` are ``Law`` keys), and follows ``<ns>/energy``
and ``<ns>/invariants``; each law's value and drift come from its ``Law``. One DiagnosticStatus
per law per system, named ``mechsim/<ns>/<law>``, hardware_id ``<ns>``; level from the relative
drift against the ``warn_drift`` / ``error_drift`` parameters (the worst finite drift of the
epoch sets the level, so an ERROR stays visible; a non-finite sample is ERROR until finite
values return); a system silent for ``stale_timeout`` wall seconds is STALE. Published every
``period`` seconds of wall time, and on demand with :meth:`publish_now`.

Epochs. A system's run is cut into epochs by a reset or an accepted parameter change; every law
re-bases (initial value, worst drift) at the start of each. The signal is in the sample streams
themselves, so it needs no ordering between topics: **a sample whose stamp is not later than the
previous sample of the same stream, from the same publisher, starts a new epoch** for the laws
that stream carries. A reset restarts at t = 0 (the stamp goes back); after a change that keeps
the state, the simulator publishes the current sample again with the new parameters (the same
stamp). A ``system_info`` never re-bases by itself: it updates the set of laws and their scales.

Trust and bounds. Each stream of a system (system_info, energy, invariants) belongs to the first
publisher heard on it; messages from any other publisher are ignored (counted in ``ignored``),
so a spoofed ``system_info`` or sample cannot re-base a running system. When the owning
publisher has left the graph, the system is forgotten and rediscovered with its new publisher.
At most ``max_systems`` namespaces are followed (those that also have an energy topic first); a
followed namespace silent for ``expire_timeout`` (or for ``stale_timeout`` once its topics have
left the graph) is forgotten, subscriptions destroyed; namespaces are followed in turns, and a
silent one not again before ``expire_timeout`` has passed. Messages fed in-process
(:meth:`feed`, or as arrays of a chunk of samples with :meth:`feed_chunk`: no message objects,
the same law tracking, vectorised over the chunk) are trusted.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.context import Context
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.serialization import deserialize_message
from rclpy.subscription import Subscription
from std_msgs.msg import Header

from mechsim.outputs.sink import Sink
from mechsim.outputs.wire import encode
from mechsim.ros.drift import LawState, track, track_prefixes
from mechsim.ros.outlet import DIAGNOSTICS_QOS, LATCHED_QOS, Outlet
from mechsim.systems.base import LEVEL_NAMES, Law
from mechsim_msgs.msg import Energy, NamedScalars, SystemInfo

_SUB_QOS = QoSProfile(depth=1000)
_INFO_TYPE = "mechsim_msgs/msg/SystemInfo"
_REPORT_TYPE = "diagnostic_msgs/msg/DiagnosticArray"
#: A diagnostic_msgs/DiagnosticStatus as the tuple of its fields: level, name, message,
#: hardware_id and the (key, value) pairs (what the wire encoder takes for the message).
StatusRow = tuple[int, str, str, str, list[tuple[str, str]]]
STREAMS = ("system_info", "energy", "invariants")
#: Laws read from one system_info at most (the rest is ignored).
MAX_LAWS = 256
#: How often discovery and expiry run [s, wall time].
HOUSEKEEPING_PERIOD = 0.5


def _stamp_ns(header: Header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def _publisher(info: Any) -> bytes:
    """The publisher GID of a received message (b"" where the middleware gives none)."""
    gid = info.get("publisher_gid") if isinstance(info, dict) else None
    return bytes(gid["data"]) if gid else b""


@dataclass
class SystemState:
    name: str
    info: SystemInfo
    laws: dict[str, LawState] = field(default_factory=dict)
    last_seen: float = field(default_factory=time.monotonic)
    last_stamp: int | None = None  # ns of the latest energy sample
    epoch: int = 0
    #: Per stream: the publisher it belongs to (absent: not heard yet) and its last stamp.
    publishers: dict[str, bytes] = field(default_factory=dict)
    stamps: dict[str, int] = field(default_factory=dict)
    #: The laws of each stream ("energy", "invariants"), in the order of ``laws``.
    streams: dict[str, list[LawState]] = field(default_factory=dict)


@dataclass
class _Follow:
    """A discovered namespace being followed over DDS."""

    subs: list[Subscription[Any]]
    last_heard: float = field(default_factory=time.monotonic)
    suspect: bool = False  # another publisher spoke on a stream: check the owner is still there


class DiagnosticsNode(Node):
    def __init__(self, *, context: Context | None = None, warn_drift: float = Law.WARN_DRIFT,
                 error_drift: float = Law.ERROR_DRIFT, period: float = 1.0,
                 stale_timeout: float = 5.0, expire_timeout: float = 60.0,
                 max_systems: int = 100, sinks: list[Sink] | None = None,
                 discover: bool = True) -> None:
        """``discover=False``: follow only systems fed to it in-process (scene runner)."""
        super().__init__("diagnostics", namespace="mechsim", context=context)
        rng = [FloatingPointRange(from_value=0.0, to_value=1.0)]
        self.declare_parameter("warn_drift", float(warn_drift), ParameterDescriptor(
            description="relative drift of a conservation law that gives WARN",
            floating_point_range=rng))
        self.declare_parameter("error_drift", float(error_drift), ParameterDescriptor(
            description="relative drift of a conservation law that gives ERROR",
            floating_point_range=rng))
        self.declare_parameter("period", float(period), ParameterDescriptor(
            description="publication period of /diagnostics [s, wall time]",
            floating_point_range=[FloatingPointRange(from_value=0.01, to_value=86400.0)]))
        self.declare_parameter("stale_timeout", float(stale_timeout), ParameterDescriptor(
            description="a system silent this long (wall time) is STALE [s]",
            floating_point_range=[FloatingPointRange(from_value=0.1, to_value=3600.0)]))
        self.declare_parameter("expire_timeout", float(expire_timeout), ParameterDescriptor(
            description="a discovered system silent this long (wall time) is forgotten [s]",
            floating_point_range=[FloatingPointRange(from_value=0.1, to_value=86400.0)]))
        self.declare_parameter("max_systems", int(max_systems), ParameterDescriptor(
            description="most systems followed at once (discovery)",
            integer_range=[IntegerRange(from_value=1, to_value=10000)]))
        self.add_on_set_parameters_callback(self._check_thresholds)
        self.systems: dict[str, SystemState] = {}
        self._follows: dict[str, _Follow] = {}
        self._quiet: dict[str, float] = {}  # forgotten while still in the graph: when
        #: Messages received over DDS (a process draining before it stops watches it).
        self.received = 0
        self.ignored = 0  # messages from a publisher that does not own the stream
        self.outlet = Outlet(self, sinks)
        self.t_diag = self.outlet.channel("/diagnostics", DiagnosticArray, DIAGNOSTICS_QOS)
        self.published = 0
        if discover:
            self._housekeeping()
            self.create_timer(HOUSEKEEPING_PERIOD, self._housekeeping)
        self.create_timer(period, self.publish_now)

    def _check_thresholds(self, params: list[Any]) -> SetParametersResult:
        warn = self.get_parameter("warn_drift").value
        err = self.get_parameter("error_drift").value
        for p in params:
            if p.name == "warn_drift":
                warn = p.value
            if p.name == "error_drift":
                err = p.value
        if warn >= err:
            return SetParametersResult(successful=False,
                                       reason="warn_drift must be smaller than error_drift")
        return SetParametersResult(successful=True)

    def _param(self, name: str) -> Any:
        return self.get_parameter(name).value

    # --- discovery, expiry --------------------------------------------------------------------
    def _housekeeping(self) -> None:
        topics = dict(self.get_topic_names_and_types())
        present = {t[: -len("/system_info")] for t, types in topics.items()
                   if t.endswith("/system_info") and _INFO_TYPE in types}
        now = time.monotonic()
        expire, stale = self._param("expire_timeout"), self._param("stale_timeout")
        for ns, follow in list(self._follows.items()):
            silent = now - follow.last_heard
            gone = ns not in present
            if follow.suspect:
                follow.suspect = False
                gone = gone or not self._owners_present(ns)
                if gone:
                    silent = math.inf  # its owner left: follow whoever publishes now
            if silent > expire or (gone and silent > stale):
                self.forget(ns)
                if not gone:
                    self._quiet[ns] = now
        for ns in [ns for ns in self._quiet if ns not in present]:
            del self._quiet[ns]
        limit = int(self._param("max_systems"))
        while len(self._quiet) > 10 * limit:  # oldest first: they may be followed again
            del self._quiet[min(self._quiet, key=self._quiet.__getitem__)]
        # In turns: namespaces with an energy topic first, then those never (or longest not)
        # followed; a silent one waits expire_timeout before it is followed again.
        candidates = sorted((ns for ns in present - self._follows.keys()
                             if now - self._quiet.get(ns, -math.inf) > expire),
                            key=lambda ns: (f"{ns}/energy" not in topics,
                                            self._quiet.get(ns, -math.inf), ns))
        for ns in candidates[: max(0, limit - len(self._follows))]:
            self.watch(ns)

    def _owners_present(self, ns: str) -> bool:
        st = self.systems.get(ns)
        if st is None:
            return True
        for stream, gid in st.publishers.items():
            if not gid:
                continue
            live = {bytes(p.endpoint_gid) for p in
                    self.get_publishers_info_by_topic(f"{ns}/{stream}")}
            if gid not in live:
                return False
        return True

    def watch(self, ns: str) -> None:
        """Follow the system whose topics live under namespace ``ns`` (e.g. "/pendulum"): its
        system_info now, its samples once a system_info has been accepted."""
        if ns in self._follows:
            return
        sub = self.create_subscription(
            SystemInfo, f"{ns}/system_info",
            functools.partial(self._dds, ns, "system_info"), LATCHED_QOS)
        self._follows[ns] = _Follow([sub])

    def forget(self, ns: str) -> None:
        """Stop following ``ns`` and drop what is known about it."""
        follow = self._follows.pop(ns, None)
        if follow is not None:
            for sub in follow.subs:
                self.destroy_subscription(sub)
        self.systems.pop(ns, None)

    def _follow_samples(self, ns: str) -> None:
        follow = self._follows.get(ns)
        if follow is None or len(follow.subs) > 1:
            return
        follow.subs += [
            self.create_subscription(Energy, f"{ns}/energy",
                                     functools.partial(self._dds, ns, "energy"), _SUB_QOS),
            self.create_subscription(NamedScalars, f"{ns}/invariants",
                                     functools.partial(self._dds, ns, "invariants"), _SUB_QOS),
        ]

    # --- receiving ----------------------------------------------------------------------------
    def _dds(self, ns: str, stream: str, msg: Any, info: Any) -> None:
        self.received += 1
        self._receive(ns, stream, msg, _publisher(info))

    def feed(self, ns: str, stream: str, msg: Any) -> None:
        """Hand a message of ``ns``'s ``stream`` ("system_info", "energy", "invariants") to
        the node in-process (trusted: no publisher check)."""
        if stream in STREAMS:
            self._receive(ns, stream, msg, None)

    def feed_chunk(self, ns: str, stream: str, stamps: np.ndarray, values: Any) -> None:
        """Hand consecutive samples of ``ns``'s ``stream`` ("energy" or "invariants") to the
        node in-process, as arrays (trusted): ``stamps`` int64 nanoseconds; ``values`` for
        "energy" anything with ``total``, ``energy_function``, ``work_external`` and
        ``work_dissipated`` arrays (``mechsim.outputs.messages.EnergyColumns``), for
        "invariants" a mapping name -> array."""
        st = self.systems.get(ns)
        if st is None or stream not in ("energy", "invariants") or len(stamps) == 0:
            return
        self._seen(st, ns)
        self._samples(st, stream, np.asarray(stamps, dtype=np.int64), values)

    def _on_info(self, ns: str, info: SystemInfo) -> None:
        self.feed(ns, "system_info", info)

    def _on_energy(self, ns: str, m: Energy) -> None:
        self.feed(ns, "energy", m)

    def _on_invariants(self, ns: str, m: NamedScalars) -> None:
        self.feed(ns, "invariants", m)

    def _owns(self, st: SystemState, ns: str, stream: str, publisher: bytes | None) -> bool:
        """Whether ``publisher`` owns ``stream`` of ``st`` (the first one heard does)."""
        if publisher is None:
            return True
        owner = st.publishers.setdefault(stream, publisher)
        if owner == publisher:
            return True
        self.ignored += 1
        follow = self._follows.get(ns)
        if follow is not None:
            follow.suspect = True
        return False

    def _receive(self, ns: str, stream: str, msg: Any, publisher: bytes | None) -> None:
        st = self.systems.get(ns)
        if stream == "system_info":
            if st is None:
                st = self.systems[ns] = SystemState(msg.instance or ns.strip("/"), msg)
                if publisher is not None:
                    st.publishers["system_info"] = publisher
                self._follow_samples(ns)
            elif not self._owns(st, ns, stream, publisher):
                return
            self._set_laws(st, msg)
        elif st is None or not self._owns(st, ns, stream, publisher):
            return
        self._seen(st, ns)
        if stream == "system_info":
            return
        stamp = np.array([_stamp_ns(msg.header)], dtype=np.int64)
        if stream == "energy":
            self._samples(st, stream, stamp, msg)
        else:
            self._samples(st, stream, stamp, {s.name: s.value for s in msg.scalars})

    def _seen(self, st: SystemState, ns: str) -> None:
        now = time.monotonic()
        st.last_seen = now
        follow = self._follows.get(ns)
        if follow is not None:
            follow.last_heard = now

    def _samples(self, st: SystemState, stream: str, stamps: np.ndarray, values: Any) -> None:
        """Samples of one stream, in the order they were sent (one message, or a chunk):
        ``values`` as :meth:`feed_chunk` takes them (or an Energy message)."""
        taken, matrix = self._law_values(st, stream, values, len(stamps))
        self._track(st, stream, stamps, taken, matrix)

    def law_rows(self, ns: str, stream: str, values: Any, n: int
                 ) -> tuple[list[LawState], np.ndarray] | None:
        """The values of the laws ``ns``'s ``stream`` carries, for ``n`` samples given as
        :meth:`feed_chunk` takes them: (laws, laws × n matrix), for :meth:`feed_rows`; None
        for a system or stream not followed. Valid until the system's laws change (a
        system_info)."""
        st = self.systems.get(ns)
        if st is None or stream not in ("energy", "invariants"):
            return None
        return self._law_values(st, stream, values, n)

    def feed_rows(self, ns: str, stream: str, stamps: np.ndarray, laws: list[LawState],
                  matrix: np.ndarray) -> None:
        """:meth:`feed_chunk` with the law values already taken (:meth:`law_rows`)."""
        st = self.systems.get(ns)
        if st is None or len(stamps) == 0:
            return
        self._seen(st, ns)
        self._track(st, stream, np.asarray(stamps, dtype=np.int64), laws, matrix)

    def feed_prefixes(self, ns: str, stream: str, stamps: np.ndarray, laws: list[LawState],
                      matrix: np.ndarray, ends: list[int]) -> Iterator[None] | None:
        """:meth:`feed_rows` of the samples up to each end in ``ends`` in turn, each taken when
        the iterator is advanced, computed once for all (``track_prefixes``). None where that
        does not apply (a system not followed, a new epoch among the samples, a non-finite
        sample, a law without an initial value): then feed the pieces with :meth:`feed_rows`."""
        st = self.systems.get(ns)
        if st is None or len(stamps) == 0:
            return None
        stamps = np.asarray(stamps, dtype=np.int64)
        previous = st.stamps.get(stream)
        if (previous is not None and int(stamps[0]) <= previous) or (
                len(stamps) > 1 and bool((stamps[1:] <= stamps[:-1]).any())):
            return None  # a new epoch starts among them
        pieces = track_prefixes(laws, matrix, ends)
        if pieces is None:
            return None
        return self._fed_prefixes(st, ns, stream, stamps, ends, pieces)

    def _fed_prefixes(self, st: SystemState, ns: str, stream: str, stamps: np.ndarray,
                      ends: list[int], pieces: Iterator[None]) -> Iterator[None]:
        last = stamps[np.maximum(np.asarray(ends, dtype=np.int64) - 1, 0)].tolist()
        done = 0
        for k, _ in enumerate(pieces):
            if ends[k] > done:
                done = ends[k]
                self._seen(st, ns)
                st.stamps[stream] = last[k]
                if stream == "energy":
                    st.last_stamp = last[k]
            yield

    @staticmethod
    def _law_values(st: SystemState, stream: str, values: Any, n: int
                    ) -> tuple[list[LawState], np.ndarray]:
        """The laws of ``stream`` that ``values`` has, and their values (laws × n)."""
        taken: list[LawState] = []
        rows = []
        for law in st.streams.get(stream, []):
            if stream == "energy":
                rows.append(law.law.value(energy=values))
            elif law.law.name in values:
                rows.append(law.law.value(invariants=values))
            else:
                continue
            taken.append(law)
        return taken, np.array(rows, dtype=float).reshape(len(rows), n)

    def _track(self, st: SystemState, stream: str, stamps: np.ndarray,
               taken: list[LawState], matrix: np.ndarray) -> None:
        """Track ``taken`` over samples stamped ``stamps`` (their values: ``matrix``). A
        stamp not later than the one before it starts a new epoch there."""
        n = len(stamps)
        previous = st.stamps.get(stream)
        last = int(stamps[-1])
        st.stamps[stream] = last
        if stream == "energy":
            st.last_stamp = last
        starts = []
        if n > 1:
            back = stamps[1:] <= stamps[:-1]
            if back.any():
                starts = (np.flatnonzero(back) + 1).tolist()
        if previous is not None and int(stamps[0]) <= previous:
            starts.insert(0, 0)
        if not starts:
            if taken and n:
                track(taken, matrix)
            return
        laws = st.streams.get(stream, [])
        edges = starts if starts[0] == 0 else [0, *starts]
        for a, b in zip(edges, [*edges[1:], n], strict=True):
            if a in starts:
                st.epoch += 1
                for law in laws:
                    law.rebase()
            if taken and b > a:
                track(taken, matrix[:, a:b])

    def _set_laws(self, st: SystemState, info: SystemInfo) -> None:
        """Adopt the laws and scales of ``info``; laws that go on keep their epoch."""
        st.info = info
        laws: dict[str, LawState] = {}
        for key, scale in list(zip(info.laws, info.law_scales, strict=False))[:MAX_LAWS]:
            try:
                law = Law.from_key(key)
            except ValueError:
                continue  # not a law this version knows
            scale = float(scale) if math.isfinite(scale) and scale > 0 else 1.0
            state = st.laws.get(law.key) or LawState(law, scale)
            state.scale = scale
            laws[law.key] = state
        st.laws = laws
        st.streams = {}
        for state in laws.values():
            st.streams.setdefault(state.law.stream, []).append(state)

    # --- output -------------------------------------------------------------------------------
    def _thresholds(self) -> tuple[float, float]:
        return self._param("warn_drift"), self._param("error_drift")

    def level(self, law: LawState, stale: bool,
              thresholds: tuple[float, float] | None = None) -> int:
        """0 OK, 1 WARN, 2 ERROR, 3 STALE; ``thresholds``: (warn, error) drifts, read from
        the parameters when not given."""
        if law.samples == 0 or stale:
            return 3
        if not law.finite_now:
            return 2
        return law.law.level(law.max_drift, *(thresholds or self._thresholds()))

    def status_rows(self) -> list[StatusRow]:
        """The report: one DiagnosticStatus per law per system, as plain values (level, name,
        message, hardware_id, [(key, value), ...]), encoded without building rclpy messages
        (the fields of the message as tuples)."""
        out: list[StatusRow] = []
        timeout = self._param("stale_timeout")
        thresholds = self._thresholds()
        now = time.monotonic()
        for st in self.systems.values():
            stale = now - st.last_seen > timeout
            info = st.info
            epoch = str(st.epoch)
            for key, law in st.laws.items():
                level = self.level(law, stale, thresholds)
                drift, max_drift = law.drift, law.max_drift
                if law.samples == 0:
                    text = "no samples yet"
                elif stale:
                    text = f"stale: no data for {now - st.last_seen:.1f} s"
                else:
                    text = (f"{LEVEL_NAMES[level]}: relative drift {drift:.3g}, "
                            f"max {max_drift:.3g}")
                    if law.nonfinite:
                        text += f", {law.nonfinite} non-finite sample(s)"
                out.append((level, f"mechsim/{st.name}/{key.replace(':', '/')}", text, st.name,
                            [("drift", f"{drift:.6e}"), ("max_drift", f"{max_drift:.6e}"),
                             ("initial", f"{law.initial!r}"), ("current", f"{law.current!r}"),
                             ("scale", f"{law.scale!r}"), ("samples", str(law.samples)),
                             ("nonfinite", str(law.nonfinite)), ("epoch", epoch),
                             ("system", info.system), ("integrator", info.integrator)]))
        return out

    def status_fields(self) -> list[dict[str, Any]]:
        """:meth:`status_rows` as nested dicts (the fields of
        diagnostic_msgs/DiagnosticStatus)."""
        return [{"level": level, "name": name, "message": message, "hardware_id": hardware_id,
                 "values": [{"key": k, "value": v} for k, v in values]}
                for level, name, message, hardware_id, values in self.status_rows()]

    def statuses(self) -> list[DiagnosticStatus]:
        """:meth:`status_rows` as rclpy messages."""
        return [DiagnosticStatus(level=bytes([level]), name=name, message=message,
                                 hardware_id=hardware_id,
                                 values=[KeyValue(key=k, value=v) for k, v in values])
                for level, name, message, hardware_id, values in self.status_rows()]

    def publish_now(self) -> None:
        if not self.systems:
            return
        ns = max((s.last_stamp for s in self.systems.values() if s.last_stamp is not None),
                 default=0)
        data = encode(_REPORT_TYPE, ((divmod(ns, 1_000_000_000), ""), self.status_rows()))
        self.outlet.publish_serialized(
            self.t_diag, data, ns, lambda: deserialize_message(data, DiagnosticArray))
        self.published += 1

    def summary(self) -> list[tuple[str, str, float, int]]:
        """(system, law, worst relative drift of the epoch, level) for every law, for tables."""
        rows = []
        thresholds = self._thresholds()
        for st in self.systems.values():
            for key, law in st.laws.items():
                rows.append((st.name, key, law.worst, self.level(law, False, thresholds)))
        return rows
