#!/usr/bin/env python3
"""Start the symmetric_top scene (seed 003 §7.8, seed 002 §7): simulator nodes and the diagnostics node.

Usage: launch_scripts/symmetric_top.py [--processes] [--fast] [--duration S] [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "symmetric_top.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
