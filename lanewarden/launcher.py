"""The `lanewarden` command's entry point (and `python -m lanewarden`'s).

Importing the CLI takes seconds on a small machine (OpenCV, filterpy and SciPy, matplotlib): a
Ctrl-C then had printed Python's KeyboardInterrupt traceback. Here it is the same one line and
exit code as a Ctrl-C a moment later (`lanewarden.cli.main`).
"""

from __future__ import annotations

import sys

from lanewarden.errors import EXIT_INTERRUPTED


def main() -> int:
    try:
        from lanewarden.cli import main as run_command
    except KeyboardInterrupt:
        sys.stderr.write("lanewarden: error: interrupted\n")
        return EXIT_INTERRUPTED
    return run_command()
