"""`mechsim view`."""

from __future__ import annotations

import os
import shlex
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
        shown = " ".join(shlex.quote(f) for f in files)
        # Rerun's servers listen on 0.0.0.0 unless told otherwise: never suggested.
        print(f"mechsim: no display here; open it where there is one (`mechsim view {shown}`), "
              f"or serve it to a browser on this machine only with `rerun --bind 127.0.0.1 "
              f"--web-viewer {shown}` (from another machine: ssh -L 9090:127.0.0.1:9090 "
              "-L 9876:127.0.0.1:9876 HOST, then open the URL it prints)")
        return 0
    # The viewer's own gRPC server listens on loopback only.
    return subprocess.call([*viewer_command(), "--bind", "127.0.0.1", *files])


def add_parser(sub: Any) -> None:
    """``mechsim view`` and ``mechsim convert`` (Rerun imported only when they run)."""
    v = sub.add_parser("view", help="open a Rerun recording (.rrd), an .mcap file or a bag "
                       "in the Rerun viewer")
    v.add_argument("file", help=".rrd file, .mcap file or bag directory")
    v.set_defaults(func=cmd_view)
