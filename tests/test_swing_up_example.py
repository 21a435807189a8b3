"""Closing the loop with mechsim: a controller node swings the pendulum up and holds it
inverted. Self-contained, to copy: it needs mechsim installed (its pytest plugin gives the
``ros_context`` and ``mechsim_graph`` fixtures), rclpy, std_msgs and sensor_msgs.

The pendulum's ``angle`` φ is measured from straight down; the controller reads
``/pendulum/state`` (sensor_msgs/JointState) and publishes the torque on ``/pendulum/effort``
(std_msgs/Float64MultiArray, one generalized force per coordinate: N·m for an angle). Each
command is held over the sample period it arrives in, up to the node's ``effort_timeout``.

- Swing-up by energy pumping: with E = ½ m R² φ̇² + m g R (1 − cos φ), a torque u changes it
  at dE/dt = u φ̇, so u = k (E_up − E) φ̇ (saturated) drives E to E_up = 2 m g R, the energy
  of the upright pendulum at rest.
- Near the top, a PD law holds it there: u = −K_p (φ − π) − K_d φ̇ (K_p > m g R).

Run it with ``python -m pytest tests/test_swing_up_example.py``.
"""

from __future__ import annotations

import math
from typing import Any

from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

MASS, LENGTH, GRAVITY = 1.0, 1.0, 9.81


class SwingUpController(Node):
    """Energy pumping far from the top, PD control near it."""

    def __init__(self, context: Any, max_pump_torque: float = 5.0) -> None:
        super().__init__("swing_up_controller", context=context)
        self.max_pump_torque = max_pump_torque
        self.effort = self.create_publisher(Float64MultiArray, "/pendulum/effort", 10)
        self.create_subscription(JointState, "/pendulum/state", self.on_state, 10)

    def torque(self, phi: float, rate: float) -> float:
        m, r, g = MASS, LENGTH, GRAVITY
        error = math.remainder(phi - math.pi, 2 * math.pi)  # from upright, in (−π, π]
        if abs(error) < 0.5 and abs(rate) < 3.0:  # hold: PD about the top
            return -40.0 * m * r * r * error - 8.0 * m * r * r * rate
        energy = 0.5 * m * r * r * rate**2 + m * g * r * (1 - math.cos(phi))
        pump = 2.0 * (2 * m * g * r - energy) * rate
        return max(-self.max_pump_torque, min(self.max_pump_torque, pump))

    def on_state(self, msg: JointState) -> None:
        u = self.torque(msg.position[0], msg.velocity[0])
        self.effort.publish(Float64MultiArray(data=[u]))


def test_swing_up_and_hold(ros_context: Any, mechsim_graph: Any) -> None:
    controller = SwingUpController(ros_context)
    mechsim_graph.add_node(controller)
    mechsim_graph.start("pendulum", mass=MASS, length=LENGTH, gravity=GRAVITY,
                        **{"initial.angle": 0.1})
    energies = mechsim_graph.collect("/pendulum/energy")

    def held_upright(states: list[JointState]) -> bool:
        """The last 100 samples (1 s at 100 Hz) within 0.05 rad of the top."""
        last = states[-100:]
        return len(last) == 100 and all(
            abs(math.remainder(s.position[0] - math.pi, 2 * math.pi)) < 0.05 for s in last)

    states = mechsim_graph.collect("/pendulum/state").wait_for(predicate=held_upright)
    assert max(abs(s.position[0]) for s in states) > 3.0  # it did swing up from 0.1 rad
    # The controller's work is in work_external: the work balance law stays OK (and energy
    # is no longer listed as conserved: the node republished its laws when the torque began).
    mechsim_graph.collect("/pendulum/system_info").wait_for(
        predicate=lambda infos: bool(infos) and list(infos[-1].laws) == ["work_balance"])
    mechsim_graph.assert_laws_ok("pendulum")
    # While held at the top (the same 100 samples), E ≈ 2 m g R. The PD hold acts on samples
    # one period old and, on a loaded machine, on late ones: the pendulum keeps an oscillation
    # inside the 0.05 rad band (seen: 0.04 J above 2 m g R, and 0.17 J, φ̇ ≈ 0.6 rad/s, beside
    # cold compilations). 0.5 J (2.5 % of E) still tells a held pendulum from a swing through
    # the top, which would also leave the band within the second. (Later samples are not
    # checked: a controller starved of CPU long enough can lose the hold.)
    def stamp(msg: Any) -> tuple[int, int]:
        return (msg.header.stamp.sec, msg.header.stamp.nanosec)

    held = {stamp(s) for s in states[-100:]}
    window = [e for e in energies.wait_for(
        predicate=lambda es: held <= {stamp(e) for e in es}) if stamp(e) in held]
    assert len(window) >= 100
    for e in window:
        assert abs(e.total - 2 * MASS * GRAVITY * LENGTH) < 0.5, (stamp(e), e.total)
