#!/usr/bin/env python3
"""Start the kepler scene (seed 003 ch. 4): simulator nodes and the diagnostics node.

Usage: launch_scripts/kepler.py [--processes] [--fast] [--duration S] [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "kepler.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
