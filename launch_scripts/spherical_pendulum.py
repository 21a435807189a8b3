#!/usr/bin/env python3
"""Start the spherical_pendulum scene (seed 002 §8): simulator nodes and the diagnostics node.

Usage: launch_scripts/spherical_pendulum.py [--processes] [--fast] [--duration S]
       [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "spherical_pendulum.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
