"""The node executables started alone (``ros2 run mechsim NAME``, a launch file's ``Node``
action, ``mechsim NAME`` without ``--scene``): each one node, configured entirely by its ROS
parameters and remaps, as turtlesim is.

- ``simulator``: the system named by its ``system`` parameter (default ``pendulum``), every
  model and run parameter from its parameters (``simulator_parameters``), in its namespace
  (``-r __ns:=/demo``; default: the system id), paced in real time (``real_time_factor``)
  until its ``duration`` (0: until stopped). A given value that is no parameter of it is
  refused, with the closest name.
- ``diagnostics``: checks every system it discovers (``ros/diagnostics.py``).
- ``recorder``: records the topics of every mechsim system in the graph (or of the
  instances of its ``scene`` parameter) to its ``bag`` and/or ``rrd`` parameters.

A stop (SIGINT, as launch sends, or SIGTERM) ends them cleanly with status 0; a system that
failed ends its simulator with 1; a refused start (a bad parameter, a name already running) is
one error line and 2.
"""

from __future__ import annotations

import difflib
from typing import Any

from mechsim.errors import ParameterError, UnknownSystemError
from mechsim.ros.graph_check import GraphCheck, discovery_window, start_context
from mechsim.ros.parameters import overrides
from mechsim.ros.process import end_node_process
from mechsim.runcore.stops import stopping

#: The system of a simulator started without a ``system`` parameter.
DEFAULT_SYSTEM = "pendulum"


def given_values(context: Any, name: str) -> tuple[dict[str, Any], str, str, Any]:
    """(the values given to a node called ``name``, its namespace, its name), both as
    remapped, and the probe they were read from: a node of that name that offers nothing to
    the graph (what a node must know before it is made, e.g. which system it runs). The caller
    destroys the probe once its next node of ``context`` exists, never before: the context's
    DDS participant ends with its last node (``graph_check``: one participant a process)."""
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    probe = Node(name, context=context, enable_rosout=False, start_parameter_services=False,
                 parameter_overrides=[Parameter("start_type_description_service", value=False)])
    values = overrides(probe)  # (raising, it leaves the probe to the context's shutdown)
    values.pop("start_type_description_service", None)
    return values, probe.get_namespace(), probe.get_name(), probe


def _system(values: dict[str, Any]) -> str:
    from mechsim.systems import system_ids

    system = values.get("system", DEFAULT_SYSTEM)
    if not isinstance(system, str):
        raise ParameterError("system", f"must be a system id (see `mechsim systems`), got "
                             f"{system!r}")
    if system not in system_ids():
        raise UnknownSystemError(system, system_ids())
    return system


def _refuse_unknown(node: Any) -> None:
    """A given value that is no parameter of ``node`` (a typo would silently do nothing)."""
    unused = sorted(node.start.unused)
    if not unused:
        return
    known = [n for n, _ in node.get_parameters_by_prefix("").items()]
    close = difflib.get_close_matches(unused[0], known, n=1)
    hint = f" (did you mean {close[0]}?)" if close else ""
    raise ParameterError(unused[0], f"not a parameter of {node.get_fully_qualified_name()}"
                         f"{hint}")


def _recorder_listens(node: Any) -> None:
    """Before the first sample: wait (at most ``CONSUMER_WAIT``) until a recorder subscribes
    to every topic of ``node`` that it records (a launch file starts both at once)."""
    import time

    from mechsim.outputs.batch import recorder_subscribed
    from mechsim.ros.processes import CONSUMER_WAIT

    end = time.monotonic() + CONSUMER_WAIT
    channels = node.outlet.channels
    while time.monotonic() < end:
        if recorder_subscribed({t: ch.publisher.get_subscription_count()
                                for t, ch in channels.items()}):
            return
        time.sleep(0.05)
    node.get_logger().warning(f"no recorder subscribed to every topic within "
                              f"{CONSUMER_WAIT:g} s; starting anyway")


def simulator_alone() -> int:
    """The simulator node of the system its parameters name, until its duration or a stop."""
    from rclpy.executors import SingleThreadedExecutor

    from mechsim.ros.outlet import wait_acked
    from mechsim.ros.simulator import NODE_NAME, SimulatorNode
    from mechsim.scene import Instance

    window = discovery_window()
    context = start_context()
    node = None
    executor = SingleThreadedExecutor(context=context)
    try:
        values, namespace, name, probe = given_values(context, NODE_NAME)
        system = _system(values)
        namespace = namespace if namespace != "/" else f"/{system}"
        clock = values.get("publish_clock", True) is True
        wait = values.get("wait_for_recorder", False) is True
        # Made before the probe goes (one participant), begun once the graph check passed.
        node = SimulatorNode(Instance(system, namespace.strip("/").split("/")[-1]),
                             context=context, publish_clock=clock, stepped=False,
                             node_name=name, deferred=True,
                             before_first_message=_recorder_listens if wait else None)
        probe.destroy_node()
        _refuse_unknown(node)
        if window > 0:
            graph = GraphCheck(context)
            try:
                graph.check([f"{namespace}/{name}"], clock, window, own=[node])
            finally:
                graph.close()
        node.begin()
        executor.add_node(node)
        while not node.finished and not stopping.is_set():
            executor.spin_once(timeout_sec=0.1)
    except KeyboardInterrupt:
        pass
    finally:
        if node is not None:
            try:
                wait_acked([ch.publisher for ch in node.outlet.channels.values()])
            except KeyboardInterrupt:
                pass
        failed = node is not None and node.failed
        end_node_process("the simulator's teardown", lambda: 1 if failed else 0, executor,
                         node, context)  # (and the probe, if a failed start left it)
    return 1 if failed else 0


def recorder_alone(report: str | None = None) -> int:
    """The recorder node: the graph's mechsim systems (or its ``scene``'s) into its ``bag``
    (default ``runs/<scene>_<time>``) and/or ``rrd``, until a stop."""
    from mechsim.ros.record import DEFAULT_BAG
    from mechsim.ros.recorder import NODE_NAME, run_recorder
    from mechsim.scene import Scene, load_scene

    context = start_context()
    try:
        values, _, _, probe = given_values(context, NODE_NAME)
        for key in ("scene", "bag", "rrd"):
            if not isinstance(values.get(key, ""), str):
                raise ParameterError(key, "must be a string (a path; empty: none)")
        scene_file = values.get("scene", "")
        scene = load_scene(scene_file) if scene_file else Scene(name="graph", systems=[])
        bag = values.get("bag", DEFAULT_BAG) or None
        rrd = values.get("rrd", "") or None
        if bag is None and rrd is None:
            raise ParameterError("bag", "empty, and no rrd: nothing to record to")
        run_recorder(scene, bag, rrd, report, context=context, probe=probe)
    except BaseException:
        context.try_shutdown()  # (with its nodes: the probe, if the recorder's never came)
        raise
    return 0
