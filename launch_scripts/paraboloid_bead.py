#!/usr/bin/env python3
"""Start the paraboloid_bead scene (seed 002 §6): simulator nodes and the diagnostics node.

Usage: launch_scripts/paraboloid_bead.py [--processes] [--fast] [--duration S]
       [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "paraboloid_bead.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
