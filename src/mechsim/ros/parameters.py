"""ROS parameter descriptors made from mechsim's parameter definitions (``mechsim.params``), so a
node advertises and enforces exactly the ranges the CLI and scene files accept."""

from __future__ import annotations

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

from mechsim.params import Parameter


def descriptor(p: Parameter, *, read_only: bool = False,
               description: str | None = None) -> ParameterDescriptor:
    """The descriptor of ``p``: description with unit and choices, and its range where both
    bounds are set (ROS ranges are inclusive; an exclusive bound is still enforced by
    ``p.validate`` in the node's set callback)."""
    text = (description or p.description) + (f" [{p.unit}]" if p.unit else "")
    if p.choices:
        text += f" (one of: {', '.join(p.choices)})"
    d = ParameterDescriptor(description=text, read_only=read_only)
    if p.minimum is not None and p.maximum is not None:
        if p.kind is float:
            d.floating_point_range = [FloatingPointRange(from_value=float(p.minimum),
                                                         to_value=float(p.maximum), step=0.0)]
        elif p.kind is int:
            d.integer_range = [IntegerRange(from_value=int(p.minimum), to_value=int(p.maximum),
                                            step=1)]
    return d
