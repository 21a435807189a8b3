"""Random and hostile inputs (hypothesis): ``load_system`` for every system id,
``Parameter.validate``, ``parse_scene`` / ``load_scene``, runtime ROS parameter changes and the
bag reader / repair on random bytes and truncated real bags; YAML alias bombs, shared-reference
bombs in Python data, curve expressions, integers with hundreds or thousands of digits, bytes
that are not UTF-8, control characters and NUL in names and paths. Allowed outcomes: success,
or a MechsimError (ParameterError, UnknownSystemError, ...) with a one-line message of bounded
length; never another exception, never a hang (alarm), never a partial file left behind."""

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
            assert text and "\n" not in text, repr(text[:200])
            assert len(text) < 2000, f"{len(text)} characters: {text[:200]}..."
            return e


# Within 4300 digits (hypothesis prints its examples); 10**5000 is tried separately.
HUGE_INTEGERS = [10**400, -(10**400), 10**4000, 2**64, -(2**63) - 1]

hostile_scalars = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-10**30, max_value=10**30),
    st.sampled_from(HUGE_INTEGERS),
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
@given(st.one_of(hostile_scalars.filter(lambda v: not (isinstance(v, int) and v.bit_length()
                                                      > 1000)),  # system_class prints ids
                 st.text(max_size=20)))
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


def _alias_bomb(levels: int = 9, width: int = 9) -> str:
    """~600 bytes of YAML whose last alias stands for width**levels (387 million) strings."""
    lines = ["l0: &l0 [" + ", ".join(["lol"] * width) + "]"]
    for i in range(1, levels):
        lines.append(f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * width) + "]")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("where", ["name: *l8", "systems: [{system: pendulum, name: *l8}]",
                                   "systems: [{system: pendulum, parameters: {mass: *l8}}]",
                                   "systems: *l8", "pacing: *l8"])
def test_yaml_alias_bomb_refused(tmp_path: Path, where: str) -> None:
    """An alias bomb anywhere in a scene: one line naming the alias, at once, never expanded
    (str()/repr() of it in an error message would take gigabytes)."""
    from mechsim.scene import load_scene

    p = tmp_path / "bomb.yaml"
    p.write_text(_alias_bomb() + where + "\n")
    assert p.stat().st_size < 1000
    err = only_mechsim_errors(lambda: load_scene(p))
    assert isinstance(err, MechsimError), err
    assert "aliases are not allowed" in str(err), err


def test_alias_in_a_set_value_is_not_expanded() -> None:
    """``--set mass=<alias bomb>``: the value is not read as YAML (aliases refused), so it is
    the text itself that is refused as a number."""
    from mechsim.scene import scene_from_target

    lines = _alias_bomb().splitlines()
    bomb = "[" + ", ".join(line.split(": ", 1)[1] for line in lines) + ", *l8]"
    err = only_mechsim_errors(lambda: scene_from_target("pendulum", [f"mass={bomb}"]))
    assert isinstance(err, MechsimError) and "must be a number (got '[&l0" in str(err), err


def _shared_bomb(levels: int = 22) -> list[Any]:
    """Python data with shared references: 2**22 leaves, a repr of 20 MB."""
    x: list[Any] = ["lol"]
    for _ in range(levels):
        x = [x, x]
    return x


@pytest.mark.parametrize("key", ["name", "pacing", "system", "instance_name", "method",
                                 "parameter", "outputs", "duration"])
def test_shared_reference_bomb_shown_bounded(key: str) -> None:
    """The API accepts Python data: a value whose repr is huge is shown in a few characters."""
    from mechsim.scene import parse_scene

    bomb = _shared_bomb()
    inst: dict[str, Any] = {"system": "pendulum"}
    data: dict[str, Any] = {"systems": [inst]}
    if key in ("name", "pacing", "duration"):
        data[key] = bomb
    elif key == "outputs":
        data["outputs"] = {"bag": bomb}
    elif key == "instance_name":
        inst["name"] = bomb
    elif key == "parameter":
        inst["parameters"] = {"mass": bomb}
    else:
        inst[key] = bomb
    err = only_mechsim_errors(lambda: parse_scene(data))
    assert isinstance(err, MechsimError) and len(str(err)) < 300, str(err)[:300]


@pytest.mark.parametrize("value", [*HUGE_INTEGERS, 10**5000],
                         ids=["1e400", "-1e400", "1e4000", "2^64", "-2^63-1", "1e5000"])
def test_huge_integers_one_line(value: int) -> None:
    """Integers far beyond float or int64: a bounded one-line error wherever they come in
    (float() overflowed and repr() refused more than 4300 digits before)."""
    from mechsim.scene import parse_scene

    for data in ({"duration": value, "systems": [{"system": "pendulum"}]},
                 {"publish_rate": value, "systems": [{"system": "pendulum"}]},
                 {"systems": [{"system": "pendulum", "parameters": {"mass": value}}]},
                 {"systems": [{"system": "coupled_oscillators",
                               "parameters": {"count": value}}]},
                 {"systems": [{"system": "pendulum", "origin": [value, 0, 0]}]},
                 {"diagnostics": {"warn_drift": value}, "systems": [{"system": "pendulum"}]}):
        got = only_mechsim_errors(lambda d=data: parse_scene(d))  # type: ignore[misc]
        if abs(value) > 1.8e308:  # beyond any float: never accepted
            assert isinstance(got, MechsimError), data
    count = {"systems": [{"system": "coupled_oscillators", "parameters": {"count": value}}]}
    assert isinstance(only_mechsim_errors(lambda: parse_scene(count)), MechsimError)


def test_huge_integer_literal_in_a_scene_file(tmp_path: Path) -> None:
    from mechsim.scene import load_scene

    p = tmp_path / "big.yaml"
    p.write_text("duration: " + "9" * 5000 + "\nsystems: [{system: pendulum}]\n")
    err = only_mechsim_errors(lambda: load_scene(p))
    assert isinstance(err, MechsimError)


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(min_size=1, max_size=300))
def test_scene_files_not_utf8(tmp_path: Path, blob: bytes) -> None:
    from mechsim.scene import load_scene

    p = tmp_path / "enc.yaml"
    p.write_bytes(b"name: x\nsystems: [{system: pendulum}]\n# " + blob)
    got = only_mechsim_errors(lambda: load_scene(p))
    try:
        blob.decode("utf-8")
    except UnicodeDecodeError:
        assert isinstance(got, MechsimError) and "not UTF-8" in str(got)


_CONTROL = ["\x00", "\n", "\r", "\x1b[2J", "\u202e", "\x7f", "\ud800"]


@pytest.mark.parametrize("c", _CONTROL, ids=[repr(c) for c in _CONTROL])
def test_control_characters_in_names_and_paths(tmp_path: Path, c: str) -> None:
    """NUL, newlines, escape sequences, bidirectional overrides and lone surrogates in names
    and paths: refused with one line (a NUL used to reach the OS as a ValueError)."""
    from mechsim.scene import load_scene, parse_scene, scene_from_target

    base = {"systems": [{"system": "pendulum"}]}
    for data in ({**base, "name": f"a{c}b"}, {**base, "name": f"ab{c}"},
                 {"systems": [{"system": "pendulum", "name": f"p{c}"}]},
                 {"systems": [{"system": f"pendulum{c}"}]},
                 {**base, "outputs": {"bag": f"runs/a{c}b"}},
                 {**base, "outputs": {"rrd": f"a{c}.rrd"}}):
        err = only_mechsim_errors(lambda d=data: parse_scene(d))  # type: ignore[misc]
        assert isinstance(err, MechsimError), data
    for target in (f"pend{c}ulum", f"{tmp_path}/s{c}.yaml"):
        err = only_mechsim_errors(lambda t=target: scene_from_target(t, []))  # type: ignore[misc]
        assert isinstance(err, MechsimError)
    err = only_mechsim_errors(lambda: load_scene(f"{tmp_path}/x{c}.yaml"))
    assert isinstance(err, MechsimError)
    err = only_mechsim_errors(lambda: scene_from_target("pendulum", [], name=f"p{c}"))
    assert isinstance(err, MechsimError)


def test_scene_name_cannot_leave_runs(tmp_path: Path) -> None:
    """The scene name is part of the default bag path runs/<scene>_<time>: never a path."""
    from mechsim.ros.record import DEFAULT_BAG, bag_path
    from mechsim.scene import Scene, parse_scene

    for name in ("../../../etc/x", "/tmp/x", "..", ".hidden", "a/b", "~root", "%Y", "-x"):
        err = only_mechsim_errors(lambda n=name: parse_scene(  # type: ignore[misc]
            {"name": n, "systems": [{"system": "pendulum"}]}))
        assert isinstance(err, MechsimError), name
        # A Scene built in Python with such a name is refused where the path is made.
        err = only_mechsim_errors(lambda n=name: bag_path(  # type: ignore[misc]
            DEFAULT_BAG, Scene(name=n, systems=[])))
        assert isinstance(err, MechsimError), name
    ok = parse_scene({"name": "my.scene-1", "systems": [{"system": "pendulum"}]})
    assert bag_path(DEFAULT_BAG, ok).startswith("runs/my.scene-1_")


# --- curve expressions (bead on a wire): bounded before sympy ---------------------------------
_ATOMS = ["x", "1", "2", "0.5", "9", "99", "1e6", "1e7", "9e99", "999999999", "pi", "E"]
_FUNCS = ["sin", "cos", "exp", "log", "sqrt", "cosh", "abs", "atanh"]


@st.composite
def curves(draw: st.DrawFn, depth: int = 0) -> str:
    if depth > 3 or draw(st.integers(0, 3)) == 0:
        return draw(st.sampled_from(_ATOMS))
    kind = draw(st.integers(0, 2))
    a = draw(curves(depth + 1))
    if kind == 0:
        return f"{draw(st.sampled_from(_FUNCS))}({a})"
    b = draw(curves(depth + 1))
    op = draw(st.sampled_from(["+", "-", "*", "/", "**", "^"]))
    return f"({a}){op}({b})" if draw(st.booleans()) else f"{a}{op}{b}"


@settings(max_examples=150, deadline=None, derandomize=True)
@given(curves(), st.floats(min_value=-1e3, max_value=1e3))
def test_curve_expressions_bounded(curve: str, x0: float) -> None:
    """Random expressions with large literals and nested powers and functions: parsed and
    checked at initial.x within seconds, or refused with one line (no kernels compiled)."""
    from mechsim.systems.bead_on_wire import BeadOnWire

    only_mechsim_errors(lambda: BeadOnWire(shape="custom", curve=curve,
                                           **{"initial.x": x0}))


@pytest.mark.parametrize("curve", ["9**9**9*x", "x**9**9**9", "(9**99)**99**99", "9^9^9",
                                   "exp(exp(exp(exp(x))))", "10**400*x", "1" * 300,
                                   "x**(99999*99999)", "((((x**2)**2)**2)**2)"])
def test_curve_bombs_refused(curve: str) -> None:
    from mechsim.systems.bead_on_wire import BeadOnWire

    got = only_mechsim_errors(lambda: BeadOnWire(shape="custom", curve=curve,
                                                 **{"initial.x": 1000.0}))
    assert isinstance(got, MechsimError), curve


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
                       st.sampled_from(["exact", "gauss6", "dop853", "verlet", "multiplier"]),
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


# --- bags: mutated real bags (sizes, compression, records, schemas) ----------------------------
#: Values written over 8 bytes of a real bag: the sizes a hostile file declares.
HOSTILE_U64 = [0, 1, 2**31, 2**32, 2**40, 2**62, 2**63 - 1, 2**64 - 1]
mutations = st.lists(st.tuples(st.floats(min_value=0.0, max_value=1.0, exclude_max=True),
                               st.one_of(st.sampled_from(HOSTILE_U64).map(
                                   lambda v: v.to_bytes(8, "little")),
                                   st.binary(min_size=1, max_size=8))),
                     min_size=1, max_size=4)


def mutated(data: bytes, edits: list[tuple[float, bytes]]) -> bytes:
    """``data`` with each edit's bytes written at its relative position (a record's opcode,
    length, a chunk's declared sizes, compression name, CRC, schema or message bytes)."""
    out = bytearray(data)
    for where, blob in edits:
        i = int(where * len(out))
        out[i:i + len(blob)] = blob
    return bytes(out[:len(data)])


def _mutated_bag(root: Path, real_bag: Path, edits: list[tuple[float, bytes]]) -> Path:
    d = root / "mut"
    d.mkdir()
    (d / "mut_0.mcap").write_bytes(mutated((real_bag / "real_0.mcap").read_bytes(), edits))
    (d / "metadata.yaml").write_text(
        (real_bag / "metadata.yaml").read_text().replace("real_0.mcap", "mut_0.mcap"))
    return d


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(mutations)
def test_mutated_real_bag(tmp_path_factory: pytest.TempPathFactory, real_bag: Path,
                          edits: list[tuple[float, bytes]]) -> None:
    """Read and repair a real bag with a few of its bytes overwritten (huge declared sizes
    among them): a result or one line; nothing but the bag's own directory changes."""
    from mechsim.outputs.bag import repair_bag

    root = tmp_path_factory.mktemp("mut")
    d = _mutated_bag(root, real_bag, edits)
    only_mechsim_errors(lambda: _read_all(d))
    before = {p.name for p in d.iterdir()}
    only_mechsim_errors(lambda: repair_bag(d))
    _no_partial_files(d, before)
    assert [p.name for p in root.iterdir()] == ["mut"]


#: Run in a child process under a 512 MiB address-space limit: the mutations of
#: ``test_mutated_real_bag`` drawn by hypothesis there, through the reader verbs' API.
_BOUNDED_FUZZ = """
import sys
from pathlib import Path
from hypothesis import HealthCheck, given, settings
sys.path.insert(0, sys.argv[2])
from test_fuzz import _mutated_bag, _read_all, mutations, only_mechsim_errors
from mechsim.outputs.bag import repair_bag
real, out = Path(sys.argv[1]), Path(sys.argv[3])
count = [0]

@settings(max_examples=25, deadline=None, derandomize=True, database=None,
          suppress_health_check=list(HealthCheck))
@given(mutations)
def fuzz(edits):
    count[0] += 1
    root = out / str(count[0])
    root.mkdir()
    d = _mutated_bag(root, real, edits)
    only_mechsim_errors(lambda: _read_all(d))
    only_mechsim_errors(lambda: repair_bag(d))

fuzz()
print("examples", count[0])
"""


def test_mutated_bags_within_an_address_space_limit(real_bag: Path, tmp_path: Path,
                                                    ros_env: dict[str, str]) -> None:
    """The same mutations under RLIMIT_AS = 512 MiB: memory follows what the reader accepts,
    never what a mutated size declares (a MemoryError would fail the child)."""
    import resource
    import subprocess
    import sys

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (512 << 20, 512 << 20))

    r = subprocess.run([sys.executable, "-c", _BOUNDED_FUZZ, str(real_bag),
                        str(Path(__file__).parent), str(tmp_path)], env=ros_env,
                       capture_output=True, text=True, timeout=600, preexec_fn=limit)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.split() == ["examples", "25"], r.stdout
