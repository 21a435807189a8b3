#!/usr/bin/env python3
"""Start the driven_oscillator scene (seed 003 §1.3–1.5): simulator nodes and the diagnostics node.

Usage: launch_scripts/driven_oscillator.py [--processes] [--fast] [--duration S] [--set name=value ...]
"""

import sys
from pathlib import Path

from mechsim.ros.launch import launch_scene

if __name__ == "__main__":
    scene = Path(__file__).resolve().parent.parent / "scenes" / "driven_oscillator.yaml"
    sys.exit(launch_scene(scene, sys.argv[1:]))
