"""The default scene (share/mechsim/scenes/default.yaml): a pendulum, a driven oscillator and a
Kepler orbit, paced in real time for 10 s, checked by the diagnostics node, recorded to a bag
and a Rerun recording under runs/ by the recorder node.

    ros2 launch mechsim default.launch.py [rate:=HZ] [duration:=S] [bag:=DIR|none] [rrd:=FILE|none]

Without a ROS install, the same scene: ``mechsim run scenes/default.yaml --processes``.
"""

from mechsim.ros.launch_description import scene_launch_description


def generate_launch_description():  # noqa: ANN201 - the launch system's entry point
    return scene_launch_description("default.yaml")
