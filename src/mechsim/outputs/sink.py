"""The sink contract: what receives the messages a node sends (the bag writer, the Rerun
logger, the in-process diagnostics feed), and the one place they are handed over
(:class:`Sinks`).

A sink declares once, in its ``capabilities`` (:class:`Capabilities`), what it takes and which
topics it wants; :class:`Sinks` checks the declaration when the sink is attached and then
dispatches every message by it, on every path (one message, a chunk of samples, a message a
node applied but did not publish, a message a recorder received), with one rule: **a sink never
gets a topic it does not want**, and outputs no sink wants need not be computed.

What a sink takes (:class:`Takes`), and the methods it must have for it:

- ``MESSAGES``: ``write(topic, type_name, msg, qos, ns)``, rclpy messages (a chunk's made only
  for the topics it wants, sample by sample in time order).
- ``COLUMNS``: a chunk's evaluated values, ``write_columns(topic, ns, values)``
  (``mechsim.outputs.messages.Columns``), for the topics that have them (state positions,
  energy, invariants, observables, /tf); ``write`` for every other message.
- ``BYTES``: CDR bytes as DDS carries them (``mechsim.outputs.wire``, padding zero):
  ``write_rows(ns, [(topic, type_name, qos, rows)])`` a chunk of N samples stamped ``ns``
  (rows: an (N, size) uint8 array per topic), ``write_bytes(topic, type_name, qos, ns, data)``
  one message. A chunk nobody takes as bytes is not encoded.

A paced run hands a sink each node's samples a block at a time (those computed ahead), in the
order they were published; a sink declared ``immediate`` (a live view) gets every sample as it
is published.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple, Protocol, runtime_checkable

import numpy as np


class Takes(enum.Enum):
    """The form in which a sink takes messages (see the module docstring)."""

    MESSAGES = "messages"
    COLUMNS = "columns"
    BYTES = "bytes"


@dataclass(frozen=True)
class Capabilities:
    """What a sink takes, whether it must see each sample as it is published, and which topics
    it wants (``wants(topic)``: a function of the topic's name alone, asked once per topic;
    None: every topic)."""

    takes: Takes = Takes.MESSAGES
    immediate: bool = False
    wants: Callable[[str], bool] | None = None


#: The methods a sink needs for each form.
METHODS = {Takes.MESSAGES: ("write",), Takes.COLUMNS: ("write", "write_columns"),
           Takes.BYTES: ("write_bytes", "write_rows")}


@runtime_checkable
class Sink(Protocol):
    """Anything with ``capabilities`` and the methods they name (:data:`METHODS`)."""

    capabilities: Capabilities


class MessageSink(Sink, Protocol):
    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None: ...


class ColumnSink(MessageSink, Protocol):
    def write_columns(self, topic: str, ns: np.ndarray, values: Any) -> None: ...


class ByteSink(Sink, Protocol):
    def write_bytes(self, topic: str, type_name: str, qos: Any, ns: int, data: bytes
                    ) -> None: ...

    def write_rows(self, ns: np.ndarray, topics: list[tuple[str, str, Any, np.ndarray]]
                   ) -> None: ...


def capabilities(sink: Any) -> Capabilities:
    """``sink``'s declared capabilities, checked: TypeError naming what is missing."""
    caps = getattr(sink, "capabilities", None)
    if not isinstance(caps, Capabilities):
        raise TypeError(f"{type(sink).__name__} is not a sink: it declares no capabilities "
                        "(mechsim.outputs.sink.Capabilities)")
    missing = [m for m in METHODS[caps.takes] if not callable(getattr(sink, m, None))]
    if missing:
        raise TypeError(f"{type(sink).__name__} takes {caps.takes.value} but has no "
                        f"{', '.join(missing)}")
    return caps


class ChunkTopic(NamedTuple):
    """One topic of a chunk of samples, as :meth:`Sinks.chunk` takes it: rows i holds the CDR
    bytes of sample i (None if nothing needed them when the chunk was encoded), and
    ``message(i)`` makes sample i's message."""

    topic: str
    type_name: str
    qos: Any
    rows: np.ndarray | None
    message: Callable[[int], Any]


class _Route(NamedTuple):
    """The sinks wanting one topic, in the order they were given, each with its form."""

    sinks: tuple[tuple[Any, Takes], ...]
    wanted: tuple[bool, ...]  # per sink, in the order given: does it want the topic?
    rows: bool  # a sink takes the topic as bytes
    columns: bool  # a sink takes the topic's values as columns


class Sinks:
    """Sinks with their capabilities, checked once (TypeError for a sink that declares none
    or lacks a method its form needs), and the one dispatch of everything handed to them."""

    def __init__(self, sinks: Sequence[Any]) -> None:
        self.sinks = list(sinks)
        self._caps = [capabilities(s) for s in self.sinks]
        #: Does a sink take every sample as it is published?
        self.immediate = any(c.immediate for c in self._caps)
        self._routes: dict[str, _Route] = {}

    def __bool__(self) -> bool:
        return bool(self.sinks)

    def route(self, topic: str) -> _Route:
        """The sinks that want ``topic`` (asked of each sink once per topic)."""
        route = self._routes.get(topic)
        if route is None:
            wanted = tuple(c.wants is None or bool(c.wants(topic)) for c in self._caps)
            chosen = tuple((s, c.takes) for s, c, w
                           in zip(self.sinks, self._caps, wanted, strict=True) if w)
            route = self._routes[topic] = _Route(
                chosen, wanted, any(t is Takes.BYTES for _, t in chosen),
                any(t is Takes.COLUMNS for _, t in chosen))
        return route

    def wants(self, topic: str) -> bool:
        return bool(self.route(topic).sinks)

    def needs_rows(self, topic: str) -> bool:
        """Does a sink that wants ``topic`` take it as CDR bytes?"""
        return self.route(topic).rows

    def needs_columns(self, topic: str) -> bool:
        """Does a sink that wants ``topic`` take its values as columns?"""
        return self.route(topic).columns

    def message(self, topic: str, type_name: str, qos: Any, ns: int, *, msg: Any = None,
                data: bytes | None = None, make: Callable[[], Any] | None = None) -> None:
        """One message stamped ``ns``, given as ``msg``, or as its CDR bytes ``data`` (with
        ``make`` to build the message for sinks that take messages): each sink that wants
        the topic gets it in its form, the bytes encoded or the message made at most once."""
        for sink, takes in self.route(topic).sinks:
            if takes is Takes.BYTES:
                if data is None:
                    from mechsim.outputs.wire import encode

                    msg = make() if msg is None and make is not None else msg
                    data = encode(type_name, msg)
                sink.write_bytes(topic, type_name, qos, ns, data)
            else:
                if msg is None:
                    if make is None:
                        raise ValueError(f"{topic}: a sink takes messages, none was given")
                    msg = make()
                sink.write(topic, type_name, msg, qos, ns)

    def chunk(self, ns: np.ndarray, topics: list[ChunkTopic],
              columns: Mapping[str, Any] | None, part: slice | None) -> None:
        """Samples ``part`` (None: all) of a chunk stamped ``ns``: each sink gets, in one call
        (per topic for columns), the topics it wants in its form. ``columns``: the evaluated
        values of the topics that have them."""
        from mechsim.outputs.messages import column_rows

        a = 0 if part is None else part.start
        if part is not None:
            ns = ns[part]
        columns = columns or {}
        routes = [self.route(t.topic).wanted for t in topics]
        for k, (sink, caps) in enumerate(zip(self.sinks, self._caps, strict=True)):
            wanted = [t for t, by_sink in zip(topics, routes, strict=True) if by_sink[k]]
            if not wanted:
                continue
            if caps.takes is Takes.BYTES:
                self._rows(sink, ns, wanted, part)
                continue
            if caps.takes is Takes.COLUMNS:
                for t in wanted:
                    if t.topic in columns:
                        values = columns[t.topic]
                        sink.write_columns(t.topic, ns, values if part is None
                                           else column_rows(values, part))
                wanted = [t for t in wanted if t.topic not in columns]
            for i in range(len(ns)):
                for t in wanted:
                    sink.write(t.topic, t.type_name, t.message(a + i), t.qos, int(ns[i]))

    @staticmethod
    def _rows(sink: Any, ns: np.ndarray, topics: list[ChunkTopic], part: slice | None) -> None:
        """A chunk's rows to a sink that takes bytes; a topic encoded without rows (no such
        sink was attached then) is encoded here, message by message."""
        rows = [(t.topic, t.type_name, t.qos, t.rows if part is None else t.rows[part])
                for t in topics if t.rows is not None]
        if rows:
            sink.write_rows(ns, rows)
        late = [t for t in topics if t.rows is None]
        if late:
            from mechsim.outputs.wire import encode

            a = 0 if part is None else part.start
            for i in range(len(ns)):
                for t in late:
                    sink.write_bytes(t.topic, t.type_name, t.qos, int(ns[i]),
                                     encode(t.type_name, t.message(a + i)))
