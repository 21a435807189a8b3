"""Recordings: rosbag2 (MCAP) bags and Rerun recordings. No nodes, no CLI."""
