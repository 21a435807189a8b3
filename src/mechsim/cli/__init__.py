"""The ``mechsim`` command: the one entry point of every mechsim process, the verbs a user runs
and the node processes a multi-process run starts (hidden verbs, ``executables``).

One mapping of outcomes to exit statuses for all of them: a user's error (a ``MechsimError``,
or a ROS environment that is not ready) is one line ``mechsim: error: ...`` and exit 2; Ctrl-C
or SIGTERM exit 130; output into a closed pipe ends quietly; anything else is a defect of
mechsim, said as one: ``mechsim: internal error: <type>: <message> (traceback in <file>)``,
exit 1, the traceback written to a new file under the user's cache directory (else the
temporary directory), never to the terminal."""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
from typing import Any

from mechsim.errors import MechsimError, one_line

EXIT_USAGE = 2
EXIT_INTERNAL = 1
EXIT_INTERRUPTED = 130

#: The verbs, in the order ``mechsim --help`` lists them: one module each in this package.
VERBS = ("systems", "run", "record", "bag", "replay", "topic", "node", "param", "service",
         "view", "convert", "bench", "stress", "cache", "figures")
#: The node processes' verbs (``executables``), not listed by ``mechsim --help``.
NODE_VERBS = ("simulator", "diagnostics", "recorder", "swing_up_controller")


class Parser(argparse.ArgumentParser):
    """argparse's parser, whose refusal of a choice (a verb, a method) says the close one:
    ``invalid choice: 'rn': did you mean 'run'? (choose from ...)``."""

    def _check_value(self, action: argparse.Action, value: Any) -> None:
        choices = action.choices
        if choices is None or value in choices:
            return
        from mechsim.errors import did_you_mean

        shown = [str(c) for c in choices if str(c) not in NODE_VERBS]
        raise argparse.ArgumentError(action, f"invalid choice: {value!r}"
                                     + did_you_mean(str(value), shown, "choose from"))


def build_parser() -> argparse.ArgumentParser:
    from mechsim import __version__

    ap = Parser(prog="mechsim", description="Simulated classical mechanics streamed as ROS 2 "
                "topics.")
    ap.add_argument("--version", action="version", version=f"mechsim {__version__}")
    # (the metavar names the verbs users run; the node processes' verbs stay unlisted)
    sub = ap.add_subparsers(dest="command", required=True, metavar=f"{{{','.join(VERBS)}}}")
    for verb in VERBS:  # each module registers its parser; heavy imports wait for the run
        importlib.import_module(f"mechsim.cli.{verb}").add_parser(sub)
    importlib.import_module("mechsim.cli.executables").add_parsers(sub)
    return ap


def main(argv: list[str] | None = None) -> int:
    code = _run(argv)
    rerun_sink = sys.modules.get("mechsim.outputs.rerun")
    if rerun_sink is not None and rerun_sink.writer_stuck():
        # The error is reported and the temporaries removed; Rerun would wait at exit for a
        # file writer that hung on a full disk, without a bound.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


def _run(argv: list[str] | None) -> int:
    # Ctrl-C stops a command even where it was started with SIGINT ignored (a background job
    # of a script, a test runner's worker): Python only installs its handler if not.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:  # Ctrl-C while the parser's modules import is a quiet 130 too
        a = build_parser().parse_args(argv)
        return int(a.func(a))
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # Output piped into `head` and the like: stop quietly, as command-line tools do.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except Exception as e:  # noqa: BLE001 - every outcome gets its one line
        return report(e)


def report(error: Exception) -> int:
    """Say what ``error`` means to the user, in one line on stderr; its exit status."""
    from mechsim.environment import RosEnvironmentError
    from mechsim.runcore.stops import is_stop, stopping

    if isinstance(error, RosEnvironmentError) and stopping.is_set():
        # SIGTERM while rclpy loaded its libraries: the import failed because of the stop.
        return EXIT_INTERRUPTED
    if isinstance(error, MechsimError | RosEnvironmentError):
        print(f"mechsim: error: {one_line(_first_line(error))}", file=sys.stderr)
        return EXIT_USAGE
    if is_stop(error):  # a stop that landed in C code and came out as another exception
        return EXIT_INTERRUPTED
    where = write_traceback(error)
    print(f"mechsim: internal error: {type(error).__name__}: "
          f"{one_line(_first_line(error))[:300]} (traceback in {where})", file=sys.stderr)
    return EXIT_INTERNAL


def _first_line(error: BaseException) -> str:
    return (str(error).splitlines() or [type(error).__name__])[0]


def write_traceback(error: BaseException) -> str:
    """Write ``error``'s traceback to a new file (created exclusively, not following links,
    readable by the user only) in ``$XDG_CACHE_HOME/mechsim/errors`` (default
    ``~/.cache``), else in the temporary directory; its path, or why there is none."""
    import datetime
    import tempfile
    import traceback
    from pathlib import Path

    from mechsim import __version__

    text = (f"mechsim {__version__} at {datetime.datetime.now().isoformat(timespec='seconds')}"
            f"\ncommand: {' '.join(sys.argv)}\n\n"
            + "".join(traceback.format_exception(error)))
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache")
    for directory in (os.path.join(base, "mechsim", "errors"), tempfile.gettempdir()):
        try:
            os.makedirs(directory, mode=0o700, exist_ok=True)
            fd, path = tempfile.mkstemp(prefix="traceback-", suffix=".txt", dir=directory)
            with os.fdopen(fd, "w", encoding="utf-8", errors="replace") as f:
                f.write(text)
            return path
        except OSError:
            continue
    return "nowhere: no writable cache or temporary directory"


def entry(argv: list[str] | None = None) -> None:
    """The console command: :func:`main`, then a quick exit (``exit_process``)."""
    code = main(argv)
    from mechsim.ros.process import exit_process

    exit_process(code)


if __name__ == "__main__":
    entry()
