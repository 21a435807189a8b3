#!/usr/bin/env python3
"""Start the scattering scene (seed 003 §5.3): simulator nodes and the diagnostics node.

Usage: launch_scripts/scattering.py [--processes] [--fast] [--duration S] [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "scattering.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
