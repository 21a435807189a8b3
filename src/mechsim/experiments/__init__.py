"""Experiments run on systems (above the physics and stepping layers)."""
