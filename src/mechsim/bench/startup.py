"""Start-up of scenes of many instances (part of ``mechsim bench --streaming``).

1. A scene of N pendulums (N = 1 ... 100) run in one process: seconds from the call to the first
   sample (``SceneRun.startup_time``: the graph check's discovery window, the nodes with
   their parameters, services, publishers and subscriptions made meanwhile, the models), warm
   kernels; for the largest N the design variants beside it, each started ``REPEAT`` times in
   turn and the median kept: the window elapsing before the first node is made, no graph
   check, each node's parameter services made with it (before the first sample), and the
   nodes without rclpy's type-description service; and where the time goes (a
   profile of the start: the seconds inside rclpy's calls that make endpoints and nodes).
2. The same endpoints made by bare rclpy, to tell the design's share from the middleware's:
   N nodes as a simulator node makes them (its services, the parameter and type-description
   services rclpy adds, its publishers and subscription) in one process; the same without
   the services rclpy adds; one node carrying every instance's publishers and services; and
   N nodes split over several processes started together (each a DDS participant of its own:
   every new endpoint is matched against the participant's others, so the cost of a
   process's endpoints grows with their square).
3. The scene itself split the same way: several processes, each running its share of the
   instances with ``run_scene``, started together; seconds from their launch to the last
   one's first sample (Python and rclpy start-up included). And ``mechsim run --processes``
   (one process per node, graph check included) of a scene of ``PROCESSES_MODE`` pendulums:
   seconds from the call to the last process ended, and the slowest process's own start-up.
"""

from __future__ import annotations

import cProfile
import json
import os
import pstats
import statistics
import subprocess
import sys
import time
from typing import Any

#: Scene sizes measured in one process.
SIZES = (1, 10, 25, 50, 100)
#: Processes the largest scene is split over.
SPLIT = 4
#: Instances of the scene run with one process per node (each process imports Python, rclpy
#: and the models, and joins the graph on its own).
PROCESSES_MODE = 25
#: Starts of each design variant of the largest scene (the median is reported).
REPEAT = 3
#: The design variants of the largest scene (name -> what differs from ``mechsim run``).
VARIANTS = {"overlapped": "as `mechsim run` starts it: the nodes made during the window, "
                          "their parameter services once the samples flow",
            "window_first": "the window elapsing before the first node is made",
            "no_graph_check": "no graph check",
            "parameter_services_first": "each node's parameter services made with it, before "
                                        "the first sample (not once the samples flow)",
            "no_type_description": "the nodes without rclpy's type-description service"}
#: rclpy's calls whose time the profile reports (function name -> label).
PROFILED = {"create_service": "create_service", "create_publisher": "create_publisher",
            "create_subscription": "create_subscription", "declare_parameters":
            "declare_parameters", "check": "graph check (its window left once the nodes are made)"}


def pendulums(n: int, prefix: str = "p") -> Any:
    from mechsim.scene import parse_scene

    return parse_scene({"name": f"{prefix}{n}", "pacing": "fast", "publish_rate": 100.0,
                        "systems": [{"system": "pendulum", "name": f"{prefix}{i}",
                                     "origin": [float(i), 0.0, 0.0]} for i in range(n)]})


def scene_startup(n: int, graph_wait: float | None = None, profile: bool = False,
                  variant: str = "overlapped") -> dict[str, Any]:
    """Start-up of a scene of ``n`` pendulums in this process (own context: the command's
    path, graph check included unless ``graph_wait`` is 0; ``variant``: one of
    ``VARIANTS``)."""
    from mechsim.ros.graph_check import ros_arguments, use_ros_arguments
    from mechsim.ros.launch import _SceneLoop, run_scene

    prof = cProfile.Profile() if profile else None
    given = ros_arguments()
    if variant == "no_graph_check":
        graph_wait = 0
    elif variant == "window_first":
        _SceneLoop.overlap_window = False
    elif variant == "parameter_services_first":
        _SceneLoop.parameter_services_later = False
    elif variant == "no_type_description":
        use_ros_arguments(["--ros-args", "-p", "start_type_description_service:=false"])
    if prof:
        prof.enable()
    try:
        run = run_scene(pendulums(n), fast=True, duration=0.02, graph_wait=graph_wait)
    finally:
        _SceneLoop.overlap_window = True
        _SceneLoop.parameter_services_later = True
        use_ros_arguments(given)
    row: dict[str, Any] = {"instances": n, "startup_s": run.startup_time,
                           "parameters_served_s": run.parameters_served_time,
                           "graph_check": graph_wait != 0, "variant": variant}
    if prof:
        prof.disable()
        stats = pstats.Stats(prof).stats  # type: ignore[attr-defined]
        spent: dict[str, float] = {}
        for (filename, _, name), (_, _, _, cumulative, _) in stats.items():
            label = PROFILED.get(name)
            if label and (("rclpy" in filename and name != "check")
                          or (name == "check" and "graph_check" in filename)):
                spent[label] = spent.get(label, 0.0) + cumulative
            if name == "__init__" and filename.endswith(os.path.join("rclpy", "node.py")):
                spent["rclpy Node() (its parameter and type-description services)"] = cumulative
        row["profile_s"] = spent
    return row


#: Bare rclpy: N nodes with the endpoints of a simulator node (``variant``: "node" as
#: mechsim makes them; "no_type_description": without rclpy's type-description service;
#: "no_rclpy_services": without the parameter and type-description services; "one_node": one
#: node carrying them all). Prints the seconds taken as JSON.
_BARE = """
import json, sys, time
from mechsim.environment import import_rclpy
rclpy = import_rclpy()
from rclpy.parameter import Parameter
from std_srvs.srv import SetBool, Trigger
from std_msgs.msg import Float64MultiArray
from sensor_msgs.msg import JointState
n, variant, publishers = int(sys.argv[1]), sys.argv[2], int(sys.argv[3])
rclpy.init()
t0 = time.monotonic()
nodes = []
def node(i):
    if variant == "no_rclpy_services":
        return rclpy.create_node(f"simulator", namespace=f"/b{i}", start_parameter_services=False,
            parameter_overrides=[Parameter("start_type_description_service", value=False)])
    if variant == "no_type_description":
        return rclpy.create_node(f"simulator", namespace=f"/b{i}",
            parameter_overrides=[Parameter("start_type_description_service", value=False)])
    return rclpy.create_node("simulator", namespace=f"/b{i}")
one = node(0) if variant == "one_node" else None
for i in range(n):
    nd = one if one is not None else node(i)
    nodes.append(nd)
    for k in range(publishers):
        nd.create_publisher(JointState, f"/b{i}/topic{k}", 10)
    nd.create_subscription(Float64MultiArray, f"/b{i}/effort", lambda m: None, 10)
    for name in ("reset", "step"):
        nd.create_service(Trigger, f"/b{i}/simulator/{name}", lambda q, r: r)
    nd.create_service(SetBool, f"/b{i}/simulator/pause", lambda q, r: r)
print(json.dumps({"seconds": time.monotonic() - t0, "ready": time.monotonic()}), flush=True)
"""


def _bare(n: int, variant: str, publishers: int) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-c", _BARE, str(n), variant, str(publishers)],
                            stdout=subprocess.PIPE, text=True)


def _answer(proc: subprocess.Popen[str]) -> dict[str, Any]:
    out, _ = proc.communicate(timeout=600)
    if proc.returncode != 0:
        raise RuntimeError(f"a start-up probe failed (exit {proc.returncode})")
    return dict(json.loads(out.strip().splitlines()[-1]))


def bare_endpoints(n: int, publishers: int) -> list[dict[str, Any]]:
    """Seconds to make ``n`` nodes' endpoints with bare rclpy, per variant (see ``_BARE``),
    and split over ``SPLIT`` processes started together (launch to the last one ready)."""
    rows = []
    for variant in ("node", "no_type_description", "no_rclpy_services", "one_node"):
        rows.append({"variant": variant, "processes": 1,
                     "seconds": _answer(_bare(n, variant, publishers))["seconds"]})
    t0 = time.monotonic()
    procs = [_bare(n // SPLIT, "node", publishers) for _ in range(SPLIT)]
    answers = [_answer(p) for p in procs]
    rows.append({"variant": "node", "processes": SPLIT,
                 "seconds": max(a["seconds"] for a in answers),
                 "launch_to_ready_s": max(a["ready"] for a in answers) - t0})
    return rows


#: A share of a split scene: ``run_scene`` for instances named ``s<k>_<i>``, no graph check;
#: prints time.monotonic() at its first sample.
_SHARE = """
import sys, time
from mechsim.bench.startup import pendulums
from mechsim.ros.launch import run_scene
first = []
def started(node):
    if not first:
        first.append(time.monotonic())
run_scene(pendulums(int(sys.argv[1]), prefix=sys.argv[2]), fast=True, duration=0.02,
          graph_wait=0, before_first_message=started)
print(first[0], flush=True)
"""


def split_scene(n: int, processes: int = SPLIT) -> dict[str, Any]:
    """A scene of ``n`` pendulums as ``processes`` processes started together: launch to the
    last one's first sample."""
    t0 = time.monotonic()
    procs = [subprocess.Popen([sys.executable, "-c", _SHARE, str(n // processes), f"s{k}_"],
                              stdout=subprocess.PIPE, text=True) for k in range(processes)]
    firsts = []
    for p in procs:
        out, _ = p.communicate(timeout=600)
        if p.returncode != 0:
            raise RuntimeError(f"a share of the split scene failed (exit {p.returncode})")
        firsts.append(float(out.strip().splitlines()[-1]))
    return {"instances": n, "processes": processes, "launch_to_first_sample_s":
            max(firsts) - t0}


def processes_mode(n: int = PROCESSES_MODE) -> dict[str, Any]:
    """``run_processes`` (``mechsim run --processes``) of ``n`` pendulums, graph check
    included: seconds from the call to the last process ended (a run of one sample period),
    and the largest start-up a simulator process reported (from its context to its first
    sample: its imports not counted)."""
    from dataclasses import replace

    from mechsim.ros.processes import run_processes

    t0 = time.monotonic()
    run, _, status = run_processes(replace(pendulums(n, prefix="m"), duration=0.02))
    if status != 0:  # (said in the report; the other figures stand)
        return {"instances": n, "failed": f"exit status {status} after "
                f"{time.monotonic() - t0:.0f} s"}
    return {"instances": n, "call_to_end_s": time.monotonic() - t0,
            "slowest_process_startup_s": run.startup_time}


def publishers_per_node() -> int:
    """The publishers a pendulum's simulator node makes."""
    from mechsim.ros.launch import run_scene

    count: list[int] = []
    run_scene(pendulums(1), fast=True, duration=0.02, graph_wait=0,
              before_first_message=lambda node: count.append(len(list(node.publishers))))
    return count[0]


def variants(n: int, repeat: int = REPEAT) -> list[dict[str, Any]]:
    """Each of ``VARIANTS`` started ``repeat`` times in turn (a loaded machine's drift shared
    among them): the median start-up of each, with every start's seconds."""
    starts: dict[str, list[float]] = {v: [] for v in VARIANTS}
    served: dict[str, list[float]] = {v: [] for v in VARIANTS}
    for _ in range(repeat):
        for v in VARIANTS:
            row = scene_startup(n, variant=v)
            starts[v].append(row["startup_s"])
            served[v].append(row["parameters_served_s"])
    return [{"instances": n, "variant": v, "graph_check": v != "no_graph_check",
             "startup_s": statistics.median(s), "starts_s": s,
             "parameters_served_s": statistics.median(served[v])}
            for v, s in starts.items()]


def startup(sizes: tuple[int, ...] = SIZES) -> dict[str, Any]:
    scene_startup(1, graph_wait=0)  # warm: kernels loaded, modules imported
    largest = max(sizes)
    rows = [scene_startup(n) for n in sizes if n != largest]
    rows += variants(largest)
    profiled = scene_startup(largest, graph_wait=None, profile=True)
    for r in rows:
        print(f"  start-up of {r['instances']:3d} pendulums in one process, "
              f"{VARIANTS[r['variant']]}: {r['startup_s']:.2f} s", file=sys.stderr)
    publishers = publishers_per_node()
    bare = bare_endpoints(largest, publishers)
    split = split_scene(largest)
    print(f"  {largest} pendulums as {SPLIT} processes: "
          f"{split['launch_to_first_sample_s']:.2f} s from launch", file=sys.stderr)
    per_node = processes_mode()
    print(f"  {per_node['instances']} pendulums, one process per node: " + (
        f"failed ({per_node['failed']})" if "failed" in per_node else
        f"{per_node['call_to_end_s']:.2f} s from the call to the end"), file=sys.stderr)
    return {"one_process": rows, "profile": profiled, "bare": bare, "split": split,
            "processes_mode": per_node, "publishers_per_node": publishers}
