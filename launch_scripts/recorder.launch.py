"""One system by id (default ``pendulum``), recorded: its simulator node, the diagnostics node
and the recorder node, which writes every message to a new bag (and a Rerun recording with
rrd:=FILE) and completes it when the launch ends at the duration or on Ctrl-C.

    ros2 launch mechsim recorder.launch.py [system:=ID] [bag:=DIR] [rrd:=FILE] [duration:=S]

Without a ROS install, the same: ``mechsim run ID --processes --duration S --bag DIR``
(``--rrd FILE``). To record nodes already running instead: ``ros2 run mechsim recorder
--ros-args -p bag:=DIR`` (every mechsim system in the graph).
"""

from mechsim.ros.launch_description import scene_launch_description


def generate_launch_description():  # noqa: ANN201 - the launch system's entry point
    return scene_launch_description(None, recording=True)
