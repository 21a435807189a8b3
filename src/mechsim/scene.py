"""Scenes: a YAML file listing system instances, their parameters, rates, pacing and outputs.

Format (every field validated; unknown keys are errors)::

    name: pendulum              # scene name (default: file stem); letters, digits, _ . -
    pacing: realtime            # realtime | fast
    real_time_factor: 1.0       # simulated seconds per wall second (0: pacing fast)
    duration: 20.0              # simulated seconds (omit: run until stopped)
    publish_rate: 100.0         # Hz of simulation time, per system
    diagnostics: {warn_drift: 1.0e-6, error_drift: 1.0e-3}   # relative drifts in (0, 1]
    outputs: {bag: runs/pendulum_bag, rrd: runs/pendulum.rrd, bag_topics: samples}
                                # bag_topics: samples (every topic but <ns>/sample_batch),
                                # batches (it instead of the per-sample topics), both
    systems:
      - system: pendulum        # system id (`mechsim systems`)
        name: pendulum          # namespace, default the system id; unique in the scene
        parameters: {initial.angle: 2.0}
        method: auto            # auto or a method of mechsim.integrators (dop853, radau15, ...)
        tolerance: 1.0e-10
        constraint_limit: 1.0e-2   # optional, as the node's ROS parameters of these names
        effort_timeout: 0.5
        effort_wait: 1.0
        effort_limit: 1.0e+6   # largest |effort| accepted, per coordinate
        origin: [0.0, 0.0, 0.0] # where the system's world-rooted frames sit in the world

The run settings go by the names of the nodes' ROS parameters everywhere: an instance's
``method``, ``tolerance``, ``constraint_limit``, ``effort_timeout``, ``effort_wait`` and
``effort_limit`` (keys of its entry, or names in its ``parameters``), the scene's ``publish_rate``,
``real_time_factor``, ``warn_drift`` and ``error_drift``; ``--set NAME=VALUE`` takes all of
them (``INSTANCE:NAME=VALUE`` for one instance's). Their ranges are defined once in
``mechsim.params`` (shared with the CLI and the nodes' ROS parameters). Files are untrusted
input: at most 1 MiB of UTF-8, YAML aliases are refused, names are checked before they reach
ROS or a path.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mechsim.errors import MechsimError, ParameterError, UnknownSystemError, did_you_mean
from mechsim.files import load_yaml, read_bounded
from mechsim.integrators import METHODS
from mechsim.params import (
    CONSTRAINT_LIMIT,
    DURATION,
    EFFORT_LIMIT,
    EFFORT_TIMEOUT,
    EFFORT_WAIT,
    ERROR_DRIFT,
    PUBLISH_RATE,
    REAL_TIME_FACTOR,
    TOLERANCE,
    WARN_DRIFT,
    Parameter,
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
#: A number YAML 1.1 reads as text (``1e-10``: no dot), taken as the number it spells.
_NUMBER_TEXT = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")

#: What a recording holds (``outputs.bag_topics``, ``--bag-topics``): every topic but the
#: sample batches (``samples``, the default), the batches instead of the per-sample topics
#: (``batches``), or ``both``; the other topics (system_info, /tf_static, markers_static,
#: /diagnostics, the efforts applied) always (``mechsim.outputs.batch.recorded``).
BAG_TOPICS = ("samples", "batches", "both")

#: Run settings of one instance (besides ``method``), under the names of the simulator node's
#: ROS parameters: keys of a ``systems`` entry, names in its ``parameters``, and ``--set``
#: names (every instance, or ``INSTANCE:NAME``).
INSTANCE_SETTINGS: dict[str, Parameter] = {
    p.name: p for p in (TOLERANCE, CONSTRAINT_LIMIT, EFFORT_TIMEOUT, EFFORT_WAIT,
                         EFFORT_LIMIT)}
#: Settings of the whole scene (every instance), under the names of the nodes' ROS
#: parameters: top-level keys (the drifts under ``diagnostics``), and ``--set`` names.
SCENE_SETTINGS: dict[str, Parameter] = {
    p.name: p for p in (PUBLISH_RATE, REAL_TIME_FACTOR, WARN_DRIFT, ERROR_DRIFT)}


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
    #: The other run settings given for this instance (``constraint_limit``,
    #: ``effort_timeout``, ``effort_wait``); the rest are the defaults of ``mechsim.params``.
    settings: dict[str, float] = field(default_factory=dict)
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
    #: What a recording holds (:data:`BAG_TOPICS`).
    bag_topics: str = "samples"
    source: Path | None = None
    #: Existing outputs may be replaced (``--force``): an .rrd, once the new one is complete.
    force: bool = False


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
    """A scene's number for the run setting ``p`` (``mechsim.params``): a number (or the text
    of one that YAML 1.1 reads as text, such as ``1e-10``), in the one range the CLI and the
    nodes share."""
    if isinstance(value, str) and _NUMBER_TEXT.fullmatch(value):
        value = float(value)
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
            raise ParameterError(f"{where}.{text}" if where else text, "unknown key" +
                                 did_you_mean(text, allowed, "allowed"))


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


#: The keys of a scene's ``systems`` entry.
INSTANCE_KEYS = {"system", "name", "parameters", "method", "origin", *INSTANCE_SETTINGS}


def parse_instance(data: Any, index: int, overrides: tuple[Override, ...] = ()) -> Instance:
    """One entry of a scene's ``systems`` with the ``overrides`` that concern it applied,
    validated (its model built: every check) once."""
    where = f"systems[{index}]"
    if not isinstance(data, dict):
        raise ParameterError(where, "must be a mapping with at least `system`")
    _keys(where, data, INSTANCE_KEYS)
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
    ours = [o for o in overrides if o.instance in ("", name)]
    method, tol, settings = _instance_settings(where, data, flat, given, ours)
    applied: dict[str, Override] = {}
    for o in ours:
        if o.name in given:
            flat[o.name] = o.value
            applied[o.name] = o
    try:
        model = cls(**flat)  # validates every parameter now, with the field named
    except ParameterError as e:
        given_by = applied.get(e.field)  # a --set: named as the user wrote it
        field_name = f"{where}.parameters.{e.field}" if given_by is None else \
            _set_field(given_by)
        raise ParameterError(field_name, e.reason) from None
    origin = data.get("origin", [0.0, 0.0, 0.0])
    if not (isinstance(origin, list | tuple) and len(origin) == 3):
        raise ParameterError(f"{where}.origin", "must be a list of three numbers [x, y, z]")
    org = tuple(positive_number(f"{where}.origin", v, positive=False) for v in origin)
    inst = Instance(system, name, flat, method, tol, org, settings)  # type: ignore[arg-type]
    inst._built = (system, dict(flat), model)
    return inst


def _set_field(o: Override) -> str:
    """How a ``--set`` is named in a message: as the user wrote it (bounded)."""
    return f"--set {o.key if len(o.key) <= 60 else shown(o.key)}"


def _instance_settings(where: str, data: dict[str, Any], flat: dict[str, Any],
                       given: set[str], overrides: list[Override]
                       ) -> tuple[str, float, dict[str, float]]:
    """(method, tolerance, other settings) of an instance: its keys, the run settings among
    its ``parameters`` (taken out of ``flat``) and the ``--set`` overrides, each checked
    where it was given."""
    raw: dict[str, tuple[Any, str]] = {}
    for key in ("method", *INSTANCE_SETTINGS):
        if key in data:
            raw[key] = (data[key], f"{where}.{key}")
        if key in flat and key not in given:
            if key in data:
                raise ParameterError(f"{where}.parameters.{key}", f"given twice (also as "
                                     f"{where}.{key})")
            raw[key] = (flat.pop(key), f"{where}.parameters.{key}")
    for key in SCENE_SETTINGS:
        if key in flat and key not in given:
            raise ParameterError(f"{where}.parameters.{key}", "a setting of the whole scene "
                                 f"(its top-level `{key}`), not of one system")
    for o in overrides:
        if o.name not in given and (o.name == "method" or o.name in INSTANCE_SETTINGS):
            raw[o.name] = (o.value, _set_field(o))
    method, method_field = raw.pop("method", ("auto", f"{where}.method"))
    if not isinstance(method, str) or method not in METHODS:
        raise ParameterError(method_field, f"unknown method {shown(method)}" +
                             did_you_mean(method if isinstance(method, str) else "", METHODS,
                                          "methods"))
    values = {key: setting(INSTANCE_SETTINGS[key], f, v) for key, (v, f) in raw.items()}
    tol = values.pop("tolerance", float(TOLERANCE.default))
    return method, tol, values


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
    data = _with_scene_overrides(data, overrides)
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
    _keys("outputs", outputs, {"bag", "rrd", "bag_topics"})
    for key in ("bag", "rrd"):
        if outputs.get(key) is not None:
            check_text(f"outputs.{key}", outputs[key])
    scene.bag, scene.rrd = outputs.get("bag"), outputs.get("rrd")
    if outputs.get("bag_topics") is not None:
        scene.bag_topics = bag_topics("outputs.bag_topics", outputs["bag_topics"])


def bag_topics(field_name: str, value: Any) -> str:
    """What a recording holds (:data:`BAG_TOPICS`), checked."""
    if value not in BAG_TOPICS:
        raise ParameterError(field_name, f"got {shown(value)}"
                             + did_you_mean(str(value), BAG_TOPICS, "choices"))
    return str(value)


def _with_scene_overrides(data: dict[str, Any],
                          overrides: list[Override] | tuple[Override, ...]) -> dict[str, Any]:
    """The scene's data with the ``--set`` of scene settings (``SCENE_SETTINGS``) in it, each
    checked and named as given."""
    out = dict(data)
    for o in overrides:
        p = SCENE_SETTINGS.get(o.name)
        if p is None:
            continue
        if o.instance:
            raise ParameterError(_set_field(o), "a setting of the whole scene: give it without "
                                 "an instance")
        value = setting(p, _set_field(o), o.value)
        if o.name in ("warn_drift", "error_drift"):
            diag = out.get("diagnostics") or {}
            out["diagnostics"] = {**(diag if isinstance(diag, dict) else {}), o.name: value}
        else:
            out[o.name] = value
    return out


def _check_overrides(instances: list[Instance], overrides: list[Override] | tuple[Override, ...]
                     ) -> None:
    """Every ``--set`` names a parameter or run setting of an instance it is meant for, or a
    setting of the scene; else the names it could have meant."""
    names = {inst.name for inst in instances}
    for o in overrides:
        if o.instance and o.instance not in names:
            raise ParameterError(_set_field(o), f"no instance {shown(o.instance)} in the scene"
                                 + did_you_mean(o.instance, names, "instances"))
        targets = [inst for inst in instances if o.instance in ("", inst.name)]
        params = {p.name for inst in targets
                  for p in system_class(inst.system).parameter_spec()}
        known = params | {"method", *INSTANCE_SETTINGS} | set(SCENE_SETTINGS)
        if o.name not in known:
            where = f"instance {shown(o.instance)}" if o.instance else "any system of the scene"
            raise ParameterError(f"--set {shown(o.name)}", f"not a parameter of {where} nor a "
                                 f"run setting{did_you_mean(o.name, known, 'names')}")


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
            "bag_topics": scene.bag_topics, "force": scene.force,
            "source": None if scene.source is None else str(scene.source),
            "systems": [{"system": i.system, "name": i.name, "parameters": i.parameters,
                         "method": i.method, "tolerance": i.tolerance,
                         "origin": list(i.origin), "settings": dict(i.settings)}
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
                            {str(k): float(v) for k, v in d["settings"].items()})
                   for d in data["systems"]]
        source = _optional(data["source"], str)
        return Scene(name=str(data["name"]), systems=systems, pacing=str(data["pacing"]),
                     real_time_factor=float(data["real_time_factor"]),
                     duration=_optional(data["duration"], float),
                     publish_rate=float(data["publish_rate"]),
                     warn_drift=float(data["warn_drift"]),
                     error_drift=float(data["error_drift"]),
                     bag=_optional(data["bag"], str), rrd=_optional(data["rrd"], str),
                     bag_topics=bag_topics("bag_topics", data["bag_topics"]),
                     source=None if source is None else Path(source),
                     force=_optional(data["force"], bool) is True)
    except (AttributeError, KeyError, TypeError, ValueError):
        raise ParameterError("scene", f"not a scene written by mechsim ({SCENE_FORMAT})"
                             ) from None
