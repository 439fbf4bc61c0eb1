"""Starting a CLI process that a test interrupts as an operator would (Ctrl-C)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable


def sigint_as_from_a_terminal() -> None:
    """`preexec_fn` for a child a test sends SIGINT to: SIGINT back to its default action, so
    the child's Python raises KeyboardInterrupt on it. A test run started in the background
    (`nohup`, `&` in a script, some CI runners) inherits SIGINT ignored, and a Python that starts
    with SIGINT ignored keeps ignoring it: the test would then wait for a Ctrl-C that never
    arrives."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def interrupted(args: list[str], ready: Callable[[], bool],
                whole_group: bool) -> tuple[int, str]:
    """Start `lanewarden ARGS`, wait (generously) until `ready()`, then send SIGINT: to the
    process, or, as a terminal's Ctrl-C does, to its whole process group. Its exit code and
    stderr."""

    def setup() -> None:
        if whole_group:
            os.setpgrp()
        sigint_as_from_a_terminal()

    run = subprocess.Popen([sys.executable, "-m", "lanewarden", *args], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True, preexec_fn=setup)
    try:
        deadline = time.monotonic() + 120.0
        while time.monotonic() < deadline and run.poll() is None and not ready():
            threading.Event().wait(0.05)
        assert run.poll() is None, run.communicate()
        if whole_group:
            os.killpg(run.pid, signal.SIGINT)
        else:
            run.send_signal(signal.SIGINT)
        _, err = run.communicate(timeout=120.0)
    finally:
        run.kill()
    return run.returncode, err
