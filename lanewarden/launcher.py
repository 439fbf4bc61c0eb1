"""The `lanewarden` command's entry point (and `python -m lanewarden`'s).

Importing the CLI takes seconds on a small machine (OpenCV, filterpy and SciPy, matplotlib): a
Ctrl-C then had printed Python's KeyboardInterrupt traceback. Here it is the same one line and
exit code as a Ctrl-C a moment later (`lanewarden.cli.main`).
"""

from __future__ import annotations

import signal
import sys

from lanewarden.errors import EXIT_INTERRUPTED


def main() -> int:
    try:
        from lanewarden.cli import main as run_command
    except KeyboardInterrupt:
        sys.stderr.write("lanewarden: error: interrupted\n")
        return EXIT_INTERRUPTED
    try:
        return run_command()
    finally:
        # The command is over (the robot stopped, everything said): a Ctrl-C or SIGTERM from now
        # on, while the interpreter shuts down, had printed a KeyboardInterrupt from an atexit
        # callback, or exited by the signal (-2) instead of with the run's exit code.
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, signal.SIG_IGN)
