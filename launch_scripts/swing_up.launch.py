"""The closed loop of docs/closed_loop.md (share/mechsim/scenes/swing_up.yaml): a pendulum,
the swing-up controller node in its namespace (/pendulum), and the diagnostics node, which
checks the work balance with the controller's work.

    ros2 launch mechsim swing_up.launch.py [rate:=HZ] [duration:=S] [bag:=DIR] [rrd:=FILE]

Without a ROS install, the same scene and controller: ``mechsim run scenes/swing_up.yaml`` and
beside it ``mechsim swing_up_controller --ros-args -r __ns:=/pendulum``.
"""

from mechsim.ros.launch_description import scene_launch_description


def generate_launch_description():  # noqa: ANN201 - the launch system's entry point
    return scene_launch_description("swing_up.yaml", controller="swing_up_controller")
