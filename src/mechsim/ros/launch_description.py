"""Launch descriptions of scenes: what the launch files in ``launch_scripts/`` (installed to
``share/mechsim/launch``) return, for ``ros2 launch mechsim FILE.launch.py``.

A launch file names a scene file (installed under ``share/mechsim/scenes``, the file
``mechsim run`` reads) and this module makes its nodes, so the two can never describe one scene
differently: one ``simulator`` node executable per instance (namespace = instance name), every
parameter from the scene as parsed and validated by mechsim (``scene.load_scene``: system,
model parameters, method, tolerance, origin, rate, pacing, duration; the first instance
publishes /clock), one ``diagnostics`` node with the scene's thresholds, a ``recorder`` node
where the scene (or the ``bag``/``rrd`` arguments) names an output, and optionally a controller
node executable per instance. The simulators start paced in real time and stop at the
duration; once all of them have, the launch shuts down (the recorder completes its outputs).

Launch arguments (``ros2 launch mechsim FILE.launch.py --show-args``): ``rate`` (Hz of
simulation time), ``duration`` (simulated seconds, 0: until Ctrl-C), ``bag`` (a new bag
directory, ``none``: no bag), ``rrd`` (a Rerun recording, ``none``: none), and, for a launch
file of one system by id, ``system``: defaults from the scene. This module imports ``launch``
and ``launch_ros``: a launch file's dependencies, never mechsim's.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from mechsim.errors import ParameterError
from mechsim.scene import Scene, load_scene, single_system_scene

#: "no output" for the bag and rrd arguments.
NONE = "none"
#: Simulated seconds of a recording launch whose scene sets no duration.
RECORDING_DURATION = 10.0


def scene_path(name: str) -> Path:
    """A scene file of the installed package (``share/mechsim/scenes/NAME``)."""
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory("mechsim")) / "scenes" / name


def _scene(scene_file: str | None, arguments: dict[str, str]) -> Scene:
    """The scene with the launch arguments applied (as ``mechsim run`` applies its options)."""
    from mechsim.params import DURATION, PUBLISH_RATE

    scene = single_system_scene(arguments["system"]) if scene_file is None \
        else load_scene(scene_path(scene_file))
    if scene.pacing == "fast":
        raise ParameterError("pacing", f"scene {scene.name!r} runs as fast as possible: "
                             "launched simulators pace themselves (run it with mechsim run)")
    if arguments.get("rate"):
        scene.publish_rate = float(PUBLISH_RATE.check(arguments["rate"], "rate"))
    if arguments.get("duration"):
        duration = float(arguments["duration"])
        scene.duration = None if duration == 0 else float(DURATION.check(duration,
                                                                           "duration"))
    for key in ("bag", "rrd"):
        value = arguments.get(key, "")
        if value:
            setattr(scene, key, None if value == NONE else value)
    return scene


def simulator_parameters(scene: Scene, index: int) -> dict[str, Any]:
    """The ROS parameters of instance ``index``'s simulator node: everything it runs."""
    inst = scene.systems[index]
    return {"system": inst.system, **inst.build().values, "method": inst.method,
            "tolerance": float(inst.tolerance), "publish_rate": float(scene.publish_rate),
            "real_time_factor": float(scene.real_time_factor),
            "duration": float(scene.duration or 0.0),
            "origin": [float(c) for c in inst.origin], "publish_clock": index == 0,
            "wait_for_recorder": scene.bag is not None or scene.rrd is not None}


def nodes(scene: Scene, controller: str | None = None) -> list[Any]:
    """The launch actions of ``scene``'s nodes, and the shutdown once every simulator ended."""
    from launch.actions import EmitEvent, RegisterEventHandler
    from launch.event_handlers import OnProcessExit
    from launch.events import Shutdown
    from launch_ros.actions import Node

    sims = [Node(package="mechsim", executable="simulator", name="simulator",
                 namespace=inst.name, parameters=[simulator_parameters(scene, i)],
                 output="screen")
            for i, inst in enumerate(scene.systems)]
    actions: list[Any] = [*sims, Node(
        package="mechsim", executable="diagnostics", output="screen",
        parameters=[{"warn_drift": scene.warn_drift, "error_drift": scene.error_drift}])]
    if controller is not None:
        actions += [Node(package="mechsim", executable=controller, namespace=inst.name,
                         output="screen") for inst in scene.systems]
    if scene.bag is not None or scene.rrd is not None:
        source = "" if scene.source is None else str(scene.source)
        actions.append(Node(package="mechsim", executable="recorder", output="screen",
                            parameters=[{"scene": source, "bag": scene.bag or "",
                                         "rrd": scene.rrd or ""}]))
    ended: set[int] = set()

    def on_exit(event: Any, context: Any) -> list[Any]:
        ended.add(event.pid)
        return [EmitEvent(event=Shutdown(reason="every simulator ended"))] \
            if len(ended) == len(sims) else []

    actions += [RegisterEventHandler(OnProcessExit(target_action=sim, on_exit=on_exit))
                for sim in sims]
    return actions


def scene_launch_description(scene_file: str | None, *, controller: str | None = None,
                             recording: bool = False) -> Any:
    """The launch description of the installed scene ``scene_file`` (None: one system by id,
    the ``system`` argument), with its launch arguments (see the module docstring);
    ``controller``: a node executable started in each instance's namespace; ``recording``:
    a bag by default (``runs/<scene>_<time>``), for ``RECORDING_DURATION`` s unless the scene
    says."""
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction

    from mechsim.ros.record import DEFAULT_BAG

    base = single_system_scene("pendulum") if scene_file is None \
        else load_scene(scene_path(scene_file))
    if recording:
        base.bag = base.bag or DEFAULT_BAG
        base.duration = base.duration or RECORDING_DURATION
    declared = [
        DeclareLaunchArgument("rate", default_value=f"{base.publish_rate:g}",
                              description="samples per second of simulation time [Hz]"),
        DeclareLaunchArgument("duration", default_value=f"{base.duration or 0:g}",
                              description="simulated seconds (0: until Ctrl-C)"),
        DeclareLaunchArgument("bag", default_value=base.bag or NONE,
                              description=f"new bag directory ({NONE}: no bag)"),
        DeclareLaunchArgument("rrd", default_value=base.rrd or NONE,
                              description=f"Rerun recording ({NONE}: none)")]
    if scene_file is None:
        from mechsim.systems import system_ids

        declared.insert(0, DeclareLaunchArgument(
            "system", default_value="pendulum", choices=list(system_ids()),
            description="system id (`mechsim systems`)"))

    def build(context: Any) -> list[Any]:
        arguments = {k: str(v) for k, v in context.launch_configurations.items()}
        return nodes(_scene(scene_file, arguments), controller)

    return LaunchDescription([*declared, OpaqueFunction(function=build)])
