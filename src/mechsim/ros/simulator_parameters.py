"""The ROS parameters of a simulator node, and what it starts with.

A simulator node is configured entirely by its parameters, as turtlesim is: ``system``, every
model parameter of that system (``formulation`` among them), ``method``, the run settings
(``runcore.change.SETTINGS``), and the start-only ones of :data:`START_ONLY`. Whoever makes the
node (a scene runner, a test, the node executable started alone) gives an instance and settings;
the values given from outside (``--ros-args -p``, ``--params-file``, a launch file's
parameters: ``parameters.overrides``) take precedence, each checked against its one range
(``mechsim.params``) before anything is built, so what a node declares is what it runs.
A value that does not pass is a ParameterError naming the parameter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

from mechsim.errors import ParameterError
from mechsim.integrators import METHODS
from mechsim.params import DURATION, shown
from mechsim.ros.parameters import descriptor, foreign, overrides
from mechsim.runcore.change import SETTINGS, Settings
from mechsim.scene import Instance
from mechsim.systems import system_class, system_ids

#: Parameters read once, when the node starts (read-only afterwards).
START_ONLY = ("system", "origin", "time_offset", "duration", "publish_clock",
              "wait_for_recorder")


@dataclass(frozen=True)
class Start:
    """What a simulator node runs: its instance (system, name, parameters, method, origin),
    settings, stamp offset, end (simulated seconds, None: until stopped), whether it
    publishes /clock, and the given values it has no parameter for."""

    instance: Instance
    settings: Settings
    stepped: bool
    time_offset: float
    end_time: float | None
    publish_clock: bool
    unused: frozenset[str]
    wait_for_recorder: bool = False


def _number(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) \
            or not math.isfinite(float(value)):
        raise ParameterError(name, f"must be a finite number (got {shown(value)})")
    return float(value)


def _origin(value: Any) -> tuple[float, float, float]:
    if not isinstance(value, list | tuple) or len(value) != 3:
        raise ParameterError("origin", f"must be three numbers [x, y, z] (got {shown(value)})")
    x, y, z = (_number("origin", v) for v in value)
    return (x, y, z)


def _end_time(value: Any) -> float | None:
    x = _number("duration", value)
    return None if x == 0 else float(DURATION.check(x, "duration"))


def _settings(given: dict[str, Any], settings: Settings, stepped: bool) -> Settings:
    changed = {name: float(p.check(given[name], name)) for name, p in SETTINGS.items()
               if name in given}
    rtf = changed.get("real_time_factor")
    if rtf is not None and stepped and rtf != settings.real_time_factor:
        raise ParameterError("real_time_factor", "read-only: this system is paced by its "
                             f"scene runner ({settings.real_time_factor:g})")
    if rtf == 0 and not stepped:
        raise ParameterError("real_time_factor", "must be > 0 for a node that paces itself "
                             "(0 means stepped by a runner; ~/pause stops it)")
    return replace(settings, **changed)


def _instance(instance: Instance, given: dict[str, Any]) -> Instance:
    """``instance`` with the given system check, model parameters and method applied (its
    model built: every check of the model)."""
    system = given.get("system", instance.system)
    if system != instance.system:
        raise ParameterError("system", f"is {instance.system!r} for this node, not "
                             f"{shown(system)} (a scene or the node's start sets it)")
    spec = {p.name for p in system_class(instance.system).parameter_spec()}
    params = {k: v for k, v in given.items() if k in spec}
    method = given.get("method", instance.method)
    if not isinstance(method, str) or method not in METHODS:
        raise ParameterError("method", f"must be one of {', '.join(METHODS)} (got "
                             f"{shown(method)})")
    origin = _origin(given["origin"]) if "origin" in given else instance.origin
    if params:  # a new model, built now: every check of the model
        instance = replace(instance, parameters={**instance.parameters, **params})
        instance.build()
    return with_changes(instance, method=method, origin=origin)


def with_changes(instance: Instance, **changes: Any) -> Instance:
    """``instance`` with ``changes`` to fields its model does not depend on (the model it
    built is kept: one model per instance per start)."""
    if all(getattr(instance, k) == v for k, v in changes.items()):
        return instance
    out = replace(instance, **changes)
    out._built = instance._built
    return out


def start_values(node: Node, instance: Instance, settings: Settings, *, stepped: bool,
                 time_offset: float, end_time: float | None, publish_clock: bool) -> Start:
    """What ``node`` (made, not yet declaring anything) starts with: the arguments of its
    maker with the node's given values applied."""
    given = overrides(node)
    instance = _instance(instance, given)
    settings = _settings(given, replace(settings, tolerance=instance.tolerance), stepped)
    if "tolerance" in given:
        instance = replace(instance, tolerance=settings.tolerance)
    if "time_offset" in given:
        time_offset = _number("time_offset", given["time_offset"])
        if time_offset < 0:
            raise ParameterError("time_offset", f"must be >= 0 (got {time_offset:g})")
    if "duration" in given:
        end_time = _end_time(given["duration"])
    publish_clock = _flag(given, "publish_clock", publish_clock)
    wait = _flag(given, "wait_for_recorder", False)
    known = {p.name for p in system_class(instance.system).parameter_spec()}
    known |= {"method", *SETTINGS, *START_ONLY}
    return Start(instance, settings, stepped, time_offset, end_time, publish_clock,
                 frozenset(foreign(set(given) - known)), wait)


def _flag(given: dict[str, Any], name: str, default: bool) -> bool:
    value = given.get(name, default)
    if not isinstance(value, bool):
        raise ParameterError(name, f"must be true or false (got {shown(value)})")
    return value


def declare(node: Node, start: Start, values: dict[str, Any], method: str) -> None:
    """Declare every parameter of the node with the values it runs (``values``: the model's,
    ``method``: the integrator's), given values taken into account already. One
    declaration of them all (one parameter event)."""
    declared: list[tuple[str, Any, ParameterDescriptor]] = []
    spec = system_class(start.instance.system).parameter_spec()
    ro = ParameterDescriptor
    declared.append(("system", start.instance.system, ro(
        description="system id (see `mechsim systems`)", read_only=True,
        additional_constraints=f"one of: {', '.join(system_ids())}")))
    for p in spec:
        later = " (takes effect at the next reset)" if p.name.startswith("initial") else ""
        declared.append((p.name, values[p.name],
                         descriptor(p, description=p.description + later)))
    declared.append(("method", method, ro(
        description="integrator", additional_constraints=f"one of: {', '.join(METHODS)}")))
    for name, p in SETTINGS.items():
        paced_by_runner = name == "real_time_factor" and start.stepped
        text = ("simulated seconds per wall second of the scene runner that steps this "
                "node (0: as fast as possible)") if paced_by_runner else None
        declared.append((name, float(getattr(start.settings, name)),
                         descriptor(p, read_only=paced_by_runner, description=text)))
    declared.append(("time_offset", float(start.time_offset), ro(
        description="stamp of simulation time 0 [s] (ROS time 0 means uninitialised)",
        read_only=True, additional_constraints=">= 0")))
    declared.append(("origin", [float(c) for c in start.instance.origin], ro(
        description="where the system's world-rooted frames sit in the world [m]",
        read_only=True, additional_constraints="three numbers [x, y, z]")))
    declared.append(("duration", float(start.end_time or 0.0), ro(
        description="simulated seconds after which the node stops stepping [s] (0: until "
        "stopped)", read_only=True, additional_constraints=">= 0")))
    declared.append(("publish_clock", bool(start.publish_clock), ro(
        description="this node publishes /clock (one clock per graph)", read_only=True)))
    declared.append(("wait_for_recorder", bool(start.wait_for_recorder), ro(
        description="started alone: the first sample waits (at most 60 s) until a recorder "
        "subscribes to every topic of the node", read_only=True)))
    node.declare_parameters("", declared, ignore_override=True)
