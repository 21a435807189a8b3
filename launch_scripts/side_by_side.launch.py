"""Two instances of one system side by side (share/mechsim/scenes/side_by_side.yaml): the
same pendulum from a small and from a large angle, in namespaces /small_swing and
/large_swing, with the diagnostics node.

    ros2 launch mechsim side_by_side.launch.py [rate:=HZ] [duration:=S] [bag:=DIR] [rrd:=FILE]

Without a ROS install, the same scene: ``mechsim run scenes/side_by_side.yaml --processes``.
"""

from mechsim.ros.launch_description import scene_launch_description


def generate_launch_description():  # noqa: ANN201 - the launch system's entry point
    return scene_launch_description("side_by_side.yaml")
