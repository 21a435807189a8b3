"""`mechsim convert`."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

from mechsim.errors import ParameterError, counted
from mechsim.outputs.rerun import convert_bag


def output_path(bag: str, rrd: str | None) -> Path:
    """The .rrd to write: ``--rrd``, else ``<bag directory>.rrd`` beside the bag."""
    for field, value in (("BAG", bag), ("--rrd", rrd)):
        if value is not None and ("\x00" in value or not value.strip()):
            raise ParameterError(field, f"{value!r} is not a path")
    if rrd:
        return Path(rrd)
    d = Path(bag).resolve()
    if not d.name:
        raise ParameterError("--rrd", f"needed for the bag {bag} (no name to derive it from)")
    return d.with_name(d.name + ".rrd")


def cmd_convert(a: Any) -> int:
    rrd = output_path(a.bag, a.rrd)
    if os.path.isdir(rrd):
        raise ParameterError("--rrd", f"{rrd} is a directory")
    if os.path.lexists(rrd) and not a.force:
        raise ParameterError("--rrd", f"{rrd} exists (add --force to replace it)")
    counts = convert_bag(Path(a.bag), rrd, replace=a.force)
    print(f"mechsim: wrote {rrd} ({counted(sum(counts.values()), 'message')} on "
          f"{counted(len(counts), 'topic')})",
          file=sys.stderr)
    return 0


def add_parser(sub: Any) -> None:
    c = sub.add_parser("convert", help="convert a rosbag2 MCAP bag to a Rerun recording "
                       "(the same entities as `run --rrd`)")
    c.add_argument("bag", help="bag directory (metadata.yaml + .mcap)")
    c.add_argument("--rrd", metavar="FILE", help="output .rrd (default: <bag>.rrd)")
    c.add_argument("--force", action="store_true",
                   help="replace an existing .rrd (only once the new one is complete)")
    c.set_defaults(func=cmd_convert)
