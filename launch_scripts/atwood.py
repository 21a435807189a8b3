#!/usr/bin/env python3
"""Start the atwood scene (seed 001 §2.1, §2.11): simulator nodes and the diagnostics node.

Usage: launch_scripts/atwood.py [--processes] [--fast] [--duration S] [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "atwood.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
