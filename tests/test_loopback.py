"""ROS 2 stays on loopback, discovery across processes works, generated interfaces import."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import psutil
import pytest

from mechsim.environment import FASTDDS_PROFILE, import_rclpy

if TYPE_CHECKING:
    from rclpy.context import Context

REPO = Path(__file__).resolve().parent.parent
LOOPBACK = {"127.0.0.1", "::1"}
TOPIC = "mechsim_loopback_test/energy"
TFMESSAGE_HASH = "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087"

# A second ROS process: publishes mechsim_msgs/Energy (kinetic = counter) until terminated.
CHILD = f"""
import os, sys, time
from mechsim.environment import import_rclpy
rclpy = import_rclpy()
from rclpy.node import Node
from mechsim_msgs.msg import Energy
rclpy.init()
node = Node("loopback_child")
pub = node.create_publisher(Energy, {TOPIC!r}, 10)
sub = node.create_subscription(Energy, {TOPIC!r} + "_echo", lambda m: None, 10)
print("PROFILE", os.environ["FASTDDS_DEFAULT_PROFILES_FILE"], flush=True)
print("READY", flush=True)
deadline, i = time.monotonic() + 300.0, 0
while time.monotonic() < deadline and rclpy.ok():
    pub.publish(Energy(kinetic=float(i)))
    i += 1
    rclpy.spin_once(node, timeout_sec=0.05)
"""


def non_loopback_sockets(pid: int) -> list[str]:
    bad = []
    for c in psutil.Process(pid).net_connections(kind="inet"):
        addrs = [c.laddr] + ([c.raddr] if c.raddr else [])
        if any(a.ip not in LOOPBACK for a in addrs):
            bad.append(f"{c.type.name} {c.laddr} -> {c.raddr or '-'}")
    return bad


def socket_count(pid: int) -> int:
    return len(psutil.Process(pid).net_connections(kind="inet"))


@pytest.fixture
def child(ros_env: dict[str, str]) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """A publisher in another process; yields (process, the profile path it uses)."""
    proc = subprocess.Popen([sys.executable, "-c", CHILD], env=ros_env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=REPO)
    try:
        profile = ""
        assert proc.stdout is not None
        for line in proc.stdout:
            if line.startswith("PROFILE "):
                profile = line.split(" ", 1)[1].strip()
            if line.strip() == "READY":
                break
        else:
            err = proc.stderr.read() if proc.stderr else ""
            pytest.fail(f"child ROS process died (rc={proc.wait()}): {err[-2000:]}")
        yield proc, profile
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def test_profile_env_points_to_project_profile() -> None:
    assert os.environ["FASTDDS_DEFAULT_PROFILES_FILE"] == str(FASTDDS_PROFILE)
    assert FASTDDS_PROFILE.is_file()
    assert os.environ["RMW_IMPLEMENTATION"] == "rmw_fastrtps_cpp"
    # LOCALHOST would make rmw_fastrtps add non-loopback transports on top of the profile.
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
    linked = REPO / "config" / "fastdds_loopback.xml"
    if linked.exists():
        assert linked.resolve() == FASTDDS_PROFILE


def test_in_process_node_binds_loopback_only(ros_context: Context) -> None:
    import_rclpy()
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_msgs.msg import String

    with Node("loopback_probe", context=ros_context) as node, \
            SingleThreadedExecutor(context=ros_context) as ex:
        ex.add_node(node)
        pub = node.create_publisher(String, "mechsim_loopback_test/probe", 10)
        got: list[str] = []
        node.create_subscription(String, "mechsim_loopback_test/probe",
                                 lambda m: got.append(m.data), 10)
        end = time.monotonic() + 60.0
        while not got and time.monotonic() < end:  # until a message made the round trip
            pub.publish(String(data="x"))
            ex.spin_once(timeout_sec=0.05)
        assert got, "the node's own message never arrived within 60 s"
        pid = os.getpid()
        assert socket_count(pid) > 0, "no sockets seen: the check would prove nothing"
        assert non_loopback_sockets(pid) == []


def test_child_process_binds_loopback_only(
    ros_context: Context, child: tuple[subprocess.Popen[str], str],
) -> None:
    proc, profile = child
    assert profile == str(FASTDDS_PROFILE)
    _first_message(ros_context, proc)  # the child is up, publishing and spinning
    assert proc.poll() is None
    assert socket_count(proc.pid) > 0
    assert non_loopback_sockets(proc.pid) == []


def _first_message(ros_context: Context, proc: subprocess.Popen[str]) -> object:
    """The first Energy message of the child process, received here (60 s at most)."""
    rclpy = import_rclpy()
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from mechsim_msgs.msg import Energy

    received = rclpy.task.Future()
    with Node("loopback_listener", context=ros_context) as node, \
            SingleThreadedExecutor(context=ros_context) as ex:
        ex.add_node(node)
        node.create_subscription(
            Energy, TOPIC, lambda m: received.done() or received.set_result(m), 10)
        ex.spin_until_future_complete(received, timeout_sec=60.0)
        assert proc.poll() is None, "child exited early"
        assert received.done(), "no message from the other process within 60 s"
        return received.result()


def test_message_from_child_process_is_received(
    ros_context: Context, child: tuple[subprocess.Popen[str], str]
) -> None:
    from mechsim_msgs.msg import Energy

    proc, _ = child
    assert isinstance(_first_message(ros_context, proc), Energy)


def msg_field_names(path: Path) -> list[str]:
    names = []
    for raw in path.read_text().splitlines():
        line = raw.split("#", 1)[0].strip()
        if line and "=" not in line.split()[1]:  # skip constants "type NAME=value"
            names.append(line.split()[1])
    return names


def test_generated_interfaces_import() -> None:
    import_rclpy()
    from mechsim_msgs.msg import Energy, NamedScalars
    from tf2_msgs.msg import TFMessage

    assert TFMessage.get_fields_and_field_types() == {
        "transforms": "sequence<geometry_msgs/TransformStamped>"}
    energy_msg = REPO / "src" / "mechsim_msgs" / "msg" / "Energy.msg"
    assert list(Energy.get_fields_and_field_types()) == msg_field_names(energy_msg)
    scalars_msg = REPO / "src" / "mechsim_msgs" / "msg" / "NamedScalars.msg"
    assert list(NamedScalars.get_fields_and_field_types()) == msg_field_names(scalars_msg)
    # Same type hash as upstream tf2_msgs, so /tf interoperates with a real ROS install.
    desc = Path(sys.prefix) / "share" / "tf2_msgs" / "msg" / "TFMessage.json"
    hashes = json.loads(desc.read_text())["type_hashes"]
    assert hashes[0]["hash_string"] == TFMESSAGE_HASH
