"""Scenes: a YAML file listing system instances, their parameters, rates, pacing and outputs.

Format (every field validated; unknown keys are errors)::

    name: pendulum              # scene name (default: file stem); letters, digits, _ . -
    pacing: realtime            # realtime | fast
    real_time_factor: 1.0       # simulated seconds per wall second (0: pacing fast)
    duration: 20.0              # simulated seconds (omit: run until stopped)
    publish_rate: 100.0         # Hz of simulation time, per system
    diagnostics: {warn_drift: 1.0e-6, error_drift: 1.0e-3}   # relative drifts in (0, 1]
    outputs: {bag: runs/pendulum_bag, rrd: runs/pendulum.rrd}
    systems:
      - system: pendulum        # system id (`mechsim systems`)
        name: pendulum          # namespace, default the system id; unique in the scene
        parameters: {initial.angle: 2.0}
        method: auto            # auto | dop853 | yoshida8 | yoshida6 | verlet
        tolerance: 1.0e-10
        origin: [0.0, 0.0, 0.0] # where the system's world-rooted frames sit in the world
        effort_limit: 1.0e+6    # largest |effort| accepted per coordinate (also --set)

Ranges of the run settings are defined once in ``mechsim.params`` (shared with the CLI and the
nodes' ROS parameters). Files are untrusted input: at most 1 MiB of UTF-8, YAML aliases are
refused, names are checked before they reach ROS or a path.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mechsim.errors import MechsimError, ParameterError, UnknownSystemError
from mechsim.files import load_yaml, read_bounded
from mechsim.integrators import METHODS
from mechsim.params import (
    DURATION,
    EFFORT_LIMIT,
    ERROR_DRIFT,
    PUBLISH_RATE,
    REAL_TIME_FACTOR,
    TOLERANCE,
    WARN_DRIFT,
    check_text,
    flatten,
    shown,
)
from mechsim.systems import system_class
from mechsim.systems.base import Law, Model

#: Instance names: ROS namespaces, short enough for every topic name built on them.
MAX_NAME = 64
_NAME = re.compile(rf"[A-Za-z][A-Za-z0-9_]{{0,{MAX_NAME - 1}}}")
#: Scene names: part of the default bag path (``runs/<scene>_<time>``), so never a path.
_SCENE_NAME = re.compile(rf"[A-Za-z0-9_][A-Za-z0-9_.-]{{0,{MAX_NAME - 1}}}")
#: Largest scene file (bytes) and ``--set`` value (characters) read.
MAX_SCENE_BYTES = 1 << 20
MAX_SET_CHARS = 10_000


@dataclass
class Instance:
    """One system of a scene: its id, instance name (ROS namespace), parameters (as given),
    method, tolerance and where its world-rooted frames sit."""

    system: str
    name: str
    parameters: dict[str, Any] = field(default_factory=dict)
    method: str = "auto"
    tolerance: float = 1e-10
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    effort_limit: float = float(EFFORT_LIMIT.default)
    #: The model built from (system, parameters) and those inputs: built once, when the
    #: instance is parsed (every check of the model), and handed on to its run.
    _built: tuple[str, dict[str, Any], Model] | None = field(default=None, init=False,
                                                             repr=False, compare=False)

    def build(self) -> Model:
        """This instance's model: the one built when it was parsed if system and parameters
        are still the ones it was built from, else a new one (validated: ParameterError)."""
        built = self._built
        if built is not None and built[0] == self.system and built[1] == self.parameters:
            return built[2]
        model = system_class(self.system)(**self.parameters)
        self._built = (self.system, dict(self.parameters), model)
        return model


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
        raise ParameterError(field_name, f"must be a number (got {shown(value)})")
    try:
        x = float(value)
    except OverflowError:
        x = math.inf
    if not math.isfinite(x) or (positive and x <= 0):
        raise ParameterError(field_name, f"must be a finite positive number (got "
                             f"{shown(value)})")
    return x


def setting(p: Any, field_name: str, value: Any) -> float:
    """A scene's number for the run setting ``p`` (``mechsim.params``): numbers only (no
    strings), in the one range the CLI and the nodes share."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ParameterError(field_name, f"must be a number (got {shown(value)})")
    return float(p.check(value, field_name))


def instance_name(field_name: str, value: Any) -> str:
    """A valid instance name (ROS namespace) or ParameterError naming ``field_name``."""
    if not isinstance(value, str) or not _NAME.fullmatch(value):
        raise ParameterError(field_name, f"must be a ROS name [A-Za-z][A-Za-z0-9_]* of at "
                             f"most {MAX_NAME} characters (got {shown(value)})")
    return value


def scene_name(value: Any) -> str:
    if not isinstance(value, str) or not _SCENE_NAME.fullmatch(value):
        raise ParameterError("name", f"must be letters, digits, _ . - (not first: . -), at "
                             f"most {MAX_NAME} characters (got {shown(value)})")
    return value


def _name_from_stem(stem: str) -> str:
    """A valid scene name from a file name (characters outside the name set become _)."""
    name = re.sub(r"[^A-Za-z0-9_.-]", "_", stem).lstrip(".-")[:MAX_NAME]
    return name or "scene"


def _keys(where: str, data: dict[str, Any], allowed: set[str]) -> None:
    for key in data:
        if key not in allowed:
            text = key if isinstance(key, str) and len(key) <= 60 else shown(key)
            raise ParameterError(f"{where}.{text}" if where else text,
                                 f"unknown key (allowed: {', '.join(sorted(allowed))})")


@dataclass(frozen=True)
class Override:
    """One ``--set``: ``name=value`` for every instance that has the parameter,
    ``instance:name=value`` for one."""

    key: str  # as given, before the "=" (named in messages)
    instance: str  # "" for every instance
    name: str
    value: Any


def parse_sets(sets: list[str]) -> list[Override]:
    """The ``--set`` items, each read once (its value as YAML where that parses, without
    aliases; else the text itself)."""
    out = []
    for item in sets:
        check_text("--set", item, MAX_SET_CHARS)
        if "=" not in item:
            raise ParameterError("--set", f"expected name=value (got {shown(item)})")
        key, raw = item.split("=", 1)
        instance, _, name = key.rpartition(":")
        try:
            value = load_yaml(raw, f"--set {shown(key)}", MAX_SET_CHARS)
        except MechsimError:
            value = raw
        out.append(Override(key, instance, name, value))
    return out


def parse_instance(data: Any, index: int, overrides: tuple[Override, ...] = ()) -> Instance:
    """One entry of a scene's ``systems`` with the ``overrides`` that concern it applied,
    validated (its model built: every check) once."""
    where = f"systems[{index}]"
    if not isinstance(data, dict):
        raise ParameterError(where, "must be a mapping with at least `system`")
    _keys(where, data, {"system", "name", "parameters", "method", "tolerance", "origin",
                        EFFORT_LIMIT.name})
    if "system" not in data:
        raise ParameterError(f"{where}.system", "missing")
    system = data["system"]
    if not isinstance(system, str) or len(system) > MAX_NAME:
        raise ParameterError(f"{where}.system", f"must be a system id (got {shown(system)})")
    cls = system_class(system)  # UnknownSystemError names the id
    name = instance_name(f"{where}.name", data.get("name", system))
    params = data.get("parameters", {}) or {}
    if not isinstance(params, dict):
        raise ParameterError(f"{where}.parameters", "must be a mapping name: value")
    flat = _parameters(where, params)
    given = {p.name for p in cls.parameter_spec()}
    applied: dict[str, Override] = {}
    for o in overrides:
        if o.name in given and o.instance in ("", name):
            flat[o.name] = o.value
            applied[o.name] = o
    try:
        model = cls(**flat)  # validates every parameter now, with the field named
    except ParameterError as e:
        given_by = applied.get(e.field)  # a --set: named as the user wrote it
        field_name = f"{where}.parameters.{e.field}" if given_by is None else \
            f"--set {given_by.key if len(given_by.key) <= 60 else shown(given_by.key)}"
        raise ParameterError(field_name, e.reason) from None
    method = data.get("method", "auto")
    if not isinstance(method, str) or method not in METHODS:
        raise ParameterError(f"{where}.method", f"must be one of {', '.join(METHODS)} "
                             f"(got {shown(method)})")
    tol = setting(TOLERANCE, f"{where}.tolerance", data.get("tolerance", TOLERANCE.default))
    origin = data.get("origin", [0.0, 0.0, 0.0])
    if not (isinstance(origin, list | tuple) and len(origin) == 3):
        raise ParameterError(f"{where}.origin", "must be a list of three numbers [x, y, z]")
    org = tuple(positive_number(f"{where}.origin", v, positive=False) for v in origin)
    inst = Instance(system, name, flat, method, tol, org,  # type: ignore[arg-type]
                    _instance_setting(EFFORT_LIMIT, where, data, name, overrides))
    inst._built = (system, dict(flat), model)
    return inst


def _instance_setting(p: Any, where: str, data: dict[str, Any], name: str,
                      overrides: tuple[Override, ...]) -> float:
    """An instance's run setting ``p`` (``effort_limit``): its key in the scene entry, or a
    ``--set`` of the same name (for every instance, or ``NAME:`` for this one)."""
    given = [o for o in overrides if o.name == p.name and o.instance in ("", name)]
    if given:
        return setting(p, f"--set {given[-1].key}", given[-1].value)
    return setting(p, f"{where}.{p.name}", data.get(p.name, p.default))


def _parameters(where: str, params: dict[str, Any]) -> dict[str, Any]:
    """A scene entry's parameters as flat ``name: value`` (``initial: {angle: 1}`` is
    ``initial.angle``)."""
    try:
        return flatten(params)
    except ParameterError as e:
        raise ParameterError(f"{where}.parameters.{e.field}", e.reason) from None


def parse_scene(data: Any, default_name: str = "scene",
                overrides: list[Override] | tuple[Override, ...] = ()) -> Scene:
    """The scene of ``data`` (a scene file's YAML) with ``overrides`` (``--set``) applied,
    every field validated once (ParameterError naming it)."""
    if not isinstance(data, dict):
        raise ParameterError("scene", "must be a YAML mapping with a `systems` list")
    _keys("", data, {"name", "pacing", "real_time_factor", "duration", "publish_rate",
                     "diagnostics", "outputs", "systems"})
    systems = data.get("systems")
    if not isinstance(systems, list) or not systems:
        raise ParameterError("systems", "must be a non-empty list of system instances")
    instances = [parse_instance(s, i, tuple(overrides)) for i, s in enumerate(systems)]
    _check_overrides(instances, overrides)
    names = [i.name for i in instances]
    for n in names:
        if names.count(n) > 1:
            raise ParameterError("systems", f"instance name {n!r} used twice: set `name`")
    pacing = data.get("pacing", "realtime")
    if pacing not in ("realtime", "fast"):
        raise ParameterError("pacing", f"must be realtime or fast (got {shown(pacing)})")
    name = scene_name(data["name"]) if "name" in data else _name_from_stem(default_name)
    scene = Scene(name=name, systems=instances, pacing=pacing)
    if "real_time_factor" in data:
        # 0 (as fast as possible) is the same as pacing: fast.
        scene.real_time_factor = setting(REAL_TIME_FACTOR, "real_time_factor",
                                         data["real_time_factor"])
        if scene.real_time_factor == 0:
            scene.pacing = "fast"
    if data.get("duration") is not None:
        scene.duration = setting(DURATION, "duration", data["duration"])
    if "publish_rate" in data:
        scene.publish_rate = setting(PUBLISH_RATE, "publish_rate", data["publish_rate"])
    _diagnostics(scene, data.get("diagnostics") or {})
    _outputs(scene, data.get("outputs") or {})
    return scene


def _diagnostics(scene: Scene, diag: Any) -> None:
    """The scene's ``diagnostics:`` thresholds."""
    if not isinstance(diag, dict):
        raise ParameterError("diagnostics", "must be a mapping")
    _keys("diagnostics", diag, {"warn_drift", "error_drift"})
    scene.warn_drift = setting(WARN_DRIFT, "diagnostics.warn_drift",
                               diag.get("warn_drift", Law.WARN_DRIFT))
    scene.error_drift = setting(ERROR_DRIFT, "diagnostics.error_drift",
                                diag.get("error_drift", Law.ERROR_DRIFT))
    if scene.warn_drift >= scene.error_drift:
        raise ParameterError("diagnostics.warn_drift", "must be smaller than error_drift")


def _outputs(scene: Scene, outputs: Any) -> None:
    """The scene's ``outputs:`` paths (checked as text; as paths when a run opens them)."""
    if not isinstance(outputs, dict):
        raise ParameterError("outputs", "must be a mapping")
    _keys("outputs", outputs, {"bag", "rrd"})
    for key in ("bag", "rrd"):
        if outputs.get(key) is not None:
            check_text(f"outputs.{key}", outputs[key])
    scene.bag, scene.rrd = outputs.get("bag"), outputs.get("rrd")


def _check_overrides(instances: list[Instance], overrides: list[Override] | tuple[Override, ...]
                     ) -> None:
    """Every ``--set`` names a parameter of an instance it is meant for."""
    for o in overrides:
        if o.name == EFFORT_LIMIT.name and any(o.instance in ("", i.name) for i in instances):
            continue  # a run setting of every instance
        if not any(o.instance in ("", inst.name) and o.name in
                   {p.name for p in system_class(inst.system).parameter_spec()}
                   for inst in instances):
            where = f"instance {shown(o.instance)}" if o.instance else "any system of the scene"
            raise ParameterError(f"--set {shown(o.name)}", f"not a parameter of {where}")


def load_scene(path: str | Path, overrides: list[Override] | tuple[Override, ...] = ()
               ) -> Scene:
    """Read and validate a scene file with ``overrides`` (``--set``) applied (MechsimError
    with a one-line reason on any problem): a regular file of at most ``MAX_SCENE_BYTES`` of
    UTF-8, YAML without aliases (``mechsim.files``)."""
    p = Path(check_text("scene", str(path)))
    try:
        raw = read_bounded(p, MAX_SCENE_BYTES)
    except OSError as e:
        raise MechsimError(f"scene {p}: cannot read ({e.strerror or e})") from None
    data = load_yaml(raw, f"scene {p}", MAX_SCENE_BYTES)
    try:
        scene = parse_scene(data, default_name=p.stem, overrides=overrides)
    except ParameterError as e:
        if e.field.startswith("--set"):
            raise
        raise ParameterError(f"scene {p}: {e.field}", e.reason) from None
    scene.source = p
    return scene


def single_system_scene(system: str, parameters: dict[str, Any] | None = None,
                        name: str | None = None,
                        overrides: list[Override] | tuple[Override, ...] = ()) -> Scene:
    """The scene `mechsim run SYSTEM` uses: one instance with default settings, named
    ``name`` (default: the system id)."""
    inst = name or system
    return parse_scene({"name": inst, "systems": [{"system": system, "name": inst,
                                                   "parameters": parameters or {}}]},
                       overrides=overrides)


def scene_from_target(target: str, sets: list[str], name: str | None = None) -> Scene:
    """The scene a command names: a scene file, or a system id run with its default scene
    (its one instance named ``name``, default the id); with the ``--set`` overrides applied
    as it is parsed, once."""
    from mechsim.systems import system_ids

    check_text("target", target)
    if name is not None:
        instance_name("--name", name)
    if target.endswith((".yaml", ".yml")) or Path(target).is_file():
        if name is not None:
            raise ParameterError("--name", "only with a SYSTEM target (a scene file names its "
                                 "instances)")
        return load_scene(target, parse_sets(sets))
    if target in system_ids():
        return single_system_scene(target, name=name, overrides=parse_sets(sets))
    raise UnknownSystemError(target, system_ids())


#: Format of a scene as data (``scene_data``).
SCENE_FORMAT = "mechsim-scene/1"


def scene_data(scene: Scene) -> dict[str, Any]:
    """The scene as plain data (JSON), exactly as parsed and with the run's settings it holds:
    what the processes of a multi-process run receive (:func:`scene_from_data`) instead of
    the command line to parse again."""
    return {"format": SCENE_FORMAT, "name": scene.name, "pacing": scene.pacing,
            "real_time_factor": scene.real_time_factor, "duration": scene.duration,
            "publish_rate": scene.publish_rate, "warn_drift": scene.warn_drift,
            "error_drift": scene.error_drift, "bag": scene.bag, "rrd": scene.rrd,
            "source": None if scene.source is None else str(scene.source),
            "systems": [{"system": i.system, "name": i.name, "parameters": i.parameters,
                         "method": i.method, "tolerance": i.tolerance,
                         "origin": list(i.origin), "effort_limit": i.effort_limit}
                        for i in scene.systems]}


def _optional(value: Any, kind: type) -> Any:
    if value is not None and not isinstance(value, kind):
        raise TypeError(value)
    return value


def scene_from_data(data: Any) -> Scene:
    """The scene :func:`scene_data` wrote (not parsed again: its models run their own checks
    when they are built); ParameterError if ``data`` is not such a scene."""
    try:
        if data.get("format") != SCENE_FORMAT:
            raise TypeError(data.get("format"))
        systems = [Instance(str(d["system"]), str(d["name"]), dict(d["parameters"]),
                            str(d["method"]), float(d["tolerance"]),
                            tuple(float(x) for x in d["origin"]),  # type: ignore[arg-type]
                            float(d["effort_limit"]))
                   for d in data["systems"]]
        source = _optional(data["source"], str)
        return Scene(name=str(data["name"]), systems=systems, pacing=str(data["pacing"]),
                     real_time_factor=float(data["real_time_factor"]),
                     duration=_optional(data["duration"], float),
                     publish_rate=float(data["publish_rate"]),
                     warn_drift=float(data["warn_drift"]),
                     error_drift=float(data["error_drift"]),
                     bag=_optional(data["bag"], str), rrd=_optional(data["rrd"], str),
                     source=None if source is None else Path(source))
    except (AttributeError, KeyError, TypeError, ValueError):
        raise ParameterError("scene", f"not a scene written by mechsim ({SCENE_FORMAT})"
                             ) from None
