"""``simulate_many``: an ensemble of runs of one system (a sweep over parameter values and/or
initial states) in one compiled call per method, the members spread over the cores
(``mechsim.integrators.ensemble``), or over the workers of a Dask cluster.

Each member is what :func:`mechsim.simulate` gives for it alone, bit for bit: a member given
by parameter values is ``simulate(model.with_values(**values), ...)``; one given by an
initial state runs as ``make_stepper(model, method, tolerance, y0=state)`` would.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from mechsim.errors import ParameterError
from mechsim.integrators import Request, method_class
from mechsim.integrators.ensemble import Members, evaluate_many, integrate_many
from mechsim.integrators.model import SteppableModel
from mechsim.simulate import (
    OUTPUTS,
    Outputs,
    OutputShape,
    OutputViews,
    SimulationResult,
    assemble,
    load_system,
    output_buffers,
    output_times,
    resolve_settings,
)
from mechsim.systems.base import Model


@dataclass
class EnsembleResult(OutputViews):
    """The members' arrays, each with a leading axis of members: ``q``, ``v`` (N, samples,
    coordinates), the work terms (N, samples), ``outputs`` (energy terms and each invariant and
    observable (N, samples), frames (N, samples, frames, 7)); per member the method that ran
    it and its counters; ``member(i)`` is member i's ``SimulationResult``."""

    models: list[Model]
    tolerance: float
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    work_external: np.ndarray
    work_dissipated: np.ndarray
    modes: np.ndarray
    outputs: Outputs
    methods: list[str]
    n_steps: np.ndarray
    n_evaluations: np.ndarray
    n_rejected: np.ndarray
    error_estimate: np.ndarray
    wall_time: float
    events: dict[int, list[tuple[float, str]]] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.methods)

    def member(self, i: int) -> SimulationResult:
        """Member ``i`` as the ``SimulationResult`` of a single run (its wall time: the
        ensemble's share)."""
        o = self.outputs
        out = Outputs(
            kinetic=None if o.kinetic is None else o.kinetic[i],
            potential=None if o.potential is None else o.potential[i],
            energy_function=None if o.energy_function is None else o.energy_function[i],
            invariants={k: v[i] for k, v in o.invariants.items()},
            observables={k: v[i] for k, v in o.observables.items()},
            frames=None if o.frames is None else o.frames[i])
        return SimulationResult(
            model=self.models[i], method=self.methods[i], tolerance=self.tolerance, t=self.t,
            q=self.q[i], v=self.v[i], work_external=self.work_external[i],
            work_dissipated=self.work_dissipated[i], outputs=out,
            wall_time=self.wall_time / len(self), n_steps=int(self.n_steps[i]),
            events=list(self.events.get(i, [])), modes=self.modes[i],
            n_evaluations=int(self.n_evaluations[i]), n_rejected=int(self.n_rejected[i]),
            error_estimate=float(self.error_estimate[i]))


def simulate_many(model: Model, t_end: float, output_dt: float | None = None, *,
                  parameters: Sequence[Mapping[str, Any]] | None = None,
                  states: Any = None, tolerance: float | None = None,
                  method: str | None = None, outputs: tuple[str, ...] = OUTPUTS,
                  work_terms: bool = True, publish_rate: float | None = None,
                  threads: int | None = None, cluster: Any = None,
                  members_per_task: int | None = None) -> EnsembleResult:
    """Integrate an ensemble of ``model``: one member per entry of ``parameters`` (values of
    the model's parameters, by the names ``load_system`` takes: the model with those
    changed) and/or per row of ``states`` (initial states: [q, q̇] or a full state of the
    model's layout), both of one length where both are given. The other arguments are those
    of :func:`mechsim.simulate` (the same settings per member: the tolerance is a contract per
    member). ``threads``: cores to use (all if None). ``cluster``: run on Dask instead:
    ``"local"`` (a local cluster of one worker process per core, made for this call), a
    scheduler's address (``"tcp://host:8786"``) or a ``distributed.Client``; the members are
    sent in tasks of ``members_per_task`` (default: four tasks per worker)."""
    tolerance, method, output_dt = resolve_settings(model, tolerance, method, outputs,
                                                    output_dt, publish_rate)
    members = _members(model, parameters, states)
    t = output_times(t_end, output_dt)
    if cluster is not None:
        return _on_dask(cluster, model, parameters, states, members_per_task,
                        dict(t_end=t_end, output_dt=output_dt, tolerance=tolerance,
                             method=method, outputs=outputs, work_terms=work_terms,
                             threads=threads))
    cls = method_class(method)
    cls.check(model)
    start = time.perf_counter()
    run = integrate_many(cls, members, tolerance, t,
                         Request(horizon=t_end, work_terms=work_terms,
                                 given_state=members.given_state), threads)
    shape = OutputShape.of(model)
    buffers = output_buffers(shape, outputs, t.size, len(members.models))
    evaluate_many(members, t, run.Y, outputs, buffers, threads)
    at = model.layout
    Y = run.Y
    return EnsembleResult(
        models=cast(list[Model], members.models), tolerance=tolerance, t=t, q=Y[..., at.q],
        v=_rates(members, t, Y),
        work_external=Y[..., at.work_external], work_dissipated=Y[..., at.work_dissipated],
        modes=Y[..., at.modes],
        outputs=assemble(shape, outputs, *buffers) if outputs else Outputs(),
        methods=run.methods, n_steps=run.n_steps, n_evaluations=run.n_evaluations,
        n_rejected=run.n_rejected, error_estimate=run.error_estimate,
        wall_time=time.perf_counter() - start, events=run.events)


def _rates(members: Members, t: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """The members' rates q̇ (N, samples, coordinates): the states' ``v`` entries, or, for a
    formulation whose state holds momenta, each member's rates from its own parameters."""
    models = cast(list[Model], members.models)
    if models[0].structure.second_order:
        return Y[..., models[0].layout.v]
    return np.stack([m.rates(t, Y[i], members.P[i]) for i, m in enumerate(models)])


def _members(model: Model, parameters: Sequence[Mapping[str, Any]] | None,
             states: Any) -> Members:
    """The members' models, initial states and parameter vectors (``ParameterError`` naming
    ``parameters`` or ``states`` and what is wrong)."""
    if parameters is None and states is None:
        raise ParameterError("parameters", "give parameter values and/or initial states, "
                             "one per member")
    if parameters is not None:
        if isinstance(parameters, Mapping) or not all(isinstance(v, Mapping)
                                                      for v in parameters):
            raise ParameterError("parameters", "must be a sequence of mappings, one per "
                                 "member (parameter name to value)")
        models = [model.with_values(**dict(values)) for values in parameters]
        if any(m.kernels is not model.kernels for m in models):
            raise ParameterError("parameters", "members must share the model's formulation "
                                 "(one set of equations)")
    y0 = _states(model, states, None if parameters is None else len(parameters))
    if parameters is None:
        assert y0 is not None  # states were given
        models = [model] * y0.shape[0]
    if y0 is None:
        y0 = np.array([m.initial_y() for m in models]).reshape(len(models), -1)
    if not models:
        raise ParameterError("parameters", "an ensemble needs at least one member")
    if parameters is None:  # one model: its parameter vector for every member
        P = np.tile(model.parameter_vector(), (len(models), 1))
    else:
        P = np.array([m.parameter_vector() for m in models]).reshape(len(models), -1)
    return Members(cast(list[SteppableModel], models), np.ascontiguousarray(y0), P,
                   given_state=states is not None)


def _states(model: Model, states: Any, n: int | None) -> np.ndarray | None:
    """The initial states as full states of the model's layout, checked."""
    if states is None:
        return None
    try:
        rows = np.array(states, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError("states", "must be an array of initial states, one row per "
                             "member") from None
    at = model.layout
    n_q = len(model.coordinates)
    if rows.ndim != 2 or rows.shape[1] not in (2 * n_q, at.size):
        raise ParameterError("states", f"must have one row per member of [q, q̇] ({2 * n_q} "
                             f"columns) or of the full state ({at.size}) (got shape "
                             f"{rows.shape})")
    if n is not None and rows.shape[0] != n:
        raise ParameterError("states", f"{rows.shape[0]} rows for {n} parameter sets")
    if not np.isfinite(rows).all():
        raise ParameterError("states", "must be finite")
    if rows.shape[1] == at.size:
        return rows
    full = np.zeros((rows.shape[0], at.size))  # work terms 0, modes those of the model
    full[:, at.q], full[:, at.v] = rows[:, :n_q], rows[:, n_q:]
    full[:, at.modes] = model.initial_y()[at.modes]
    return full


def _on_dask(cluster: Any, model: Model, parameters: Sequence[Mapping[str, Any]] | None,
             states: Any, members_per_task: int | None, settings: dict[str, Any]
             ) -> EnsembleResult:
    """``simulate_many`` with its members in tasks on a Dask cluster (see there)."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:  # pragma: no cover - a dependency of mechsim
        raise ParameterError("cluster", "needs Dask's distributed package") from None
    n = len(parameters) if parameters is not None else len(states)
    own: list[Any] = []
    if isinstance(cluster, Client):
        client = cluster
    elif cluster == "local":
        local = LocalCluster(n_workers=os.cpu_count() or 1, threads_per_worker=1,
                             processes=True, dashboard_address=None)
        own = [local, client := Client(local)]
    elif isinstance(cluster, str):
        client = Client(cluster)
        own = [client]
    else:
        raise ParameterError("cluster", "must be 'local', a scheduler address or a "
                             "distributed.Client")
    try:
        workers = max(1, len(client.scheduler_info().get("workers", {})))
        size = members_per_task or max(1, math.ceil(n / (4 * workers)))
        system = (model.id, dict(model.values))
        futures = [client.submit(_task, system,
                                 None if parameters is None else list(parameters[a:a + size]),
                                 None if states is None else np.asarray(states)[a:a + size],
                                 settings, pure=False)
                   for a in range(0, n, size)]
        parts = client.gather(futures)
    finally:
        for thing in reversed(own):
            thing.close()
    return _joined(parts, model, parameters)


def _task(system: tuple[str, dict[str, Any]],
          parameters: list[Mapping[str, Any]] | None, states: Any,
          settings: dict[str, Any]) -> EnsembleResult:
    """One task of a Dask run: its members on the worker, returned without their models."""
    system_id, values = system
    model = load_system(system_id, **values)
    result = simulate_many(model, parameters=parameters, states=states, **settings)
    result.models = []
    return result


def _joined(parts: list[EnsembleResult], model: Model,
            parameters: Sequence[Mapping[str, Any]] | None) -> EnsembleResult:
    """The tasks' results as one, in the members' order."""
    def cat(get: Any) -> Any:
        return np.concatenate([get(p) for p in parts])

    first = parts[0]
    o = first.outputs
    outputs = Outputs(
        kinetic=None if o.kinetic is None else cat(lambda p: p.outputs.kinetic),
        potential=None if o.potential is None else cat(lambda p: p.outputs.potential),
        energy_function=None if o.energy_function is None
        else cat(lambda p: p.outputs.energy_function),
        invariants={k: cat(lambda p, k=k: p.outputs.invariants[k]) for k in o.invariants},
        observables={k: cat(lambda p, k=k: p.outputs.observables[k]) for k in o.observables},
        frames=None if o.frames is None else cat(lambda p: p.outputs.frames))
    events: dict[int, list[tuple[float, str]]] = {}
    offset = 0
    for p in parts:
        events.update({offset + i: e for i, e in p.events.items()})
        offset += len(p)
    models = ([model.with_values(**dict(v)) for v in parameters] if parameters is not None
              else [model] * offset)
    return EnsembleResult(
        models=models, tolerance=first.tolerance, t=first.t, q=cat(lambda p: p.q),
        v=cat(lambda p: p.v), work_external=cat(lambda p: p.work_external),
        work_dissipated=cat(lambda p: p.work_dissipated), modes=cat(lambda p: p.modes),
        outputs=outputs, methods=[m for p in parts for m in p.methods],
        n_steps=cat(lambda p: p.n_steps), n_evaluations=cat(lambda p: p.n_evaluations),
        n_rejected=cat(lambda p: p.n_rejected), error_estimate=cat(lambda p: p.error_estimate),
        wall_time=max(p.wall_time for p in parts), events=events)
