"""The ``mechsim`` command. Every user error is one line on stderr and exit status 2."""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys

from mechsim.errors import MechsimError

EXIT_USAGE = 2


#: The verbs, in the order ``mechsim --help`` lists them: one module each in this package.
VERBS = ("systems", "run", "record", "bag", "replay", "topic", "node", "param", "service",
         "view", "convert", "bench", "stress", "cache", "figures")


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="mechsim", description="Simulated classical mechanics "
                                 "streamed as ROS 2 topics.")
    sub = ap.add_subparsers(dest="command", required=True)
    for verb in VERBS:  # each module registers its parser; heavy imports wait for the run
        importlib.import_module(f"mechsim.cli.{verb}").add_parser(sub)
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
    except MechsimError as e:
        print(f"mechsim: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # Output piped into `head` and the like: stop quietly, as command-line tools do.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except RuntimeError as e:  # RosEnvironmentError and rclpy start-up failures
        print(f"mechsim: error: {str(e).splitlines()[0] if str(e) else type(e).__name__}",
              file=sys.stderr)
        return EXIT_USAGE


def entry() -> None:
    """The console command: :func:`main`, then a quick exit (``exit_process``)."""
    code = main()
    from mechsim.ros.process import exit_process

    exit_process(code)


if __name__ == "__main__":
    entry()
