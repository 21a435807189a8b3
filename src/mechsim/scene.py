"""Scenes: a YAML file listing system instances, their parameters, rates, pacing and outputs.

Format (every field validated; unknown keys are errors)::

    name: pendulum              # scene name (default: file stem)
    pacing: realtime            # realtime | fast
    real_time_factor: 1.0       # simulated seconds per wall second, with pacing realtime
    duration: 20.0              # simulated seconds (omit: run until stopped)
    publish_rate: 100.0         # Hz of simulation time, per system
    diagnostics: {warn_drift: 1.0e-6, error_drift: 1.0e-3}
    outputs: {bag: runs/pendulum_bag, rrd: runs/pendulum.rrd}
    systems:
      - system: pendulum        # system id (`mechsim systems`)
        name: pendulum          # namespace, default the system id; unique in the scene
        parameters: {initial.angle: 2.0}
        method: auto            # auto | dop853 | yoshida8 | yoshida6 | verlet
        tolerance: 1.0e-10
        origin: [0.0, 0.0, 0.0] # where the system's world-rooted frames sit in the world
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from mechsim.errors import MechsimError, ParameterError, UnknownSystemError
from mechsim.integrators import METHODS
from mechsim.params import flatten
from mechsim.systems import system_class
from mechsim.systems.base import Law

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


@dataclass
class Instance:
    system: str
    name: str
    parameters: dict[str, Any] = field(default_factory=dict)
    method: str = "auto"
    tolerance: float = 1e-10
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass
class Scene:
    name: str
    systems: list[Instance]
    pacing: str = "realtime"
    real_time_factor: float = 1.0
    duration: float | None = None
    publish_rate: float = 100.0
    warn_drift: float = Law.WARN_DRIFT
    error_drift: float = Law.ERROR_DRIFT
    bag: str | None = None
    rrd: str | None = None
    source: Path | None = None


def positive_number(field_name: str, value: Any, positive: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ParameterError(field_name, f"must be a number (got {value!r})")
    x = float(value)
    if not math.isfinite(x) or (positive and x <= 0):
        raise ParameterError(field_name, f"must be a finite positive number (got {value!r})")
    return x


def _keys(where: str, data: dict[str, Any], allowed: set[str]) -> None:
    for key in data:
        if key not in allowed:
            raise ParameterError(f"{where}.{key}" if where else str(key),
                                 f"unknown key (allowed: {', '.join(sorted(allowed))})")


def parse_instance(data: Any, index: int) -> Instance:
    where = f"systems[{index}]"
    if not isinstance(data, dict):
        raise ParameterError(where, "must be a mapping with at least `system`")
    _keys(where, data, {"system", "name", "parameters", "method", "tolerance", "origin"})
    if "system" not in data:
        raise ParameterError(f"{where}.system", "missing")
    system = data["system"]
    cls = system_class(system)  # UnknownSystemError names the id
    name = data.get("name", system)
    if not isinstance(name, str) or not _NAME.match(name):
        raise ParameterError(f"{where}.name", f"must be a ROS name [A-Za-z][A-Za-z0-9_]* "
                             f"(got {name!r})")
    params = data.get("parameters", {}) or {}
    if not isinstance(params, dict):
        raise ParameterError(f"{where}.parameters", "must be a mapping name: value")
    try:
        cls(**flatten(params))  # validates every parameter now, with the field named
    except ParameterError as e:
        raise ParameterError(f"{where}.parameters.{e.field}", e.reason) from None
    method = data.get("method", "auto")
    if method not in METHODS:
        raise ParameterError(f"{where}.method", f"must be one of {', '.join(METHODS)}")
    tol = positive_number(f"{where}.tolerance", data.get("tolerance", 1e-10))
    if tol >= 1:
        raise ParameterError(f"{where}.tolerance", f"must be < 1 (got {tol!r})")
    origin = data.get("origin", [0.0, 0.0, 0.0])
    if not (isinstance(origin, list | tuple) and len(origin) == 3):
        raise ParameterError(f"{where}.origin", "must be a list of three numbers [x, y, z]")
    org = tuple(positive_number(f"{where}.origin", v, positive=False) for v in origin)
    return Instance(system, name, flatten(params), method, tol, org)  # type: ignore[arg-type]


def parse_scene(data: Any, default_name: str = "scene") -> Scene:
    if not isinstance(data, dict):
        raise ParameterError("scene", "must be a YAML mapping with a `systems` list")
    _keys("", data, {"name", "pacing", "real_time_factor", "duration", "publish_rate",
                     "diagnostics", "outputs", "systems"})
    systems = data.get("systems")
    if not isinstance(systems, list) or not systems:
        raise ParameterError("systems", "must be a non-empty list of system instances")
    instances = [parse_instance(s, i) for i, s in enumerate(systems)]
    names = [i.name for i in instances]
    for n in names:
        if names.count(n) > 1:
            raise ParameterError("systems", f"instance name {n!r} used twice: set `name`")
    pacing = data.get("pacing", "realtime")
    if pacing not in ("realtime", "fast"):
        raise ParameterError("pacing", f"must be realtime or fast (got {pacing!r})")
    scene = Scene(name=str(data.get("name", default_name)), systems=instances, pacing=pacing)
    if "real_time_factor" in data:
        scene.real_time_factor = positive_number("real_time_factor", data["real_time_factor"])
    if data.get("duration") is not None:
        scene.duration = positive_number("duration", data["duration"])
    if "publish_rate" in data:
        scene.publish_rate = positive_number("publish_rate", data["publish_rate"])
    diag = data.get("diagnostics") or {}
    if not isinstance(diag, dict):
        raise ParameterError("diagnostics", "must be a mapping")
    _keys("diagnostics", diag, {"warn_drift", "error_drift"})
    scene.warn_drift = positive_number("diagnostics.warn_drift",
                                       diag.get("warn_drift", Law.WARN_DRIFT))
    scene.error_drift = positive_number("diagnostics.error_drift",
                                        diag.get("error_drift", Law.ERROR_DRIFT))
    if scene.warn_drift >= scene.error_drift:
        raise ParameterError("diagnostics.warn_drift", "must be smaller than error_drift")
    outputs = data.get("outputs") or {}
    if not isinstance(outputs, dict):
        raise ParameterError("outputs", "must be a mapping")
    _keys("outputs", outputs, {"bag", "rrd"})
    for key in ("bag", "rrd"):
        if outputs.get(key) is not None and not isinstance(outputs[key], str):
            raise ParameterError(f"outputs.{key}", "must be a path string")
    scene.bag, scene.rrd = outputs.get("bag"), outputs.get("rrd")
    return scene


def load_scene(path: str | Path) -> Scene:
    """Read and validate a scene file (MechsimError with a one-line reason on any problem)."""
    p = Path(path)
    try:
        text = p.read_text()
    except OSError as e:
        raise MechsimError(f"scene {p}: cannot read ({e.strerror or e})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        where = f" line {mark.line + 1}" if mark is not None else ""
        raise MechsimError(f"scene {p}:{where} is not valid YAML") from None
    try:
        scene = parse_scene(data, default_name=p.stem)
    except ParameterError as e:
        raise ParameterError(f"scene {p}: {e.field}", e.reason) from None
    scene.source = p
    return scene


def single_system_scene(system: str, parameters: dict[str, Any] | None = None) -> Scene:
    """The scene `mechsim run SYSTEM` uses: one instance with default settings."""
    return parse_scene({"name": system, "systems": [{"system": system,
                                                      "parameters": parameters or {}}]})


def apply_overrides(scene: Scene, sets: list[str]) -> None:
    """``name=value`` for every instance that has the parameter, ``inst:name=value`` for one."""
    for item in sets:
        if "=" not in item:
            raise ParameterError("--set", f"expected name=value (got {item!r})")
        key, raw = item.split("=", 1)
        target, _, name = key.rpartition(":")
        try:
            value = yaml.safe_load(raw)
        except yaml.YAMLError:
            value = raw
        hit = False
        for idx, inst in enumerate(scene.systems):
            if target and inst.name != target:
                continue
            names = {p.name for p in system_class(inst.system).parameter_spec()}
            if name in names:
                params = dict(inst.parameters)
                params[name] = value
                scene.systems[idx] = parse_instance(
                    {"system": inst.system, "name": inst.name, "parameters": params,
                     "method": inst.method, "tolerance": inst.tolerance,
                     "origin": list(inst.origin)}, idx)
                hit = True
        if not hit:
            where = f"instance {target!r}" if target else "any system of the scene"
            raise ParameterError(f"--set {name}", f"not a parameter of {where}")


def scene_from_target(target: str, sets: list[str]) -> Scene:
    """The scene a command names: a scene file, or a system id run with its default scene;
    then the ``--set`` overrides."""
    from mechsim.systems import system_ids

    if target.endswith((".yaml", ".yml")) or Path(target).is_file():
        scene = load_scene(target)
    elif target in system_ids():
        scene = single_system_scene(target)
    else:
        raise UnknownSystemError(target, system_ids())
    apply_overrides(scene, sets)
    return scene
