"""Joining the ROS graph, and checking it before a start.

A start looks at the graph (after a bounded discovery wait, ``GRAPH_WAIT`` or
``MECHSIM_GRAPH_WAIT`` seconds from joining it, 0 for no check; a conflict seen sooner refuses at
once): an instance whose node ``/<name>/simulator`` already runs elsewhere on the ROS domain, or
a ``/clock`` already published by another live node, stops the start with one line naming the
running node (one clock per graph: sim-time consumers would see time jump). A name left in the
graph by a killed process (no answer from its parameter service) does not count.

The window overlaps the start's own work: the models are loaded and a scene's simulator nodes
made (``launch``) while it runs. Those nodes publish no sample and nothing serves their
parameters or services until the check has passed (nothing spins them; a refused start
destroys them unanswered), and they are not in the way themselves (a name counts once more
often in the graph than among the start's own nodes). What a live node of the same name sees
meanwhile: a second node of its name in the graph, its service requests also reaching a server
that does not answer, a publisher on its topics (and on /clock) that publishes nothing, and
the new node's parameters announced on /parameter_events. Two starts of the same names at the
same moment can both pass: neither answers the other's check until it has passed its own.

One participant a process: rmw makes a context's DDS participant with its first node and ends
it with its last, and a participant ending while the graph's other participants are
discovering it (a launch starting its nodes) can crash the process (SIGSEGV) or deadlock Fast
DDS. A node made only to look (the check's own, a node executable's probe of its given values)
is therefore destroyed only once the process's next node exists: the nodes a start makes are
made before the check's node goes, and begun once the check has passed.

A command joins the graph (:func:`join_graph`) once its input is validated, so that discovery
runs while it loads the models; the next :func:`joined_context` takes that context. Every
context of a command starts through :func:`start_context`: a ROS that cannot start in this
environment is one line (``RosStartError``), never a traceback.
"""

from __future__ import annotations

import math
import os
import time
from collections import Counter
from collections.abc import Iterable, Iterator
from typing import Any

from mechsim.errors import MechsimError, ParameterError, RosStartError
from mechsim.params import DISCOVERY_WINDOW

#: Seconds of discovery before the graph is checked for duplicate names and /clock. A new
#: participant learns of the running ones from their periodic announcements (every 0.5 s with
#: the project's profile); the window leaves room for a loaded machine. Its range:
#: ``params.DISCOVERY_WINDOW``.
GRAPH_WAIT = float(DISCOVERY_WINDOW.default)
#: Environment variable that sets the discovery window instead (seconds, 0 … 600): a loaded
#: machine or a slow network may need more. A conflict seen earlier refuses at once, so a long
#: window costs only a start that has none.
GRAPH_WAIT_VARIABLE = "MECHSIM_GRAPH_WAIT"
#: Seconds a node found in the graph has to answer before it counts as gone (killed).
LIVENESS_TIMEOUT = 2.0


#: Seconds between requests to a node found in the graph (a request sent the moment its
#: service is discovered can lose its response).
ASK_AGAIN = 0.5


class _Liveness:
    """Does one node found in the graph answer on its parameter service? One client for the
    whole check, asked again every ``ASK_AGAIN`` s, polled without blocking."""

    def __init__(self, node: Any, full_name: str, now: float) -> None:
        from rcl_interfaces.srv import ListParameters

        self.request = ListParameters.Request(depth=1)
        self.client = node.create_client(ListParameters, f"{full_name}/list_parameters")
        self.seen = now
        self.first_asked: float | None = None
        self.last_asked = 0.0
        self.futures: list[Any] = []

    def poll(self, now: float, end: float) -> bool | None:
        """True: it answered. False: gone (asked for ``LIVENESS_TIMEOUT`` s without an
        answer, a frozen node or a killed process's entry; or its service never reachable by
        the end of the window and ``LIVENESS_TIMEOUT`` s after it was seen). None: not known
        yet (its service not discovered yet, or asked less than ``LIVENESS_TIMEOUT`` s ago)."""
        if any(f.done() for f in self.futures):
            return True
        if self.client.service_is_ready():
            if self.first_asked is None:
                self.first_asked = now
            elif now - self.first_asked >= LIVENESS_TIMEOUT:
                return False
            elif now - self.last_asked < ASK_AGAIN:
                return None
            self.futures.append(self.client.call_async(self.request))
            self.last_asked = now
            return None
        return False if now >= max(end, self.seen + LIVENESS_TIMEOUT) else None


def _split(full: str) -> tuple[str, str]:
    """(namespace, name) of a fully qualified node name, as the graph lists them."""
    namespace, _, node = full.rpartition("/")
    return namespace or "/", node


def window_setting(value: Any, field: str) -> float:
    """``value`` (seconds, a number or its text) as a discovery window, else a ParameterError
    naming ``field`` and the range."""
    try:
        return float(DISCOVERY_WINDOW.check(value, field))
    except ParameterError:
        raise ParameterError(field, f"{str(value)[:20]!r} is not a number of seconds in "
                             f"{DISCOVERY_WINDOW.minimum:g} … {DISCOVERY_WINDOW.maximum:g}"
                             ) from None


def discovery_window() -> float:
    """The discovery window of the graph check: ``MECHSIM_GRAPH_WAIT`` seconds if set (a
    ParameterError naming it if it is not a number in 0 … 600), else ``GRAPH_WAIT``."""
    raw = os.environ.get(GRAPH_WAIT_VARIABLE, "").strip()
    return window_setting(raw, GRAPH_WAIT_VARIABLE) if raw else GRAPH_WAIT


def quiet_node(name: str, namespace: str, context: Any) -> Any:
    """A node of mechsim's own tooling (a graph check, a command's probe): none of the
    command's ROS arguments apply to it, and it offers no service, so nothing of it stays
    listed once it is destroyed (rclpy's ~/get_type_description service outlived the node in
    ``ros2 service list``)."""
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    return Node(name, namespace=namespace, context=context, use_global_arguments=False,
                enable_rosout=False, start_parameter_services=False,
                parameter_overrides=[Parameter("start_type_description_service",
                                               value=False)])


class GraphCheck:
    """Refuse (MechsimError, one line) to start simulator nodes whose names a live node of
    the domain already uses, or a second /clock. Made before the models are built and the
    nodes made, so that discovery (which starts with the context's participant) runs
    meanwhile; :meth:`look` between them refuses a conflict seen early; :meth:`check` waits
    for the rest of the discovery window, refusing as soon as it sees a conflict."""

    def __init__(self, context: Any, started: float | None = None) -> None:
        """``started``: when ``context`` joined the graph (discovery began), if earlier."""
        from rclpy.executors import SingleThreadedExecutor

        self.context = context
        self.started = time.monotonic() if started is None else started
        self.probe = quiet_node(f"graph_check_{os.getpid()}", "/mechsim", context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.probe)
        self._liveness: dict[str, _Liveness] = {}

    def check(self, names: list[str], clock: bool, wait: float, own: Iterable[Any] = ()
              ) -> None:
        """Refuse as soon as a node in the way answers; start once ``wait`` seconds (from
        joining) passed and every node found in the way is known to be gone. ``names``:
        instance names (their node ``/<name>/simulator``) or fully qualified node names.
        ``own``: this start's nodes made already (not spun yet), which are not in the way."""
        end = self.started + wait
        while True:
            now = time.monotonic()
            undecided = self.look(names, clock, own, now, end)
            if now >= end and not undecided:
                return
            self.executor.spin_once(timeout_sec=0.05)

    def look(self, names: list[str], clock: bool, own: Iterable[Any] = (),
             now: float | None = None, end: float | None = None) -> bool:
        """One look at the graph, without waiting: refuse (MechsimError) if a node in the way
        answered; True if one found is not known yet to be gone. A start that makes its nodes
        during the window calls this between them, so that a conflict refuses at once."""
        now = time.monotonic() if now is None else now
        end = math.inf if end is None else end
        undecided = False
        for full, conflict in self._in_the_way(names, clock, list(own)):
            liveness = self._liveness.get(full)
            if liveness is None:
                liveness = self._liveness[full] = _Liveness(self.probe, full, now)
            answer = liveness.poll(now, end)
            if answer:
                raise MechsimError(conflict)
            undecided = undecided or answer is None
        self.executor.spin_once(timeout_sec=0.0)
        return undecided

    def _in_the_way(self, names: list[str], clock: bool, own: list[Any]
                    ) -> Iterator[tuple[str, str]]:
        """(full node name, the refusal if it is alive) for every node in the graph now that
        an instance name or the clock would clash with. ``own`` nodes are not in the way: a
        name counts once more often in the graph than among them (the graph lists every
        node, ours included, a name once per node), and a /clock publisher once more often
        than they publish it."""
        domain = self.context.get_domain_id()
        present = Counter((ns, n) for n, ns in self.probe.get_node_names_and_namespaces())
        ours = Counter(_split(n.get_fully_qualified_name()) for n in own)
        for name in names:
            full = name if name.startswith("/") else f"/{name}/simulator"
            if present[_split(full)] <= ours[_split(full)]:
                continue
            if name.startswith("/"):
                yield full, (f"{full} is already running on ROS domain {domain}; stop it or "
                             "start this node under another name (-r __ns:=/NAME)")
            else:
                yield full, (f"instance {name!r}: {full} is already running on ROS domain "
                             f"{domain}; stop it or give this instance another name "
                             "(--name, or `name:` in the scene)")
        if clock:
            own_clocks = Counter(n.get_fully_qualified_name() for n in own
                                 if any(p.topic_name == "/clock" for p in n.publishers))
            for info in self.probe.get_publishers_info_by_topic("/clock"):
                full = f"{info.node_namespace.rstrip('/')}/{info.node_name}"
                if own_clocks[full] > 0:
                    own_clocks[full] -= 1
                    continue
                yield full, (f"/clock is already published on ROS domain {domain} by {full}: "
                             "one clock per graph (stop that scene, run the systems in one "
                             "scene, or use another ROS_DOMAIN_ID)")

    @property
    def asked(self) -> set[str]:
        """The full names of the nodes found in the way, asked whether they answer."""
        return set(self._liveness)

    def close(self) -> None:
        for liveness in self._liveness.values():
            self.probe.destroy_client(liveness.client)
        self.executor.shutdown()
        self.probe.destroy_node()


#: The ROS arguments of this process's command (``--ros-args ...``: ``use_ros_arguments``).
_ros_arguments: list[str] = []


def use_ros_arguments(args: list[str]) -> None:
    """``args`` (``--ros-args`` and what follows it on a command line) are the ROS arguments
    every context this process starts from now on is initialised with: rcl's global
    arguments (remaps, parameters, log level) for the command's nodes. Checked by rcl now: a
    ParameterError naming ``--ros-args`` with rcl's reason if it cannot parse them, or if
    arguments that are not ROS arguments follow them."""
    if args:
        from mechsim.environment import import_rclpy

        import_rclpy()
        from rclpy.utilities import remove_ros_args

        try:
            rest = remove_ros_args(["mechsim", *args])[1:]
        except RuntimeError as e:  # rcl's RCLInvalidROSArgsError
            text = (str(e).splitlines() or [type(e).__name__])[0]
            text = text.removeprefix("Failed to parse ROS arguments: ").split(", at /")[0]
            raise ParameterError("--ros-args", text) from None
        if rest:
            raise ParameterError("--ros-args", f"not ROS arguments: {' '.join(rest)[:200]} "
                                 "(a command's own options go before --ros-args)")
    _ros_arguments[:] = args


def ros_arguments() -> list[str]:
    """The ROS arguments of this process's command (empty if it gave none)."""
    return list(_ros_arguments)


def start_context() -> Any:
    """A new rclpy context, initialised with the command's ROS arguments
    (``use_ros_arguments``; ROS's own signal handlers off: a command handles its stops). A
    ``ROS_DOMAIN_ID`` that no participant can use, or an rclpy that cannot start in this
    environment, is a RosStartError (one line)."""
    from mechsim.environment import import_rclpy, valid_domain_id

    raw = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if raw and not (raw.isdigit() and valid_domain_id(int(raw))):
        raise RosStartError(f"ROS_DOMAIN_ID={raw[:20]!r}: not a domain id in 0 … 101 or "
                            "215 … 232")
    rclpy = import_rclpy()
    from rclpy.signals import SignalHandlerOptions

    context = rclpy.context.Context()
    try:
        rclpy.init(args=["mechsim", *_ros_arguments], context=context,
                   signal_handler_options=SignalHandlerOptions.NO)
    except RuntimeError as e:  # rclpy's own start-up failures (RCLError)
        raise RosStartError((str(e).splitlines() or [type(e).__name__])[0]) from None
    return context


#: A context that joined the graph early (``join_graph``) and when, for the next start.
_joined: tuple[Any, float] | None = None


def join_graph() -> None:
    """Join the ROS graph now: a command calls this once its input is validated, so that
    discovery runs while it loads its models, and its start then waits only for what is left
    of the discovery window. The next :func:`joined_context` takes it."""
    global _joined
    if _joined is None:
        _joined = (start_context(), time.monotonic())


def joined_context() -> tuple[Any, float]:
    """The context of :func:`join_graph` (joining now if nothing did) and when it joined;
    the next call joins again."""
    global _joined
    join_graph()
    assert _joined is not None
    joined, _joined = _joined, None
    return joined
