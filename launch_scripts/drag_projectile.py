#!/usr/bin/env python3
"""Start the drag_projectile scene (seed 001 §2.5–2.6): simulator nodes and the diagnostics node.

Usage: launch_scripts/drag_projectile.py [--processes] [--fast] [--duration S] [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "drag_projectile.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
