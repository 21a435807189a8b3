#!/usr/bin/env python3
"""Start the sphere_slide scene (seed 001 §1.1): simulator nodes and the diagnostics node.

Usage: launch_scripts/sphere_slide.py [--processes] [--fast] [--duration S] [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "sphere_slide.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
