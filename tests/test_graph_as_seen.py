"""mechsim's nodes as the ROS graph shows them (what ``ros2 topic echo``, ``ros2 service
list``, ``ros2 param describe`` and ``ros2 node list`` read, asked through rclpy here; the same
with the real ros2 command: test_ros2_cli.py): every advertised topic answers, nothing of a
node that is gone stays listed, the descriptors carry the rules, the read-only pace reads its
value, hidden nodes stay hidden."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import Any

import yaml

import mechsim
from mechsim.ros.outlet import subscription_qos
from rosuser import DEADLINE, Listener, mechsim_command, process, until

#: Topics of the ROS infrastructure every node has, published only on events.
INFRASTRUCTURE = ("/rosout", "/parameter_events")


def _scene(tmp: Path, systems: list[str], rate: float = 20.0) -> Path:
    path = tmp / "scene.yaml"
    path.write_text(yaml.safe_dump({"name": "seen", "publish_rate": rate, "systems": [
        {"system": s, "name": s, "origin": [3.0 * i, 0.0, 0.0]}
        for i, s in enumerate(systems)]}))
    return path


def _env() -> dict[str, str]:
    return {**os.environ, "MECHSIM_GRAPH_WAIT": "0"}


def _expected(systems: list[str]) -> set[str]:
    """The topics a scene of ``systems`` publishes: each system's by what its model has,
    and the shared ones."""
    topics = {"/clock", "/diagnostics"}
    for s in systems:
        m = mechsim.load_system(s)
        joints = len(m.coordinates) - (4 if m.attitude is not None else 0)
        for leaf, has in (("energy", True), ("system_info", True), ("sample_batch", True),
                          ("state", joints > 0),
                          ("pose", m.attitude is not None), ("twist", m.attitude is not None),
                          ("invariants", bool(m.invariants)),
                          ("observables", bool(m.observables)),
                          ("markers", bool(m.frames) and any(
                              v.kind in ("link", "trail") for v in m.visuals())),
                          ("markers_trails", bool(m.frames) and any(
                              v.kind == "trail" for v in m.visuals())),
                          ("markers_static", bool(m.frames) and any(
                              v.kind not in ("link", "trail") for v in m.visuals())),
                          ("curves", bool(m.curves()))):
            if has:
                topics.add(f"/{s}/{leaf}")
        if any(not f.static for f in m.frames):
            topics.add("/tf")
        if any(f.static for f in m.frames):
            topics.add("/tf_static")
    return topics


def _advertised(listener: Listener, expected: set[str]) -> dict[str, str]:
    """The topics the scene's nodes publish, with their types, once the expected ones are
    all advertised."""
    node = listener.node

    def seen() -> dict[str, str] | None:
        topics = {t: types[0] for t, types in node.get_topic_names_and_types()
                  if t not in INFRASTRUCTURE and node.get_publishers_info_by_topic(t)}
        return topics if expected <= set(topics) else None
    return listener.wait(seen, "every expected topic advertised")


def test_every_advertised_topic_of_every_system_answers(ros_context: Any,
                                                        tmp_path: Path) -> None:
    """As ``ros2 topic echo --once``: a reader with the QoS its publishers offer gets a
    message on each topic within a bounded time; no topic is advertised and left silent
    (invariants where a system has none, /tf where every frame is fixed, ...)."""
    from mechsim.outputs.bag import message_class

    systems = mechsim.system_ids()
    listener = Listener(ros_context)
    try:
        with process(mechsim_command("run", str(_scene(tmp_path, systems))), _env()) as p:
            expected = _expected(systems)
            topics = _advertised(listener, expected)
            assert set(topics) == expected  # none advertised that nothing is published on
            for topic, type_name in topics.items():
                offered = [i.qos_profile for i in
                           listener.node.get_publishers_info_by_topic(topic)]
                listener.listen(topic, message_class(type_name), subscription_qos(offered))
            try:
                listener.wait(lambda: all(listener.got[t] for t in topics),
                              "a message on every advertised topic")
            except AssertionError:
                raise AssertionError(f"silent: {sorted(t for t in topics if not listener.got[t])}"
                                     ) from None
            assert p.poll() is None
    finally:
        listener.close()


def test_nothing_of_a_node_that_is_gone_stays_listed(ros_context: Any, tmp_path: Path) -> None:
    """The start-up graph check's node and the command tools' nodes offer no service and
    leave nothing behind; a stopped simulator's services leave the list."""
    listener = Listener(ros_context)
    node = listener.node
    try:
        with process(mechsim_command("run", "pendulum"), os.environ):
            listener.wait(lambda: "/pendulum/simulator/step" in dict(
                node.get_service_names_and_types()), "the simulator's services")
            def listed() -> bool:
                """One `mechsim node list` (its discovery window is a second: on a loaded
                machine a run may list the simulator only the next time)."""
                out = subprocess.run(mechsim_command("node", "list"), capture_output=True,
                                     text=True, timeout=DEADLINE)
                assert out.returncode == 0, out.stderr
                return "/pendulum/simulator" in out.stdout

            until(listed, "`mechsim node list` listing /pendulum/simulator")
            listener.wait(lambda: "/mechsim/node_list" not in [
                f"{ns.rstrip('/')}/{n}" for n, ns in node.get_node_names_and_namespaces()],
                "the node list tool's node gone")
            services = [s for s, _ in node.get_service_names_and_types()]
            assert not [s for s in services if "graph_check" in s or "node_list" in s], services
        listener.wait(lambda: not [s for s, _ in node.get_service_names_and_types()
                                   if s.startswith("/pendulum/")],
                      "the stopped simulator's services gone")
    finally:
        listener.close()


def _describe(ros_context: Any, node_name: str, names: list[str]) -> dict[str, Any]:
    from rcl_interfaces.srv import DescribeParameters, GetParameters
    from rclpy.executors import SingleThreadedExecutor

    from mechsim.ros.graph_check import quiet_node
    from mechsim.testing import wait_until

    client_node = quiet_node("describer", "/", ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(client_node)
    try:
        out: dict[str, Any] = {}
        for srv, service, field in ((DescribeParameters, "describe_parameters",
                                     "descriptors"), (GetParameters, "get_parameters",
                                                      "values")):
            c = client_node.create_client(srv, f"{node_name}/{service}")
            assert wait_until(ex, c.service_is_ready)
            future = c.call_async(srv.Request(names=names))
            assert wait_until(ex, future.done)
            out[field] = dict(zip(names, getattr(future.result(), field), strict=True))
        return out
    finally:
        ex.shutdown()
        client_node.destroy_node()


def test_descriptors_carry_the_rules_and_the_pace_reads_its_value(ros_context: Any,
                                                                  tmp_path: Path) -> None:
    scene = tmp_path / "paced.yaml"
    scene.write_text("real_time_factor: 2.0\nsystems:\n  - {system: pendulum}\n")
    with process(mechsim_command("run", str(scene)), os.environ):
        got = _describe(ros_context, "/pendulum/simulator",
                        ["mass", "formulation", "method", "publish_rate", "real_time_factor",
                         "initial.angle", "system"])
    d, v = got["descriptors"], got["values"]
    assert d["mass"].additional_constraints == "> 0"
    assert d["formulation"].additional_constraints == ("one of: reduced, multiplier, "
                                                       "polar_multiplier, small_angle, hamiltonian")
    assert d["method"].additional_constraints.startswith("one of: auto, ")
    r = d["publish_rate"].floating_point_range[0]
    assert (r.from_value, r.to_value) == (0.01, 10000.0)
    assert d["initial.angle"].additional_constraints == ">= -3.14159 and <= 3.14159"
    assert "pendulum" in d["system"].additional_constraints and d["system"].read_only
    # The scene runner paces this node at 2x real time: read-only, and its real value.
    assert d["real_time_factor"].read_only and v["real_time_factor"].double_value == 2.0


def test_node_list_hides_hidden_nodes(ros_context: Any) -> None:
    from rclpy.node import Node

    hidden = Node("_hidden_tool", namespace="/elsewhere", context=ros_context)
    shown = Node("visible_tool", namespace="/elsewhere", context=ros_context)
    try:
        def names(*extra: str) -> list[str]:
            out = subprocess.run(mechsim_command("node", "list", "--wait", "3", *extra),
                                 capture_output=True, text=True, timeout=DEADLINE)
            assert out.returncode == 0, out.stderr
            return out.stdout.split()
        plain = names()
        assert "/elsewhere/visible_tool" in plain and "/elsewhere/_hidden_tool" not in plain
        assert "/elsewhere/_hidden_tool" in names("--all")
    finally:
        hidden.destroy_node()
        shown.destroy_node()
