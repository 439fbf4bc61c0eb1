"""Starting a CLI process that a test interrupts as an operator would (Ctrl-C)."""

from __future__ import annotations

import signal


def sigint_as_from_a_terminal() -> None:
    """`preexec_fn` for a child a test sends SIGINT to: SIGINT back to its default action, so
    the child's Python raises KeyboardInterrupt on it. A test run started in the background
    (`nohup`, `&` in a script, some CI runners) inherits SIGINT ignored, and a Python that starts
    with SIGINT ignored keeps ignoring it: the test would then wait for a Ctrl-C that never
    arrives."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
