"""`mechsim view`."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import Any

from mechsim.errors import MechsimError
from mechsim.outputs.rerun import viewer_command


def cmd_view(a: Any) -> int:
    path = Path(a.file)
    if path.is_dir():  # a bag: Rerun reads MCAP with ROS 2 messages directly
        files = [str(p) for p in sorted(path.glob("*.mcap"))]
        if not files:
            raise MechsimError(f"{path}: no .mcap files in this directory")
    elif path.is_file():
        files = [str(path)]
    else:
        raise MechsimError(f"{path}: no such file (an .rrd recording, an .mcap file or a bag)")
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        shown = " ".join(files)
        print(f"mechsim: no display here; open it where there is one with `rerun {shown}`, "
              f"or in a browser with `rerun --web-viewer {shown}`")
        return 0
    # The viewer's own gRPC server listens on loopback only.
    return subprocess.call([*viewer_command(), "--bind", "127.0.0.1", *files])


def add_parser(sub: Any) -> None:
    """``mechsim view`` and ``mechsim convert`` (Rerun imported only when they run)."""
    v = sub.add_parser("view", help="open a Rerun recording (.rrd), an .mcap file or a bag "
                       "in the Rerun viewer")
    v.add_argument("file", help=".rrd file, .mcap file or bag directory")
    v.set_defaults(func=cmd_view)
