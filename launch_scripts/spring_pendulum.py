#!/usr/bin/env python3
"""Start the spring_pendulum scene (seed 001 §2.2): simulator nodes and the diagnostics node.

Usage: launch_scripts/spring_pendulum.py [--processes] [--fast] [--duration S] [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "spring_pendulum.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
