#!/usr/bin/env python3
"""Start the rigid_body scene (seed 003 §7.2–7.7): simulator nodes and the diagnostics node.

Usage: launch_scripts/rigid_body.py [--processes] [--fast] [--duration S] [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "rigid_body.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
