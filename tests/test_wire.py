"""The wire encoder (``mechsim.outputs.wire``) against rclpy's own serializer: every message
type installed (plain random values), every type mechsim publishes (hostile values: empty and
long sequences, long and multi-byte strings, strings with a NUL, NaN with a payload, infinities,
negative zero, subnormals, the extreme integers), the forms of a value (rclpy message, dicts,
tuples, numpy and ``array.array`` sequences), a definition given as schema text (checked with
rosbags, an independent reader and writer), and the errors."""

from __future__ import annotations

import glob
import math
import os
import random
import struct
import sys
from array import array
from typing import Any

import numpy as np
import pytest

from mechsim.environment import import_rclpy

import_rclpy()

from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402
from rosidl_parser import definition as d  # noqa: E402

from mechsim.errors import MechsimError  # noqa: E402
from mechsim.outputs.wire import (  # noqa: E402
    Layout,
    cdr_bytes,
    compile_encoder,
    encode,
    message_class,
    parse_definition,
    type_of,
    typestore_with,
)

INSTALLED = sorted({f"{p.split(os.sep)[-3]}/msg/{os.path.basename(p)[:-4]}"
                    for p in glob.glob(os.path.join(sys.prefix, "share", "*", "msg", "*.msg"))})
#: Every type a mechsim node publishes or records.
PUBLISHED = ("sensor_msgs/msg/JointState", "geometry_msgs/msg/PoseStamped",
             "geometry_msgs/msg/TwistStamped", "mechsim_msgs/msg/Energy",
             "mechsim_msgs/msg/NamedScalars", "mechsim_msgs/msg/SystemInfo",
             "tf2_msgs/msg/TFMessage", "rosgraph_msgs/msg/Clock",
             "diagnostic_msgs/msg/DiagnosticArray", "std_msgs/msg/Float64MultiArray")

_NAN = struct.unpack("<d", b"\x01\x00\x00\x00\x00\x00\xf8\xff")[0]  # negative, with a payload
_INTS = {"int8": (-2**7, 2**7 - 1), "uint8": (0, 2**8 - 1), "int16": (-2**15, 2**15 - 1),
         "uint16": (0, 2**16 - 1), "int32": (-2**31, 2**31 - 1), "uint32": (0, 2**32 - 1),
         "int64": (-2**63, 2**63 - 1), "uint64": (0, 2**64 - 1), "char": (0, 127)}
_HOSTILE_FLOATS = (math.nan, _NAN, math.inf, -math.inf, -0.0, 5e-324, 1e-45, 1.7976931348623157e308,
                   3.4028234663852886e38, 0.1)
_HOSTILE_TEXT = ("", "a", "ab", "abc", "abcd", "Δ énergie", "🙂☃e\u0301", "a\x00b", "x" * 100_000)


def _number(typename: str, rng: random.Random, hostile: bool) -> Any:
    if typename == "boolean":
        return rng.random() < 0.5
    if typename == "octet":
        return bytes([rng.choice((0, 255)) if hostile else rng.randrange(256)])
    if typename in ("float", "double"):
        if hostile:
            v = rng.choice(_HOSTILE_FLOATS)
            return v if typename == "double" or abs(v) < 3.5e38 or not math.isfinite(v) else 1.0
        return rng.uniform(-1e6, 1e6)
    lo, hi = _INTS[typename]
    return rng.choice((lo, hi, 0)) if hostile else rng.randint(lo, hi)


def _text(rng: random.Random, hostile: bool, bound: int | None) -> str:
    text = rng.choice(_HOSTILE_TEXT) if hostile else "".join(
        rng.choice("abcdefgh/_ Δ") for _ in range(rng.randrange(12)))
    return text[:bound] if bound else text


def _value(t: Any, rng: random.Random, hostile: bool, depth: int) -> Any:
    if isinstance(t, d.BasicType):
        return _number(t.typename, rng, hostile)
    if isinstance(t, d.AbstractString):
        return _text(rng, hostile, getattr(t, "maximum_size", None))
    if isinstance(t, d.NamespacedType):
        return _message(message_class("/".join([*t.namespaces, t.name])), rng, hostile, depth + 1)
    if isinstance(t, d.Array):
        return [_value(t.value_type, rng, hostile, depth) for _ in range(t.size)]
    assert isinstance(t, d.AbstractSequence), t
    nested = isinstance(t.value_type, (d.NamespacedType, d.AbstractString))
    lengths = (0, 1, 3) if nested or depth else (0, 1, 3, 5000)
    n = rng.choice(lengths) if hostile else rng.randrange(4)
    if isinstance(t, d.BoundedSequence):
        n = min(n, t.maximum_size)
    return [_value(t.value_type, rng, hostile, depth) for _ in range(n)]


def _message(cls: type, rng: random.Random, hostile: bool, depth: int = 0) -> Any:
    msg = cls()
    fields = list(cls.get_fields_and_field_types())  # type: ignore[attr-defined]
    for name, t in zip(fields, cls.SLOT_TYPES, strict=True):  # type: ignore[attr-defined]
        setattr(msg, name, _value(t, rng, hostile, depth))
    return msg


def _check(type_name: str, msg: Any, ours: bytes | None = None) -> None:
    """``ours`` (default: ``encode(type_name, msg)``) is rclpy's serialization of ``msg`` with
    zero padding, cut where the data ends, and decodes to what rclpy's bytes decode to."""
    cls = type(msg)
    theirs = serialize_message(msg)  # rmw's estimated size: padding may follow the data
    ours = encode(type_name, msg) if ours is None else ours
    assert len(ours) <= len(theirs), (len(ours), len(theirs))
    a = np.frombuffer(ours, np.uint8)
    b = np.frombuffer(theirs[:len(ours)], np.uint8)
    assert not a[a != b].any(), f"{type_name}: data bytes differ at {np.flatnonzero(a != b)[:8]}"
    assert repr(deserialize_message(ours, cls)) == repr(deserialize_message(theirs, cls))
    # rosbags reads exactly these bytes and writes them again (zero padding, nothing after).
    store = typestore_with(type_name)
    assert store.serialize_cdr(store.deserialize_cdr(ours, type_name), type_name).tobytes() \
        == ours


@pytest.mark.parametrize("type_name", INSTALLED)
def test_every_installed_type_equals_rclpy(type_name: str) -> None:
    cls = message_class(type_name)
    rng = random.Random(type_name)
    for _ in range(3):
        _check(type_name, _message(cls, rng, hostile=False))


@pytest.mark.parametrize("type_name", PUBLISHED)
def test_hostile_values_equal_rclpy(type_name: str) -> None:
    cls = message_class(type_name)
    rng = random.Random(f"hostile {type_name}")
    for _ in range(25):
        msg = _message(cls, rng, hostile=True)
        _check(type_name, msg)
        assert cdr_bytes(msg) == encode(type_name, msg)


def test_value_forms_give_the_same_bytes() -> None:
    """An rclpy message, dicts, tuples; numbers as lists, tuples, numpy arrays (of the field's
    type and of others, contiguous or not, either byte order) or ``array.array``."""
    from sensor_msgs.msg import JointState

    js = JointState(name=["a", "Δ"], position=[1.0, -2.5], velocity=[0.5, 0.25], effort=[])
    js.header.frame_id = "world"
    js.header.stamp.sec, js.header.stamp.nanosec = 7, 999
    want = encode("sensor_msgs/msg/JointState", js)
    _check("sensor_msgs/msg/JointState", js, want)
    wide = np.array([[1.0, 9.0], [-2.5, 9.0]])
    for position in ([1.0, -2.5], (1.0, -2.5), np.array([1.0, -2.5]), wide[:, 0],
                     np.array([1.0, -2.5], dtype=">f8"), array("d", [1.0, -2.5]),
                     np.array([1.0, -2.5], dtype=np.float32), array("f", [1.0, -2.5])):
        as_dict = {"header": {"stamp": {"sec": 7, "nanosec": 999}, "frame_id": "world"},
                   "name": ["a", "Δ"], "position": position, "velocity": [0.5, 0.25],
                   "effort": np.zeros(0)}
        assert encode("sensor_msgs/msg/JointState", as_dict) == want
        as_tuple = (((7, 999), "world"), ("a", "Δ"), position, array("d", [0.5, 0.25]), [])
        assert encode("sensor_msgs/msg/JointState", as_tuple) == want
    octets = {"layout": {"dim": [], "data_offset": 0}, "data": b"\x00\xff\x10"}
    from std_msgs.msg import UInt8MultiArray
    _check("std_msgs/msg/UInt8MultiArray", UInt8MultiArray(data=[0, 255, 16]),
           encode("std_msgs/msg/UInt8MultiArray", octets))


#: A definition no installed package has: every kind of field, in the schema text a bag stores.
BATCH = """\
# a batch of samples as columns
float64[] t
float32[] q
string<=8[<=3] names
Part[2] fixed
Part[<=4] bounded
uint8[3] octets
bool flag
int64 last
================================================================================
MSG: wire_test/Part
int16 a
float64[] b
string c
builtin_interfaces/Time stamp
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""


def _batch(rng: np.random.Generator, n: int) -> dict[str, Any]:
    def part(k: int) -> dict[str, Any]:
        return {"a": -k, "b": rng.standard_normal(k), "c": "ü" * k,
                "stamp": {"sec": k, "nanosec": 3}}
    return {"t": np.arange(n) * 0.1, "q": rng.standard_normal(n).astype(np.float32),
            "names": ["x", "yy", "zzzzzzzz"][: n % 4], "fixed": [part(1), part(0)],
            "bounded": [part(k) for k in range(n % 5)], "octets": b"abc",
            "flag": bool(n % 2), "last": -(2**63)}


@pytest.mark.parametrize("n", [0, 1, 2, 7, 1000])
def test_definition_text_round_trips_through_rosbags(n: int) -> None:
    """A type from a schema text: rosbags (an independent reader and writer, zero padding)
    decodes our bytes and writes them again unchanged, the values in place."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    types = parse_definition("wire_test/msg/Batch", BATCH)
    enc = compile_encoder("wire_test/msg/Batch", types)
    value = _batch(np.random.default_rng(n), n)
    buf = bytearray(b"\x00\x01\x00\x00")
    enc(buf, value)
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(BATCH, "wire_test/msg/Batch"))
    back = store.deserialize_cdr(bytes(buf), "wire_test/msg/Batch")
    assert store.serialize_cdr(back, "wire_test/msg/Batch").tobytes() == bytes(buf)
    assert np.array_equal(back.t, value["t"]) and np.array_equal(back.q, value["q"])
    assert list(back.names) == value["names"] and back.last == -(2**63)
    assert [p.c for p in back.bounded] == [p["c"] for p in value["bounded"]]
    assert [list(p.b) for p in back.fixed] == [list(p["b"]) for p in value["fixed"]]


@pytest.mark.parametrize("value, reason", [
    ({"data": "1.5"}, "cannot encode"),
    ({"data": 1.5}, "cannot encode"),
    ({}, "cannot encode"),
])
def test_a_value_that_does_not_fit_is_one_line(value: Any, reason: str) -> None:
    with pytest.raises(MechsimError, match=reason) as e:
        encode("std_msgs/msg/Int32", value)
    assert "\n" not in str(e.value) and "std_msgs/msg/Int32" in str(e.value)


def test_bounds_and_lengths_are_checked() -> None:
    types = parse_definition("wire_test/msg/Batch", BATCH)
    enc = compile_encoder("wire_test/msg/Batch", types)
    value = _batch(np.random.default_rng(0), 3)
    for key, bad in (("names", ["a", "b", "c", "d"]), ("names", ["123456789"]),
                     ("fixed", value["fixed"][:1]), ("octets", b"ab"),
                     ("bounded", value["fixed"] * 3)):
        with pytest.raises(ValueError, match=key):
            enc(bytearray(b"\x00\x01\x00\x00"), {**value, key: bad})


def test_unsupported_and_broken_definitions_are_one_line() -> None:
    for text, why in (("wstring w\n", "wstring"), ("int32 a\nMissing b\n", "lacks"),
                      ("float64[ x\n", "does not parse")):
        with pytest.raises(MechsimError, match=why) as e:
            parse_definition("wire_test/msg/Bad", text)
        assert "\n" not in str(e.value)
    with pytest.raises(MechsimError, match="not installed"):
        message_class("wire_test/msg/Nothing")


def test_layout_rows_equal_rclpy_for_every_sample() -> None:
    """A chunk encoded by a Layout (prototype traced by the same encoder, numbers and stamps
    written in) equals rclpy's serialization of each sample's message."""
    from mechsim.outputs.wire import time_rows
    from tf2_msgs.msg import TFMessage

    rng = np.random.default_rng(3)
    proto = _message(TFMessage, random.Random(3), hostile=False)
    while not proto.transforms:
        proto = _message(TFMessage, random.Random(len(proto.transforms) + 4), hostile=False)
    lay = Layout("tf2_msgs/msg/TFMessage", proto)
    parts = ("translation.x", "translation.y", "translation.z", "rotation.x", "rotation.y",
             "rotation.z", "rotation.w")
    block = lay.block([f"transforms.{j}.transform.{p}" for j in range(len(proto.transforms))
                       for p in parts])
    n = 6
    values = rng.standard_normal((n, block.width))
    values[0, 0] = math.nan
    ns = np.array([0, 1, 999_999_999, 10**9, 2**40, 2**62], dtype=np.int64)
    for rows in (lay.encode(ns, [(block, values)]), lay.encode(ns, [(block, values)],
                                                                   time_rows(ns))):
        for i in range(n):
            msg = deserialize_message(rows[i].tobytes(), TFMessage)
            want = TFMessage(transforms=proto.transforms)
            for j, tr in enumerate(want.transforms):
                tr.header.stamp.sec, tr.header.stamp.nanosec = divmod(int(ns[i]), 10**9)
                for k, p in enumerate(parts):
                    owner, leaf = p.split(".")
                    setattr(getattr(tr.transform, owner), leaf, float(values[i, 7 * j + k]))
            _check("tf2_msgs/msg/TFMessage", want, rows[i].tobytes())
            assert type_of(msg) == "tf2_msgs/msg/TFMessage"
    one = lay.encode(ns[:1], [(block, values[:1])])
    assert one.tobytes() == lay.encode(ns, [(block, values)])[0].tobytes()
