"""Session-wide ROS 2 setup: loopback-only Fast DDS and a per-run ROS_DOMAIN_ID.

The environment is configured at import time of this conftest, i.e. before any test module
can import rclpy. `make test` passes ROS_DOMAIN_ID; a bare `pytest` run picks one from its PID.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import TYPE_CHECKING

import pytest

from mechsim.environment import configure_ros_environment, valid_domain_id

if TYPE_CHECKING:
    from rclpy.context import Context


def _domain_id_for(pid: int) -> int:
    """A domain id in 1..101 (0 is everyone's default; 102..214 are not usable)."""
    return pid % 101 + 1


_VALID_IDS = [*range(1, 102), *range(215, 233)]


def _session_domain_id() -> int:
    """The run's domain id (ROS_DOMAIN_ID, else from the PID); each pytest-xdist worker gets
    its own, so parallel workers never see each other's nodes."""
    raw = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if raw:
        domain_id = int(raw)
        if not valid_domain_id(domain_id):
            raise pytest.UsageError(f"ROS_DOMAIN_ID={raw} outside 0..101 and 215..232")
    else:
        domain_id = _domain_id_for(os.getpid())
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    if worker.startswith("gw") and domain_id in _VALID_IDS:
        k = int(worker[2:])
        domain_id = _VALID_IDS[(_VALID_IDS.index(domain_id) + 41 * k) % len(_VALID_IDS)]
    return domain_id


ROS_DOMAIN_ID = _session_domain_id()
configure_ros_environment(ROS_DOMAIN_ID)


def pytest_report_header(config: pytest.Config) -> str:
    return (f"ROS_DOMAIN_ID={ROS_DOMAIN_ID} "
            f"FASTDDS_DEFAULT_PROFILES_FILE={os.environ['FASTDDS_DEFAULT_PROFILES_FILE']}")


@pytest.fixture(scope="session")
def ros_domain_id() -> int:
    """The ROS domain id of this test run."""
    return ROS_DOMAIN_ID


@pytest.fixture
def ros_context(ros_domain_id: int) -> Iterator[Context]:
    """A fresh rclpy Context, initialised for this test only; shut down afterwards.

    Pass ``context=ros_context`` to every Node and Executor.
    """
    from mechsim.environment import import_rclpy

    rclpy = import_rclpy()
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=ros_domain_id)
    try:
        yield ctx
    finally:
        ctx.try_shutdown()


@pytest.fixture
def ros_env() -> dict[str, str]:
    """Environment for a child process (``subprocess.Popen(..., env=ros_env)``) that uses ROS
    with this run's settings (profile, domain id, RMW, library path)."""
    return dict(os.environ)
