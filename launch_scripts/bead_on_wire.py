#!/usr/bin/env python3
"""Start the bead_on_wire scene (seed 000 S2 and others): simulator nodes and the diagnostics node.

Usage: launch_scripts/bead_on_wire.py [--processes] [--fast] [--duration S] [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "bead_on_wire.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
