#!/usr/bin/env python3
"""Start the moving_coordinates scene (seed 000 S4–S5, seed 002 §4): simulator nodes and the diagnostics node.

Usage: launch_scripts/moving_coordinates.py [--processes] [--fast] [--duration S] [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "moving_coordinates.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
