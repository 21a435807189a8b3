"""What colcon's ament_python build runs (``setup.py ... install``); metadata, data files and
entry points are in setup.cfg, the build backend for pip in pyproject.toml.

The node executables (entry point group ``mechsim.executables``) become console scripts only
for ``setup.py install`` and ``develop``, as colcon runs them: installed under
``lib/mechsim`` (``[install]``, ``[develop]`` in setup.cfg), where ``ros2 run`` and launch_ros
look for a package's executables. A wheel (pip) puts only ``mechsim`` on PATH; the project's
set-up writes ``lib/mechsim`` into its venv itself (tools/bootstrap.py).
"""

import configparser
import sys
from pathlib import Path

from setuptools import setup


def entry_points(group: str) -> list[str]:
    cfg = configparser.ConfigParser()
    cfg.read(Path(__file__).with_name("setup.cfg"), encoding="utf-8")
    text = cfg.get("options.entry_points", group, fallback="")
    return [line.strip() for line in text.splitlines() if line.strip()]


if {"install", "develop"} & set(sys.argv[1:]):
    setup(entry_points={"console_scripts": [*entry_points("console_scripts"),
                                            *entry_points("mechsim.executables")],
                        "pytest11": entry_points("pytest11"),
                        "mechsim.executables": entry_points("mechsim.executables")})
else:
    setup()
