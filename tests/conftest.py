"""The suite's ROS isolation and fixtures come from mechsim's own pytest plugin
(``mechsim.testing``, registered as a ``pytest11`` entry point when mechsim is installed): the
loopback-only Fast DDS profile and a per-session, per-worker ``ROS_DOMAIN_ID`` are set before
collection; ``ros_domain_id``, ``ros_context``, ``ros_env`` and ``mechsim_graph`` are its
fixtures. `make test` passes ROS_DOMAIN_ID; a bare `pytest` run picks one from its PID."""

from rosuser import ros2_env  # noqa: E402,F401 - the real ros2 command's fixture (or a skip)
