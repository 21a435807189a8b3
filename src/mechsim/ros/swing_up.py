"""The swing-up controller node of docs/closed_loop.md, as a node executable
(``ros2 run mechsim swing_up_controller --ros-args -r __ns:=/pendulum``): it swings a
pendulum (system ``pendulum``, reduced formulation: one coordinate ``angle`` φ, from straight
down) up from rest and holds it inverted, through the simulator's effort input.

Physics (docs/closed_loop.md, "Worked example: swing-up and hold"): with
E = ½ m R² φ̇² + m g R (1 − cos φ), a generalized force u on φ changes the energy at
dE/dt = u φ̇, so pumping u = k (E_up − E) φ̇, saturated at ``max_torque``, drives E to
E_up = 2 m g R (upright, at rest); within ``hold_angle`` of the top and slower than
``hold_rate``, a PD law u = −K_p m R² (φ − π) − K_d m R² φ̇ holds it there (K_p > g/R).
m, R and g are the simulated pendulum's own: read from its ``system_info``, never repeated.

Topics (relative, in the node's namespace): ``state`` (sensor_msgs/JointState) and
``system_info`` in, ``effort`` (std_msgs/Float64MultiArray) out: one command per state.
"""

from __future__ import annotations

import math
from typing import Any

import yaml
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from mechsim.ros.outlet import LATCHED_QOS, STATE_QOS
from mechsim_msgs.msg import SystemInfo

#: The gains (ROS parameters, with their defaults and meaning).
GAINS = {
    "pump_gain": (2.0, "energy pumping gain k [1/(J·s)]"),
    "max_torque": (5.0, "largest pumping torque [N·m]"),
    "hold_kp": (40.0, "PD stiffness near the top, per m R² [1/s²]"),
    "hold_kd": (8.0, "PD damping near the top, per m R² [1/s]"),
    "hold_angle": (0.5, "angle from the top within which the PD law holds [rad]"),
    "hold_rate": (3.0, "rate below which the PD law holds [rad/s]"),
}


def swing_up_torque(phi: float, rate: float, mass: float, length: float, gravity: float,
                    gains: dict[str, float]) -> float:
    """The torque on φ (N·m) for angle ``phi`` (rad, 0 straight down) and ``rate`` (rad/s)."""
    inertia = mass * length * length
    error = math.remainder(phi - math.pi, 2 * math.pi)  # from the top, in (−π, π]
    if abs(error) < gains["hold_angle"] and abs(rate) < gains["hold_rate"]:
        return -inertia * (gains["hold_kp"] * error + gains["hold_kd"] * rate)
    energy = 0.5 * inertia * rate * rate + mass * gravity * length * (1 - math.cos(phi))
    pump = gains["pump_gain"] * (2 * mass * gravity * length - energy) * rate
    return max(-gains["max_torque"], min(gains["max_torque"], pump))


class SwingUpController(Node):
    """Answers every state of its namespace's pendulum with a torque (see the module)."""

    def __init__(self, *, context: Any = None, namespace: str = "pendulum") -> None:
        super().__init__("swing_up_controller", namespace=namespace, context=context)
        for name, (default, text) in GAINS.items():
            self.declare_parameter(name, default, ParameterDescriptor(
                description=text, additional_constraints="> 0"))
        self.pendulum: tuple[float, float, float] | None = None  # m, R, g
        self.effort = self.create_publisher(Float64MultiArray, "effort", STATE_QOS)
        self.create_subscription(SystemInfo, "system_info", self._on_info, LATCHED_QOS)
        self.create_subscription(JointState, "state", self._on_state, STATE_QOS)
        self.commands = 0

    def _on_info(self, info: SystemInfo) -> None:
        values = yaml.safe_load(info.parameters_yaml) or {}
        if info.system != "pendulum" or list(info.coordinates) != ["angle"]:
            self.pendulum = None
            self.get_logger().error(f"{info.instance}: not a pendulum in its reduced "
                                    f"formulation ({info.system}, {info.formulation}): idle")
            return
        self.pendulum = (float(values["mass"]), float(values["length"]),
                         float(values["gravity"]))

    def _on_state(self, msg: JointState) -> None:
        if self.pendulum is None or not msg.position or not msg.velocity:
            return
        gains = {name: float(self.get_parameter(name).value) for name in GAINS}
        u = swing_up_torque(msg.position[0], msg.velocity[0], *self.pendulum, gains)
        self.effort.publish(Float64MultiArray(data=[u]))
        self.commands += 1


def controller_alone() -> int:
    """The controller node until a stop (status 0)."""
    from rclpy.executors import SingleThreadedExecutor

    from mechsim.ros.graph_check import start_context
    from mechsim.runcore.stops import stopping

    context = start_context()
    executor = SingleThreadedExecutor(context=context)
    node = None
    try:
        node = SwingUpController(context=context)
        executor.add_node(node)
        while not stopping.is_set():
            executor.spin_once(timeout_sec=0.1)
    except KeyboardInterrupt:
        pass
    finally:
        executor.shutdown()
        if node is not None:
            node.destroy_node()
        context.try_shutdown()
    return 0
