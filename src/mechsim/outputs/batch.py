"""Samples as columns: the ``<ns>/sample_batch`` topic (``mechsim_msgs/SampleBatch``), one
message per block of samples a simulator computes, and its consumers' side.

- :class:`BatchEncoder`: a block of samples (``messages.Chunk``) as one message's CDR bytes,
  the values those of the per-sample topics bit for bit (the same arrays go into both).
- :func:`decode`: the bytes of one message as a :class:`SampleBatch` of numpy arrays,
  checked against the bytes' length: a message from a peer or a file
  costs bounded time and memory whatever its counts declare.
- :func:`read_batches`: the batches of a bag; :func:`joined`: many batches as one.
- Which topics a recording holds (:func:`recorded`): the per-sample topics, the batches, or
  both (``outputs.bag_topics`` of a scene, ``--bag-topics``: ``scene.BAG_TOPICS``).

A live subscription that yields batches is :mod:`mechsim.ros.batches`.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from mechsim.errors import MechsimError
from mechsim.outputs.messages import Chunk, EnergyColumns, MessageFactory
from mechsim.scene import BAG_TOPICS

#: The topic (in an instance's namespace) and its type.
TOPIC = "sample_batch"
TYPE = "mechsim_msgs/msg/SampleBatch"
#: The column groups of a batch, in the message's order.
GROUPS = ("positions", "velocities", "energy", "invariants", "observables")
#: The energy columns, as on ``<ns>/energy``.
ENERGY_TERMS = ("kinetic", "potential", "total", "energy_function", "work_external",
                "work_dissipated")
#: Samples of one batch message at most (a longer release is sent as several).
MAX_SAMPLES = 1000
#: builtin_interfaces/Time as it lies in a CDR sequence (int32 sec, uint32 nanosec).
TIME_RECORD = np.dtype([("sec", "<i4"), ("nanosec", "<u4")])

#: The topics that follow the samples (in an instance's namespace, or global): one message
#: per sample, and the trail bodies (``markers_trails``) with the samples where they change.
PER_SAMPLE_TOPICS = ("state", "pose", "twist", "energy", "invariants", "observables",
                     "markers", "markers_trails")
PER_SAMPLE_GLOBAL = ("/tf", "/clock")


def is_batch_topic(topic: str) -> bool:
    return topic.rpartition("/")[2] == TOPIC


def is_per_sample_topic(topic: str) -> bool:
    base, _, leaf = topic.rpartition("/")
    return topic in PER_SAMPLE_GLOBAL or (bool(base) and leaf in PER_SAMPLE_TOPICS)


def recorded(bag_topics: str) -> Callable[[str], bool]:
    """Which topics a recording of ``bag_topics`` (``scene.BAG_TOPICS``) wants, by name."""
    if bag_topics == "samples":
        return lambda topic: not is_batch_topic(topic)
    if bag_topics == "batches":
        return lambda topic: not is_per_sample_topic(topic)
    if bag_topics == "both":
        return lambda topic: True
    raise MechsimError(f"bag_topics: one of {', '.join(BAG_TOPICS)} (got {bag_topics!r})")


def recorder_subscribed(subscribers: dict[str, int], bag_topics: str | None = None) -> bool:
    """Has a recorder subscribed to every topic it records (``subscribers``: the count of
    each topic of a node; ``bag_topics``: what it records, None: any of ``BAG_TOPICS``)?"""
    choices = BAG_TOPICS if bag_topics is None else (bag_topics,)
    return any(all(n > 0 for t, n in subscribers.items() if recorded(c)(t)) for c in choices)


def _rate_unit(unit: str) -> str:
    return f"{unit}/s" if unit else "1/s"


class BatchEncoder:
    """The ``SampleBatch`` messages of one model (names and units from ``factory``)."""

    def __init__(self, factory: MessageFactory) -> None:
        m = factory.model
        names = factory.coordinate_names
        units = [c.unit for c in m.coordinates]
        self.factory = factory
        self.names = {"positions": (names, units),
                      "velocities": (names, [_rate_unit(u) for u in units]),
                      "energy": (list(ENERGY_TERMS), ["J"] * len(ENERGY_TERMS)),
                      "invariants": (factory.invariant_names, factory.invariant_units),
                      "observables": (factory.observable_names, factory.observable_units)}

    def encode(self, times: np.ndarray, c: Chunk, a: int, b: int) -> bytes:
        """Samples ``a`` to ``b`` (exclusive) of the chunk ``c`` (simulation times
        ``times``) as one message; energy, invariants and observables must be evaluated
        (those the model has)."""
        from mechsim.outputs.wire import encode

        ns = c.ns[a:b]
        stamps = np.empty(b - a, TIME_RECORD)
        stamps["sec"] = ns // 1_000_000_000
        stamps["nanosec"] = ns % 1_000_000_000
        assert c.energy is not None
        e = EnergyColumns.of(c)
        columns = {"positions": _columns(c.q, a, b), "velocities": _columns(c.v, a, b),
                   "energy": [x[a:b] for x in (e.kinetic, e.potential, e.total,
                                               e.energy_function, e.work_external,
                                               e.work_dissipated)],
                   "invariants": _columns(c.invariants, a, b),
                   "observables": _columns(c.observables, a, b)}
        value: dict[str, Any] = {
            "header": {"stamp": (int(stamps["sec"][0]), int(stamps["nanosec"][0])),
                       "frame_id": "world"},
            "stamps": stamps, "time": np.ascontiguousarray(times[a:b], dtype="<f8")}
        for group in GROUPS:
            names, units = self.names[group]
            value[group] = list(zip(names, units, columns[group], strict=True))
        return encode(TYPE, value)


def _columns(matrix: np.ndarray | None, a: int, b: int) -> list[np.ndarray]:
    """Rows ``a`` to ``b`` of each column of ``matrix`` (none if it was not evaluated: the
    model has no such values)."""
    return [] if matrix is None else [matrix[a:b, j] for j in range(matrix.shape[1])]


@dataclass(frozen=True)
class Series:
    """Named columns: ``values[:, k]`` is quantity ``names[k]`` (unit ``units[k]``) at each
    sample; ``series["theta"]`` is one column."""

    names: tuple[str, ...]
    units: tuple[str, ...]
    values: np.ndarray  # (samples, columns)

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.values[:, self.names.index(name)]
        except ValueError:
            from mechsim.errors import did_you_mean

            raise KeyError(f"no column {name!r}{did_you_mean(name, self.names, 'columns')}"
                           ) from None

    def __contains__(self, name: object) -> bool:
        return name in self.names

    def __len__(self) -> int:
        return len(self.names)


@dataclass(frozen=True)
class SampleBatch:
    """One ``SampleBatch`` message as numpy arrays: ``stamps`` (int64 ns), ``time``
    (simulation time [s]) and a :class:`Series` per group (:data:`GROUPS`), one row per
    sample."""

    stamps: np.ndarray
    time: np.ndarray
    positions: Series
    velocities: Series
    energy: Series
    invariants: Series
    observables: Series

    def __len__(self) -> int:
        return int(self.stamps.shape[0])


class _Reader:
    """A cursor over one message's CDR bytes (alignment counted from the header's end)."""

    _U32 = struct.Struct("<I")

    def __init__(self, data: bytes) -> None:
        self.data = data
        self.at = 4

    def align(self, size: int) -> None:
        self.at += (-(self.at - 4)) % size

    def need(self, size: int) -> None:
        if self.at + size > len(self.data):
            raise ValueError(f"the message ends at byte {len(self.data)}, a field needs "
                             f"{size} bytes from byte {self.at}")

    def u32(self) -> int:
        self.align(4)
        self.need(4)
        (n,) = self._U32.unpack_from(self.data, self.at)
        self.at += 4
        return int(n)

    def string(self) -> str:
        n = self.u32()
        self.need(n)
        if n == 0 or self.data[self.at + n - 1] != 0:
            raise ValueError(f"a string at byte {self.at} does not end in NUL")
        text = self.data[self.at:self.at + n - 1].decode("utf-8", errors="replace")
        self.at += n
        return text

    def array(self, dtype: np.dtype[Any], align: int) -> np.ndarray:
        n = self.u32()
        if n:
            self.align(align)
        self.need(n * dtype.itemsize)
        out = np.frombuffer(self.data, dtype, n, self.at)
        self.at += n * dtype.itemsize
        return out

    def series(self, samples: int) -> Series:
        count = self.u32()
        self.need(count * 12)  # each column: two strings and a count at least
        names, units, columns = [], [], []
        for _ in range(count):
            names.append(self.string())
            units.append(self.string())
            values = self.array(np.dtype("<f8"), 8)
            if values.shape[0] != samples:
                raise ValueError(f"column {names[-1]!r} has {values.shape[0]} values for "
                                 f"{samples} samples")
            columns.append(values)
        values = np.column_stack(columns) if columns else np.empty((samples, 0))
        return Series(tuple(names), tuple(units), values)


def decode(data: bytes | bytearray | memoryview) -> SampleBatch:
    """The ``SampleBatch`` message whose CDR bytes are ``data`` (as published, recorded, or
    received with ``raw=True``); MechsimError in one line if they are not one."""
    data = bytes(data)
    if data[:2] != b"\x00\x01":
        raise MechsimError("sample batch: not little-endian CDR (encapsulation "
                           f"{data[:2].hex() or 'missing'})")
    r = _Reader(data)
    try:
        r.need(8)
        r.at += 8  # header.stamp: the first sample's
        r.string()  # header.frame_id
        times = r.array(TIME_RECORD, 4)
        stamps = times["sec"].astype(np.int64) * 1_000_000_000 + times["nanosec"]
        t = r.array(np.dtype("<f8"), 8)
        if t.shape[0] != stamps.shape[0]:
            raise ValueError(f"{t.shape[0]} times for {stamps.shape[0]} stamps")
        groups = [r.series(stamps.shape[0]) for _ in GROUPS]
    except (ValueError, struct.error) as e:
        raise MechsimError(f"sample batch: {e}") from None
    return SampleBatch(stamps, t, *groups)


def _joined_series(parts: list[Series]) -> Series:
    first = parts[0]
    for p in parts[1:]:
        if p.names != first.names:
            raise MechsimError(f"sample batches: columns {list(p.names)} after "
                               f"{list(first.names)} (a model change): join them apart")
    return Series(first.names, first.units, np.concatenate([p.values for p in parts]))


def joined(batches: Iterable[SampleBatch]) -> SampleBatch:
    """Consecutive batches of one system as one (their columns must be the same)."""
    parts = list(batches)
    if not parts:
        raise MechsimError("sample batches: none to join")
    return SampleBatch(np.concatenate([b.stamps for b in parts]),
                       np.concatenate([b.time for b in parts]),
                       *(_joined_series([getattr(b, g) for b in parts]) for g in GROUPS))


def read_batches(bag: str | Path, topics: list[str] | None = None
                 ) -> Iterator[tuple[str, SampleBatch]]:
    """(topic, batch) for every ``SampleBatch`` message of the bag (``topics``: only these),
    in log-time order within each file (the order of ``mechsim.outputs.bag.read_messages``).
    A bag recorded without them (``bag_topics: samples``) yields nothing."""
    from mechsim.outputs.bag import read_messages

    for m in read_messages(bag, topics):
        if m.type_name == TYPE:
            yield m.topic, decode(m.data)
