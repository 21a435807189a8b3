"""The live graph for users without a ROS install: nodes, their parameters and services, shaped
like ``ros2 node list``, ``ros2 param list|get|set`` and ``ros2 service call``.

Every call goes through the standard ROS interfaces any ROS tool uses (``rcl_interfaces``
parameter services, ``std_srvs`` services), from a short-lived node of this process that joins
the graph with the project's loopback DDS profile. Waits are bounded by ``timeout`` seconds; a
node or service that does not answer is one :class:`MechsimError` naming it.
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass
from typing import Any

from mechsim.errors import MechsimError, ParameterError
from mechsim.ros.topic_tools import graph_node

#: Services a mechsim simulator node offers, with their type and request field.
SERVICES = {"reset": ("std_srvs/srv/Trigger", None), "pause": ("std_srvs/srv/SetBool", "data"),
            "step": ("mechsim_msgs/srv/Step", "samples")}


def full_name(name: str) -> str:
    """'/pendulum/simulator' for 'pendulum/simulator' or '/pendulum/simulator'."""
    if not name or name != name.strip() or any(ord(c) < 32 for c in name):
        raise ParameterError("node", f"invalid node name {name!r}")
    return name if name.startswith("/") else "/" + name


def _join(namespace: str, name: str) -> str:
    return f"{namespace.rstrip('/')}/{name}" if namespace != "/" else f"/{name}"


def _discover(node: Any, ex: Any, until: Any, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if until():
            return True
        ex.spin_once(timeout_sec=0.05)
    return bool(until())


def hidden(name: str) -> bool:
    """A hidden node: one whose name, or a namespace of which, starts with "_" (as ``ros2
    node list`` hides the ``/_ros2cli_...`` nodes of the ros2 command itself)."""
    return any(part.startswith("_") for part in name.split("/"))


def node_names(wait: float = 1.0, *, all_nodes: bool = False) -> list[str]:
    """Fully qualified names of the graph's nodes, this tool's own node left out, and the
    hidden ones too unless ``all_nodes``."""
    with graph_node("node_list") as (node, ex):
        _discover(node, ex, lambda: False, wait)
        own = _join(node.get_namespace(), node.get_name())
        names = {_join(ns, n) for n, ns in node.get_node_names_and_namespaces()}
    return sorted(n for n in names - {own} if all_nodes or not hidden(n))


def _client(node: Any, ex: Any, srv_type: Any, service: str, timeout: float) -> Any:
    client = node.create_client(srv_type, service)
    if not _discover(node, ex, client.service_is_ready, timeout):
        raise MechsimError(f"{service}: no such service in the graph (waited {timeout:g} s; "
                           "`mechsim node list` shows the running nodes)")
    return client


def _call(ex: Any, client: Any, request: Any, timeout: float, what: str) -> Any:
    future = client.call_async(request)
    end = time.monotonic() + timeout
    while not future.done() and time.monotonic() < end:
        ex.spin_once(timeout_sec=0.05)
    if not future.done():
        raise MechsimError(f"{what}: no answer within {timeout:g} s")
    return future.result()


@dataclass(frozen=True)
class ParameterInfo:
    name: str
    value: Any
    description: str
    read_only: bool


def _from_value(v: Any) -> Any:
    from rcl_interfaces.msg import ParameterType as T

    return {T.PARAMETER_BOOL: lambda: v.bool_value, T.PARAMETER_INTEGER: lambda: v.integer_value,
            T.PARAMETER_DOUBLE: lambda: v.double_value,
            T.PARAMETER_STRING: lambda: v.string_value,
            T.PARAMETER_BYTE_ARRAY: lambda: list(v.byte_array_value),
            T.PARAMETER_BOOL_ARRAY: lambda: list(v.bool_array_value),
            T.PARAMETER_INTEGER_ARRAY: lambda: list(v.integer_array_value),
            T.PARAMETER_DOUBLE_ARRAY: lambda: list(v.double_array_value),
            T.PARAMETER_STRING_ARRAY: lambda: list(v.string_array_value),
            }.get(v.type, lambda: None)()


def list_parameters(node_name: str, timeout: float = 5.0) -> list[ParameterInfo]:
    """Every parameter of ``node_name`` with its value and descriptor."""
    from rcl_interfaces.srv import DescribeParameters, GetParameters, ListParameters

    target = full_name(node_name)
    with graph_node("param_client") as (node, ex):
        c = _client(node, ex, ListParameters, f"{target}/list_parameters", timeout)
        names = sorted(_call(ex, c, ListParameters.Request(), timeout,
                             f"{target}/list_parameters").result.names)
        g = _client(node, ex, GetParameters, f"{target}/get_parameters", timeout)
        values = _call(ex, g, GetParameters.Request(names=names), timeout,
                       f"{target}/get_parameters").values
        d = _client(node, ex, DescribeParameters, f"{target}/describe_parameters", timeout)
        descs = _call(ex, d, DescribeParameters.Request(names=names), timeout,
                      f"{target}/describe_parameters").descriptors
    return [ParameterInfo(n, _from_value(v), ds.description, ds.read_only)
            for n, v, ds in zip(names, values, descs, strict=True)]


def _current(node: Any, ex: Any, target: str, name: str, timeout: float) -> Any:
    """The ParameterValue of ``name`` on node ``target``; ParameterError if it has none."""
    from rcl_interfaces.msg import ParameterType
    from rcl_interfaces.srv import GetParameters

    g = _client(node, ex, GetParameters, f"{target}/get_parameters", timeout)
    values = _call(ex, g, GetParameters.Request(names=[name]), timeout,
                   f"{target}/get_parameters").values
    if not values or values[0].type == ParameterType.PARAMETER_NOT_SET:
        from rcl_interfaces.srv import ListParameters

        from mechsim.errors import did_you_mean

        c = _client(node, ex, ListParameters, f"{target}/list_parameters", timeout)
        names = _call(ex, c, ListParameters.Request(), timeout,
                      f"{target}/list_parameters").result.names
        raise ParameterError(name, f"not a parameter of {target}"
                             + did_you_mean(name, names, "parameters"))
    return values[0]


def get_parameter(node_name: str, name: str, timeout: float = 5.0) -> Any:
    target = full_name(node_name)
    with graph_node("param_client") as (node, ex):
        return _from_value(_current(node, ex, target, name, timeout))


def _to_value(raw: str, current: Any) -> Any:
    """The YAML value of ``raw``, converted to the parameter's current type where that is
    loss-free (``1`` for a double parameter is 1.0), as ``ros2 param set`` does."""
    import yaml
    from rcl_interfaces.msg import ParameterType as T
    from rcl_interfaces.msg import ParameterValue

    if len(raw) > 10_000:
        raise ParameterError("value", "longer than 10000 characters")
    try:
        value = yaml.safe_load(raw)
    except yaml.YAMLError:
        value = raw
    out = ParameterValue()
    if current.type == T.PARAMETER_DOUBLE and isinstance(value, str) \
            and re.fullmatch(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+", value):
        value = float(value)  # 1e-10: a number YAML 1.1 reads as text
    if current.type == T.PARAMETER_DOUBLE and isinstance(value, int) \
            and not isinstance(value, bool):
        if abs(value) > 2 ** 53:
            raise ParameterError("value", f"integer too large for a double ({len(raw)} digits)")
        value = float(value)
    if isinstance(value, bool):
        out.type, out.bool_value = T.PARAMETER_BOOL, value
    elif isinstance(value, int):
        if not -2 ** 63 <= value < 2 ** 63:
            raise ParameterError("value", "integer out of the 64-bit range")
        out.type, out.integer_value = T.PARAMETER_INTEGER, value
    elif isinstance(value, float):
        if not math.isfinite(value):
            raise ParameterError("value", f"must be finite (got {raw})")
        out.type, out.double_value = T.PARAMETER_DOUBLE, value
    elif isinstance(value, str):
        out.type, out.string_value = T.PARAMETER_STRING, value
    else:
        raise ParameterError("value", f"a number, boolean or string is expected (got {raw!r})")
    return out


def set_parameter(node_name: str, name: str, raw: str, timeout: float = 5.0) -> Any:
    """Set one parameter; returns the value now in force. A rejected set raises
    ParameterError with the node's reason."""
    from rcl_interfaces.msg import Parameter
    from rcl_interfaces.srv import SetParameters

    target = full_name(node_name)
    with graph_node("param_client") as (node, ex):
        value = _to_value(raw, _current(node, ex, target, name, timeout))
        s = _client(node, ex, SetParameters, f"{target}/set_parameters", timeout)
        result = _call(ex, s, SetParameters.Request(parameters=[Parameter(name=name,
                                                                          value=value)]),
                       timeout, f"{target}/set_parameters").results[0]
    if not result.successful:
        reason = result.reason or "rejected by the node"
        raise ParameterError(name, reason.removeprefix(f"{name}: "))
    return _from_value(value)


def _request(service: str, arg: str | None) -> tuple[Any, Any]:
    """(service type, request) of ``service`` (one of ``SERVICES``) with its argument."""
    from std_srvs.srv import SetBool, Trigger

    from mechsim_msgs.srv import Step

    if service not in SERVICES:
        raise ParameterError("service", f"must be one of {', '.join(SERVICES)} (got "
                             f"{service!r})")
    if service == "reset":
        if arg is not None:
            raise ParameterError("value", "reset takes no value")
        return Trigger, Trigger.Request()
    if service == "step":
        if arg is None or not arg.isdigit() or not 0 < int(arg) < 2**32:
            raise ParameterError("value", "step takes a number of samples, 1 or more")
        return Step, Step.Request(samples=int(arg))
    flags = {"true": True, "false": False, "on": True, "off": False, "1": True, "0": False}
    if arg is None or arg.lower() not in flags:
        raise ParameterError("value", "pause takes true or false")
    return SetBool, SetBool.Request(data=flags[arg.lower()])


def call_service(node_name: str, service: str, arg: str | None = None,
                 timeout: float = 5.0) -> tuple[bool, str]:
    """Call ``<node>/<service>`` (``reset``, ``pause`` or ``step``); returns (success,
    message)."""
    srv_type, request = _request(service, arg)
    target = f"{full_name(node_name)}/{service}"
    with graph_node("service_client") as (node, ex):
        c = _client(node, ex, srv_type, target, timeout)
        response = _call(ex, c, request, timeout, target)
    return bool(response.success), str(response.message)
