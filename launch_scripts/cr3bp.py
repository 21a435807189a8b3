#!/usr/bin/env python3
"""Start the CR3BP scene (seed 000 S12): simulator nodes and the diagnostics node.

Usage: launch_scripts/cr3bp.py [--processes] [--fast] [--duration S] [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "cr3bp.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
