"""mechsim: simulated classical mechanics streamed as ROS 2 topics.

Pure-Python API (no ROS needed)::

    import mechsim
    model = mechsim.load_system("pendulum", **{"initial.angle": 1.0})
    run = mechsim.simulate(model, t_end=10.0, output_dt=0.01)
    run.total, run.invariants, run.observables["tension"]

Every sample of a running system, many at a time, as numpy arrays (ROS needed)::

    with mechsim.subscribe_batches(["pendulum"]) as sub:
        for topic, batch in sub.batches(idle=5.0):
            batch.time, batch.positions["angle"], batch.energy["total"]

and the same from a bag: ``mechsim.read_batches(path)``.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mechsim.errors import IntegrationError, MechsimError, ParameterError, UnknownSystemError
from mechsim.simulate import SimulationResult, load_system, simulate
from mechsim.systems import system_ids

if TYPE_CHECKING:
    from mechsim.outputs.batch import SampleBatch
    from mechsim.ros.batches import BatchSubscriber

__version__ = "0.1.0"
__all__ = ["IntegrationError", "MechsimError", "ParameterError", "SimulationResult",
           "UnknownSystemError", "load_system", "read_batches", "simulate",
           "subscribe_batches", "system_ids", "__version__"]


def subscribe_batches(topics: str | list[str], *, context: Any = None) -> BatchSubscriber:
    """A subscriber (a hidden node of its own, in a ROS context of its own unless one is
    given) to the ``<ns>/sample_batch`` topics of ``topics``: batch topics or instance names
    (``"pendulum"`` is ``/pendulum/sample_batch``). ``sub.batches(idle=...)`` yields (topic,
    :class:`~mechsim.outputs.batch.SampleBatch`) as they arrive, ``sub.take(timeout)``
    returns them; every message is kept until taken. Use it as a context manager, or call
    ``close()``. Needs rclpy (imported with the project's DDS profile)."""
    from mechsim.ros.batches import BatchSubscriber

    return BatchSubscriber([topics] if isinstance(topics, str) else list(topics),
                           context=context)


def read_batches(bag: str | Path, topics: list[str] | None = None
                 ) -> Iterator[tuple[str, SampleBatch]]:
    """(topic, batch) for every ``<ns>/sample_batch`` message of a recording (``topics``:
    only these), as numpy arrays; no ROS needed."""
    from mechsim.outputs.batch import read_batches as read

    return read(bag, topics)
