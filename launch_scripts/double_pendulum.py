#!/usr/bin/env python3
"""Start the double_pendulum scene (seed 001 §2.3): simulator nodes and the diagnostics node.

Usage: launch_scripts/double_pendulum.py [--processes] [--fast] [--duration S] [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "double_pendulum.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
