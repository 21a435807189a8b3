"""The in-process diagnostics feed: a sink that hands each chunk's law values straight to the
diagnostics node of the same process (lossless, whatever the executor's pace), reported at
the stamps of the runner's diagnostics period."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from typing import Any

import numpy as np

from mechsim.outputs.sink import Capabilities, Takes


def _same(a: list[Any], b: list[Any]) -> bool:
    """The same objects, in the same order."""
    return len(a) == len(b) and all(x is y for x, y in zip(a, b, strict=True))


def _laws_carried(topic: str) -> bool:
    """The topics the feed wants: what the diagnostics node follows."""
    return topic.rpartition("/")[2] in ("system_info", "energy", "invariants")


#: A stamp past every sample (``DiagnosticsFeed.deliver``).
_EVERY_NS = int(np.iinfo(np.int64).max)


class DiagnosticsFeed:
    """In-process sink that hands system_info messages and the energy/invariant values of
    each chunk straight to the diagnostics node: lossless, whatever the executor's pace.
    Each chunk's law values are taken when it arrives (``DiagnosticsNode.law_rows``: a
    system_info delivers what is held first, so they are the laws that apply) and held
    until :meth:`deliver` (the runner reports in between, at the stamps of its diagnostics
    period, however long the chunks)."""

    capabilities = Capabilities(Takes.COLUMNS, wants=_laws_carried)

    def __init__(self, diag: Any) -> None:
        self.diag = diag
        #: (namespace, stream, stamps, laws, laws × samples values), in arrival order.
        self.pending: list[tuple[str, str, Any, list[Any], Any]] = []

    def write(self, topic: str, type_name: str, msg: Any, qos: Any, ns: int) -> None:
        self.deliver()  # a system_info applies to the samples after it
        base, _, leaf = topic.rpartition("/")
        self.diag.feed(base, leaf, msg)

    def write_columns(self, topic: str, ns: Any, values: Any) -> None:
        """A chunk's evaluated energy or invariants (no message objects: see the Outlet)."""
        base, _, leaf = topic.rpartition("/")
        rows = self.diag.law_rows(base, leaf, values, len(ns))
        if rows is not None:
            self.pending.append((base, leaf, ns, *rows))

    def _runs(self) -> list[tuple[str, str, Any, list[Any], Any]]:
        """The held samples as runs (namespace, stream, stamps, laws, values): pieces of a
        stream whose stamps go on increasing joined (a paced run hands them over a sample or
        two at a time); a new epoch (a stamp not later) starts a new run."""
        runs: list[tuple[str, str, list[Any], list[Any], list[Any]]] = []
        last: dict[tuple[str, str], tuple[str, str, list[Any], list[Any], list[Any]]] = {}
        for base, leaf, ns, laws, matrix in self.pending:
            run = last.get((base, leaf))
            if run is None or ns[0] <= run[2][-1][-1] or not _same(laws, run[3]):
                run = last[base, leaf] = (base, leaf, [], laws, [])
                runs.append(run)
            run[2].append(ns)
            run[4].append(matrix)
        return [(base, leaf, np.concatenate(pieces) if len(pieces) > 1 else pieces[0], laws,
                 np.concatenate(parts, axis=1) if len(parts) > 1 else parts[0])
                for base, leaf, pieces, laws, parts in runs]

    def deliver(self) -> None:
        """Feed every held sample."""
        for _ in self.reports([_EVERY_NS]):
            pass

    def reports(self, stamps: list[int]) -> Iterator[None]:
        """Feed the held samples stamped up to each of ``stamps`` (increasing) in turn, one
        step per report (the rest stays held): the laws are tracked once for all of them
        where they can be (``DiagnosticsNode.feed_prefixes``), piece by piece where not."""
        runs = self._runs()
        # A stream held in several runs (a new epoch among them) is fed piece by piece: the
        # runs take turns at each report.
        turns = Counter((base, leaf) for base, leaf, *_ in runs)
        steps: list[Iterator[None]] = []
        keep = []
        for base, leaf, ns, laws, matrix in runs:
            ends = ns.searchsorted(np.asarray(stamps, dtype=np.int64), "right").tolist()
            step = self.diag.feed_prefixes(base, leaf, ns, laws, matrix, ends) \
                if ends[-1] and turns[base, leaf] == 1 else None
            steps.append(step if step is not None else
                         self._pieces(base, leaf, ns, laws, matrix, ends))
            if ends[-1] < len(ns):
                keep.append((base, leaf, ns[ends[-1]:], laws, matrix[:, ends[-1]:]))
        self.pending = keep
        for _ in stamps:
            for step in steps:
                next(step)
            yield

    def _pieces(self, base: str, leaf: str, ns: Any, laws: list[Any], matrix: Any,
                ends: list[int]) -> Iterator[None]:
        done = 0
        for end in ends:
            if end > done:
                self.diag.feed_rows(base, leaf, ns[done:end], laws, matrix[:, done:end])
                done = end
            yield
