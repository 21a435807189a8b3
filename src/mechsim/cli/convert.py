"""`mechsim convert`."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from mechsim.outputs.rerun import convert_bag


def cmd_convert(a: Any) -> int:
    bag = Path(a.bag)
    rrd = Path(a.rrd) if a.rrd else bag.with_name(bag.name.rstrip("/") + ".rrd")
    counts = convert_bag(bag, rrd)
    print(f"mechsim: wrote {rrd} ({sum(counts.values())} messages on {len(counts)} topics)",
          file=sys.stderr)
    return 0


def add_parser(sub: Any) -> None:
    c = sub.add_parser("convert", help="convert a rosbag2 MCAP bag to a Rerun recording "
                       "(the same entities as `run --rrd`)")
    c.add_argument("bag", help="bag directory (metadata.yaml + .mcap)")
    c.add_argument("--rrd", metavar="FILE", help="output .rrd (default: <bag>.rrd)")
    c.set_defaults(func=cmd_convert)

