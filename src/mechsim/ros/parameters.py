"""ROS parameters of mechsim's nodes: descriptors made from mechsim's parameter definitions
(``mechsim.params``), so a node advertises and enforces exactly the ranges the CLI and scene
files accept, and the values a node is started with from outside (``--ros-args -p``,
``--params-file``, a launch file's parameters), read as rcl resolved them for its name."""

from __future__ import annotations

from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

from mechsim.params import Parameter

#: Parameters rclpy declares on every node itself (and ``qos_overrides.*``, its QoS overrides).
ROS_OWN = frozenset({"use_sim_time", "start_type_description_service"})


def rule(p: Parameter) -> str:
    """``p``'s range and choices as text (``additional_constraints``): "> 0", ">= 0 and <= 1",
    "one of: a, b"; empty if any value of its type is accepted."""
    if p.choices:
        return f"one of: {', '.join(p.choices)}"
    parts = []
    if p.minimum is not None:
        parts.append(f"{'>' if p.exclusive_minimum else '>='} {p.minimum:g}")
    if p.maximum is not None:
        parts.append(f"{'<' if p.exclusive_maximum else '<='} {p.maximum:g}")
    return " and ".join(parts)


def descriptor(p: Parameter, *, read_only: bool = False,
               description: str | None = None) -> ParameterDescriptor:
    """The descriptor of ``p``: description with unit, its rule (``additional_constraints``:
    the choices, or the bounds and whether each is included: ``> 0``), and its range where
    both bounds are set (ROS ranges are inclusive: an exclusive bound is enforced by the
    node's own check, whose refusal names the rule)."""
    text = (description or p.description) + (f" [{p.unit}]" if p.unit else "")
    d = ParameterDescriptor(description=text, read_only=read_only, additional_constraints=rule(p))
    if p.minimum is not None and p.maximum is not None:
        if p.kind is float:
            d.floating_point_range = [FloatingPointRange(from_value=float(p.minimum),
                                                         to_value=float(p.maximum), step=0.0)]
        elif p.kind is int:
            d.integer_range = [IntegerRange(from_value=int(p.minimum), to_value=int(p.maximum),
                                            step=1)]
    return d


def overrides(node: Any) -> dict[str, Any]:
    """The values ``node`` was given from outside, by name (rcl's parameter overrides for its
    fully qualified name: ``-p``, ``--params-file`` with node names and ``/**`` wildcards).
    rclpy keeps them on the node (``_parameter_overrides``) and applies them only when a
    parameter is declared; reading them first lets a node validate them with its own rules
    and messages, and build its model from them before it declares anything."""
    table = getattr(node, "_parameter_overrides", None) or {}
    return {name: p.value for name, p in table.items()}


def foreign(names: set[str]) -> set[str]:
    """Those of ``names`` that are neither rclpy's own parameters nor its QoS overrides."""
    return {n for n in names if n not in ROS_OWN and not n.startswith("qos_overrides.")}
