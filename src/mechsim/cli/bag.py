"""`mechsim bag`."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from mechsim.errors import counted


def add_parser(sub: Any) -> None:
    b = sub.add_parser("bag", help="inspect or repair a recorded bag")
    bsub = b.add_subparsers(dest="bag_command", required=True)
    i = bsub.add_parser("info", help="what a bag holds (like `ros2 bag info`)")
    i.add_argument("bag", metavar="DIR")
    i.set_defaults(func=cmd_bag_info)
    r = bsub.add_parser("repair", help="complete an interrupted or damaged bag (rewrite the "
                        "MCAP from its readable chunks with a summary, write metadata.yaml); "
                        "refused while the bag is being recorded")
    r.add_argument("bag", metavar="DIR")
    r.set_defaults(func=cmd_bag_repair)


def cmd_bag_info(a: argparse.Namespace) -> int:
    from mechsim.outputs.bag import check_storage, describe, read_metadata

    meta = read_metadata(Path(a.bag))
    check_storage(Path(a.bag), meta)  # framing and declared sizes (nothing decompressed)
    text = describe(meta)
    try:
        print(text, flush=True)
    except BrokenPipeError:  # `mechsim bag info DIR | head`
        import os
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


def cmd_bag_repair(a: argparse.Namespace) -> int:
    from mechsim.environment import import_rclpy
    from mechsim.outputs.bag import repair_bag

    try:
        import_rclpy()  # to read SystemInfo messages back into custom_data; optional
    except RuntimeError:
        pass
    r = repair_bag(Path(a.bag))
    if r.complete:
        state = "was complete"
    elif r.lost_chunks:
        state = (f"{r.lost_chunks} damaged chunk{'s' if r.lost_chunks != 1 else ''} skipped "
                 f"(the first {r.lost_reason}), the others kept; original kept as "
                 f"{r.damaged.name if r.damaged else '?'}")
    else:
        state = "was truncated; readable chunks kept"
    if r.cut and not r.complete:
        state += f"; the file ends early ({r.cut})"
    print(f"bag {r.path}: {counted(r.messages, 'message')} on {counted(r.topics, 'topic')} "
          f"({state}); "
          "metadata.yaml written")
    return 0

