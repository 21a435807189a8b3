"""Random and hostile inputs (hypothesis): ``load_system`` for every system id,
``Parameter.validate``, ``parse_scene`` / ``load_scene``, runtime ROS parameter changes and the
bag reader / repair on random bytes and truncated real bags. Allowed outcomes: success, or a
MechsimError (ParameterError, UnknownSystemError, ...) with a one-line message; never another
exception, never a hang (alarm), never a partial file left behind."""

from __future__ import annotations

import math
import os
import signal
import string
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mechsim.errors import MechsimError
from mechsim.params import Parameter
from mechsim.systems import system_class, system_ids

SYSTEMS = system_ids()
FUZZ = settings(max_examples=60, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.too_slow,
                                       HealthCheck.function_scoped_fixture])


@contextmanager
def time_limit(seconds: int = 10) -> Iterator[None]:
    """Fail (not hang) if the block takes longer than ``seconds``."""
    def on_alarm(signum: int, frame: Any) -> None:
        raise TimeoutError(f"no answer within {seconds} s (hang)")

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def only_mechsim_errors(fn: Callable[[], Any]) -> Any:
    with time_limit():
        try:
            return fn()
        except MechsimError as e:
            text = str(e)
            assert text and "\n" not in text, repr(text)
            return e


hostile_scalars = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-10**30, max_value=10**30),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, -1.0, 1e-320, 1e308, -1e308, math.pi, "nan", "inf", "-1",
                     "1e999", "", " ", "true", "0x10", "1_000"]),
    st.text(max_size=12))
hostile = st.recursive(hostile_scalars,
                       lambda inner: st.one_of(st.lists(inner, max_size=3),
                                               st.dictionaries(st.text(max_size=6), inner,
                                                               max_size=3)),
                       max_leaves=6)


def _param_names(system: str) -> list[str]:
    return [p.name for p in system_class(system).parameter_spec()]


@st.composite
def system_and_params(draw: st.DrawFn) -> tuple[str, dict[str, Any]]:
    system = draw(st.sampled_from(SYSTEMS))
    names = _param_names(system)
    keys = st.one_of(st.sampled_from(names), st.text(string.ascii_letters + "._", max_size=10))
    params = draw(st.dictionaries(keys, hostile, max_size=4))
    return system, params


@FUZZ
@given(system_and_params())
def test_load_system_hostile_parameters(case: tuple[str, dict[str, Any]]) -> None:
    from mechsim import load_system

    system, params = case
    only_mechsim_errors(lambda: load_system(system, **params))


@settings(max_examples=25, deadline=None, derandomize=True)
@given(st.one_of(hostile_scalars, st.text(max_size=20)))
def test_load_system_hostile_ids(system_id: Any) -> None:
    from mechsim import load_system

    only_mechsim_errors(lambda: load_system(system_id))


@FUZZ
@given(st.sampled_from(SYSTEMS).flatmap(
    lambda s: st.tuples(st.sampled_from(system_class(s).parameter_spec()), hostile)))
def test_parameter_validate(case: tuple[Parameter, Any]) -> None:
    param, value = case
    got = only_mechsim_errors(lambda: param.validate(value))
    if not isinstance(got, MechsimError):
        assert isinstance(got, param.kind)
        if param.is_numeric:
            assert math.isfinite(got)
            if param.minimum is not None:
                assert got >= param.minimum
            if param.maximum is not None:
                assert got <= param.maximum


scene_keys = st.sampled_from(["name", "pacing", "real_time_factor", "duration", "publish_rate",
                              "diagnostics", "outputs", "systems", "bogus"])
instance = st.one_of(
    hostile,
    st.fixed_dictionaries({"system": st.one_of(st.sampled_from(SYSTEMS), hostile)},
                          optional={"name": st.one_of(st.just("a"), hostile),
                                    "parameters": hostile, "method": hostile,
                                    "tolerance": hostile, "origin": hostile, "extra": hostile}))
scenes = st.one_of(hostile, st.dictionaries(scene_keys, hostile, max_size=5),
                   st.fixed_dictionaries({"systems": st.lists(instance, max_size=3)},
                                         optional={"pacing": hostile, "duration": hostile,
                                                   "publish_rate": hostile,
                                                   "diagnostics": hostile, "outputs": hostile,
                                                   "name": hostile,
                                                   "real_time_factor": hostile}))


@FUZZ
@given(scenes)
def test_parse_scene(data: Any) -> None:
    from mechsim.scene import parse_scene

    only_mechsim_errors(lambda: parse_scene(data))


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.one_of(st.text(max_size=200), st.binary(max_size=200).map(
    lambda b: b.decode("latin-1"))))
def test_load_scene_malformed_yaml(tmp_path: Path, text: str) -> None:
    from mechsim.scene import load_scene

    p = tmp_path / "scene.yaml"
    p.write_text(text, encoding="utf-8", errors="surrogateescape")
    only_mechsim_errors(lambda: load_scene(p))


def test_load_scene_missing_and_unreadable(tmp_path: Path) -> None:
    from mechsim.scene import load_scene

    with pytest.raises(MechsimError, match="cannot read"):
        load_scene(tmp_path / "nope.yaml")
    with pytest.raises(MechsimError, match="cannot read"):
        load_scene(tmp_path)  # a directory
    (tmp_path / "bomb.yaml").write_text("a: &a [*a, *a]\n" * 3 + "systems: [1, 2]\n")
    only_mechsim_errors(lambda: load_scene(tmp_path / "bomb.yaml"))


# --- runtime ROS parameter changes: same validation, bad values rejected, simulation goes on ---
@pytest.fixture(scope="module")
def sim_node() -> Iterator[Any]:
    from mechsim.environment import import_rclpy

    rclpy = import_rclpy()
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    from mechsim.ros.simulator import SimulatorNode
    from mechsim.scene import Instance

    node = SimulatorNode(Instance("pendulum", "fuzzed"), context=ctx, real_time_factor=0.0)
    yield node
    node.destroy_node()
    ctx.try_shutdown()


ros_values = st.one_of(st.booleans(), st.integers(min_value=-2**62, max_value=2**62),
                       st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=8),
                       st.lists(st.floats(allow_nan=True), max_size=3))


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.sampled_from(["mass", "length", "gravity", "initial.angle", "formulation", "method",
                        "tolerance", "publish_rate", "constraint_limit", "real_time_factor"]),
       ros_values)
def test_runtime_parameters_validated(sim_node: Any, name: str, value: Any) -> None:
    from rclpy.parameter import Parameter as RosParameter

    before = sim_node.get_parameter(name).value
    with time_limit():
        try:
            results = sim_node.set_parameters([RosParameter(name, value=value)])
        except Exception as e:  # rclpy refuses some types at construction
            assert type(e).__name__ in ("InvalidParameterTypeException", "TypeError"), e
            return
    res = results[0]
    if not res.successful:
        assert res.reason and "\n" not in res.reason
        assert sim_node.get_parameter(name).value == before
    else:
        v = sim_node.get_parameter(name).value
        if isinstance(v, float):
            assert math.isfinite(v)
    t0 = sim_node.t
    sim_node.advance_to(t0 + 0.05)
    assert sim_node.failed is None, sim_node.failed
    sim_node.set_parameters([RosParameter(name, value=before)])


# --- bags: random bytes, truncated real bags, missing pieces ---------------------------------
@pytest.fixture(scope="module")
def real_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from mechsim.ros import record
    from mechsim.scene import parse_scene

    scene = parse_scene({"name": "fz", "systems": [{"system": "pendulum"}]})
    path = tmp_path_factory.mktemp("bags") / "real"
    record.run_with_outputs(scene, fast=True, duration=0.5, bag=str(path))
    return path


def _read_all(path: Path) -> int:
    from mechsim.outputs.bag import read_messages, read_metadata

    read_metadata(path)
    return sum(1 for _ in read_messages(path))


def _no_partial_files(d: Path, before: set[str]) -> None:
    leftovers = {p.name for p in d.iterdir()} - before
    assert not {n for n in leftovers if n.endswith((".tmp", ".part", ".partial"))}, leftovers


@settings(max_examples=30, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=2048), st.booleans())
def test_bag_reader_random_bytes(tmp_path_factory: pytest.TempPathFactory, real_bag: Path,
                                 blob: bytes, with_metadata: bool) -> None:
    from mechsim.outputs.bag import repair_bag

    d = tmp_path_factory.mktemp("rand") / "rand"
    d.mkdir()
    (d / "rand_0.mcap").write_bytes(blob)
    if with_metadata:
        meta = (real_bag / "metadata.yaml").read_text().replace("real_0.mcap", "rand_0.mcap")
        (d / "metadata.yaml").write_text(meta)
    only_mechsim_errors(lambda: _read_all(d))
    before = {p.name for p in d.iterdir()}
    only_mechsim_errors(lambda: repair_bag(d))
    _no_partial_files(d, before)


@settings(max_examples=25, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.floats(min_value=0.0, max_value=1.0), st.booleans())
def test_truncated_real_bag(tmp_path_factory: pytest.TempPathFactory, real_bag: Path,
                            fraction: float, keep_metadata: bool) -> None:
    from mechsim.outputs.bag import repair_bag

    data = (real_bag / "real_0.mcap").read_bytes()
    d = tmp_path_factory.mktemp("trunc") / "trunc"
    d.mkdir()
    (d / "trunc_0.mcap").write_bytes(data[: int(len(data) * fraction)])
    if keep_metadata:
        (d / "metadata.yaml").write_text(
            (real_bag / "metadata.yaml").read_text().replace("real_0.mcap", "trunc_0.mcap"))
    only_mechsim_errors(lambda: _read_all(d))
    before = {p.name for p in d.iterdir()}
    got = only_mechsim_errors(lambda: repair_bag(d))
    _no_partial_files(d, before)
    if not isinstance(got, MechsimError):  # a repaired bag reads back completely
        assert _read_all(d) == got.messages


@settings(max_examples=30, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.one_of(hostile, st.text(max_size=300)))
def test_corrupt_metadata(tmp_path_factory: pytest.TempPathFactory, real_bag: Path,
                          meta: Any) -> None:
    import yaml

    d = tmp_path_factory.mktemp("meta") / "m"
    d.mkdir()
    (d / "m_0.mcap").write_bytes((real_bag / "real_0.mcap").read_bytes())
    text = meta if isinstance(meta, str) else yaml.safe_dump(
        {"rosbag2_bagfile_information": meta})
    (d / "metadata.yaml").write_text(text, errors="surrogateescape")
    only_mechsim_errors(lambda: _read_all(d))


def test_cli_bad_bags_one_line(tmp_path: Path, real_bag: Path,
                               capsys: pytest.CaptureFixture[str]) -> None:
    """replay / convert / bag info / bag repair on missing or corrupt bags: exit 2, one line."""
    from mechsim.cli import main

    corrupt = tmp_path / "corrupt"
    corrupt.mkdir()
    (corrupt / "corrupt_0.mcap").write_bytes(os.urandom(512))
    (corrupt / "metadata.yaml").write_text(
        (real_bag / "metadata.yaml").read_text().replace("real_0.mcap", "corrupt_0.mcap"))
    for bag in (tmp_path / "missing", corrupt):
        for argv in (["bag", "info", str(bag)], ["bag", "repair", str(bag)],
                     ["replay", str(bag), "--rate", "0"],
                     ["convert", str(bag), "--rrd", str(tmp_path / "x.rrd")]):
            if argv[0] == "bag" and argv[1] == "info" and bag == corrupt:
                continue  # info reads metadata only
            with time_limit(30):
                code = main(argv)
            err = capsys.readouterr().err.strip()
            assert code == 2, (argv, err)
            assert err.startswith("mechsim: error:") and "\n" not in err, (argv, err)
    assert not (tmp_path / "x.rrd").exists()  # no partial output left behind
