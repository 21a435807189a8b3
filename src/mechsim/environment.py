"""Process environment for ROS 2 (rclpy from PyPI wheels, Fast DDS confined to loopback).

Call :func:`configure_ros_environment` before ``import rclpy`` (or use :func:`import_rclpy`).
It sets, in ``os.environ``:

- ``FASTDDS_DEFAULT_PROFILES_FILE``: the loopback-only Fast DDS profile shipped as package data
  (``mechsim/data/fastdds_loopback.xml``). It is the default participant profile: builtin
  transports off, shared memory plus UDPv4 on 127.0.0.1 only, discovery on 127.0.0.1.
- ``RMW_IMPLEMENTATION=rmw_fastrtps_cpp`` (the profile is a Fast DDS profile).
- ``ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT``: rmw leaves discovery to the profile.
  ``LOCALHOST`` must NOT be used with this profile: with it, rmw_fastrtps adds transports that
  bind UDP sockets on 0.0.0.0 and on the external interface (seen with rmw_fastrtps_cpp 9.3.3).
- ``ROS_DISTRO=kilted`` (the wheels' distribution; rosbag2 metadata records it).
- ``ROS_DOMAIN_ID`` only if ``domain_id`` is given; an existing user setting is kept otherwise.
- ``ROS_PYTHON_CHECK_FIELDS=1`` only if ``check_fields=True``.
- ``AMENT_PREFIX_PATH`` gains the venv prefix, so ament_index lookups
  (``get_package_share_directory("tf2_msgs")``) find the wheels and the generated packages.

Several hosts (opt-in). With ``MECHSIM_DDS_INTERFACE`` set to an IPv4 address of this host and
``MECHSIM_DDS_PEERS`` to the comma-separated IPv4 addresses of the other hosts, the profile is
generated instead (:func:`hosts_profile`): the same shape, with that interface allowed beside
127.0.0.1, discovery unicast on it, and the peers as initial peers (unicast discovery, no
multicast). Every other interface stays closed. Unset, the loopback profile is used.

Variables that would widen discovery beyond loopback (``ROS_LOCALHOST_ONLY``, ``ROS_STATIC_PEERS``,
``ROS_DISCOVERY_SERVER``, ``ROS_SUPER_CLIENT``, ``ROS2_EASY_MODE``, ``FASTDDS_BUILTIN_TRANSPORTS``,
``FASTRTPS_DEFAULT_PROFILES_FILE``) are removed.

``LD_LIBRARY_PATH`` cannot be fixed from inside a running process (the loader reads it at
start). In the project venv the ``ros_wheels_bootstrapper`` .pth (installed with ``ros-rclpy``)
re-executes the interpreter with the wheels' library directories on it; this module only checks
that this happened.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import sys
from pathlib import Path
from types import ModuleType

__all__ = [
    "BOOTSTRAP_HINT",
    "FASTDDS_PROFILE",
    "RosEnvironmentError",
    "configure_ros_environment",
    "import_rclpy",
    "hosts_profile",
    "valid_domain_id",
]

#: The loopback-only Fast DDS profile (single source of truth; config/ links to it).
FASTDDS_PROFILE: Path = Path(__file__).resolve().parent / "data" / "fastdds_loopback.xml"

BOOTSTRAP_HINT = "run `make test` or `python3 tools/bootstrap.py` first"

#: Interface packages built from src/ by tools/bootstrap.py (not on PyPI).
GENERATED_PACKAGES = ("tf2_msgs", "mechsim_msgs")

_REMOVED_VARS = (
    "ROS_LOCALHOST_ONLY",
    "ROS_STATIC_PEERS",
    "ROS_DISCOVERY_SERVER",
    "ROS_SUPER_CLIENT",
    "ROS2_EASY_MODE",
    "FASTDDS_BUILTIN_TRANSPORTS",
    "FASTRTPS_DEFAULT_PROFILES_FILE",
)


class RosEnvironmentError(RuntimeError):
    """The ROS 2 environment (venv with the ROS wheels and generated messages) is missing."""

    def __init__(self, problem: str) -> None:
        super().__init__(f"ROS 2 environment not ready ({problem}): {BOOTSTRAP_HINT}")
        self.problem = problem


def valid_domain_id(domain_id: int) -> bool:
    """True for the domain ids Fast DDS can use on Linux with default ports (0..101, 215..232)."""
    return 0 <= domain_id <= 101 or 215 <= domain_id <= 232


def _ipv4(field: str, text: str) -> str:
    """A unicast IPv4 address of a host, or a one-line error naming the variable."""
    import ipaddress

    try:
        addr = ipaddress.IPv4Address(text.strip())
    except ValueError:
        raise RosEnvironmentError(f"{field}: not an IPv4 address ({text[:64]!r})") from None
    if addr.is_unspecified or addr.is_multicast or addr.is_reserved:
        raise RosEnvironmentError(f"{field}: {addr} is not a unicast host address")
    return str(addr)


def hosts_profile(interface: str, peers: list[str]) -> str:
    """The Fast DDS profile for several hosts: loopback plus ``interface``; discovery unicast
    to ``peers`` (and this host). Text only; see :func:`configure_ros_environment`."""
    iface = _ipv4("MECHSIM_DDS_INTERFACE", interface)
    hosts = [_ipv4("MECHSIM_DDS_PEERS", p) for p in peers if p.strip()]
    if not hosts:
        raise RosEnvironmentError("MECHSIM_DDS_PEERS: no peer address given")
    text = FASTDDS_PROFILE.read_text()
    text = text.replace("mechsim_loopback", "mechsim_hosts")
    text = text.replace("<interfaceWhiteList>\n          <address>127.0.0.1</address>",
                        "<interfaceWhiteList>\n          <address>127.0.0.1</address>\n"
                        f"          <address>{iface}</address>")
    meta = "<metatrafficUnicastLocatorList>"
    loc = "\n            <locator>\n              <udpv4>\n                <address>{}</address>" \
          "\n              </udpv4>\n            </locator>"
    text = text.replace(meta, meta + loc.format(iface), 1)
    peers_tag = "<initialPeersList>"
    text = text.replace(peers_tag, peers_tag + "".join(loc.format(h) for h in hosts), 1)
    return text


def _profile_file() -> Path:
    """The profile this process uses: the loopback one, or the generated several-hosts one
    (written once per content, exclusively and atomically, in a private directory)."""
    interface = os.environ.get("MECHSIM_DDS_INTERFACE")
    if not interface:
        return FASTDDS_PROFILE
    import hashlib
    import tempfile

    text = hosts_profile(interface, os.environ.get("MECHSIM_DDS_PEERS", "").split(","))
    digest = hashlib.sha256(text.encode()).hexdigest()[:16]
    folder = Path(tempfile.gettempdir()) / f"mechsim-dds-{os.getuid()}"
    folder.mkdir(mode=0o700, exist_ok=True)
    if folder.is_symlink() or folder.stat().st_uid != os.getuid():
        raise RosEnvironmentError(f"{folder}: not a private directory of this user")
    target = folder / f"fastdds_hosts_{digest}.xml"
    if not target.is_file():
        fd, tmp = tempfile.mkstemp(dir=folder, suffix=".tmp")
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, target)
    return target


def _prepend_path(var: str, entry: str) -> None:
    parts = [p for p in os.environ.get(var, "").split(os.pathsep) if p]
    if entry not in parts:
        os.environ[var] = os.pathsep.join([entry, *parts])


def _venv_has_ros_wheels() -> bool:
    return (Path(sys.prefix) / "lib" / "librcl.so").exists()


def configure_ros_environment(
    domain_id: int | None = None, *, check_fields: bool = False
) -> None:
    """Set the ROS 2 environment variables of this process (call before ``import rclpy``).

    Child processes started afterwards with ``os.environ`` inherit the same settings.
    Raises :class:`RosEnvironmentError` if the Fast DDS profile is missing and ``ValueError``
    for an unusable ``domain_id``.
    """
    if domain_id is not None:
        if not valid_domain_id(domain_id):
            raise ValueError(f"ROS domain id {domain_id} outside 0..101 and 215..232")
        os.environ["ROS_DOMAIN_ID"] = str(domain_id)
    if not FASTDDS_PROFILE.is_file():
        raise RosEnvironmentError(f"Fast DDS profile {FASTDDS_PROFILE} missing")
    profile = _profile_file()
    for var in _REMOVED_VARS:
        os.environ.pop(var, None)
    os.environ["FASTDDS_DEFAULT_PROFILES_FILE"] = str(profile)
    os.environ["RMW_IMPLEMENTATION"] = "rmw_fastrtps_cpp"
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SYSTEM_DEFAULT"
    os.environ["ROS_DISTRO"] = "kilted"
    if check_fields:
        os.environ["ROS_PYTHON_CHECK_FIELDS"] = "1"
    if (Path(sys.prefix) / "share" / "ament_index").is_dir():
        _prepend_path("AMENT_PREFIX_PATH", sys.prefix)


def _check_environment() -> None:
    if importlib.util.find_spec("rclpy") is None:
        raise RosEnvironmentError(f"rclpy not installed for {sys.executable}")
    if _venv_has_ros_wheels():
        lib = str(Path(sys.prefix) / "lib")
        if lib not in os.environ.get("LD_LIBRARY_PATH", "").split(os.pathsep):
            raise RosEnvironmentError(
                f"LD_LIBRARY_PATH lacks {lib}; the ros_wheels_bootstrapper .pth did not run "
                "(unset _ROS_WHEELS_BOOTSTRAP_COMPLETE inherited from another environment)"
            )
    for pkg in GENERATED_PACKAGES:
        spec = importlib.util.find_spec(pkg)
        # src/ is on sys.path (editable install); src/<pkg> without __init__.py would be
        # found as a namespace package, which has no origin file.
        if spec is None or spec.origin is None:
            raise RosEnvironmentError(f"interface package {pkg} not built")


def import_rclpy(domain_id: int | None = None, *, check_fields: bool = False) -> ModuleType:
    """Configure the environment, check it, and return the imported ``rclpy`` module."""
    configure_ros_environment(domain_id, check_fields=check_fields)
    _check_environment()
    try:
        return importlib.import_module("rclpy")
    except ImportError as e:
        raise RosEnvironmentError(f"import rclpy failed: {e}") from e
