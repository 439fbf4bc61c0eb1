"""How the commands that move the robot (`run`, `base drive`) take terminal and kill signals.

SIGINT (Ctrl-C), SIGTERM, SIGQUIT (Ctrl-\\) and SIGHUP (the terminal went away) ask the command to
stop the robot and end; SIGTSTP (Ctrl-Z) asks it to stop the robot first and then suspend. The
handlers only record the request; the command's own loop acts on it within one period, so a
request never interleaves with a half-sent command (and no handler does I/O). `suspend()` stops
this process with SIGSTOP, which, unlike a re-raised SIGTSTP, also works in an orphaned process
group, and returns once something sends SIGCONT.

The dead-man process is in a session of its own and never sees these signals: while this
process is suspended it holds the stop (see `KobukiBase.hold_stopped`).

The simulation commands' worker processes (the demo's pool, the campaign's Dask workers) are in
the terminal's process group, so a terminal's Ctrl-C reaches them too: they ignore it
(`leave_interrupts_to_the_parent`) and the command, which gets it as well, shuts them down and
says so in one line, instead of each worker printing its own KeyboardInterrupt traceback.
SIGTERM to such a command becomes an interrupt (`raise_interrupt`), so it ends the same way.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from types import FrameType

#: Signals that mean "stop the robot and end", like the operator's Ctrl-C.
STOP_SIGNALS: tuple[signal.Signals, ...] = (
    signal.SIGINT, signal.SIGTERM, signal.SIGQUIT, signal.SIGHUP,
)


@dataclass
class SignalRequests:
    """What the signals asked for since the command started (set by the handlers only)."""

    stop: signal.Signals | None = None
    suspend: bool = False

    def pending(self) -> bool:
        """Whether a stop or a suspend was asked for (what ends a tick's wait at once:
        `Ticker.wait(interrupted=requests.pending)`)."""
        return self.stop is not None or self.suspend


@contextmanager
def signal_requests() -> Iterator[SignalRequests]:
    """Install the handlers for the duration of a `with` block (main thread only); the previous
    handlers come back on exit."""
    requests = SignalRequests()

    def on_stop(signum: int, frame: FrameType | None) -> None:
        requests.stop = requests.stop or signal.Signals(signum)

    def on_suspend(signum: int, frame: FrameType | None) -> None:
        requests.suspend = True

    previous = {sig: signal.signal(sig, on_stop) for sig in STOP_SIGNALS}
    previous[signal.SIGTSTP] = signal.signal(signal.SIGTSTP, on_suspend)
    try:
        yield requests
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def suspend() -> None:
    """Stop this process now (the robot must already be stopped); returns after SIGCONT."""
    os.kill(os.getpid(), signal.SIGSTOP)


def leave_interrupts_to_the_parent() -> None:
    """In a worker process: ignore SIGINT (its parent gets the same Ctrl-C and ends the work)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def raise_interrupt(signum: int, frame: FrameType | None) -> None:
    """A signal handler that turns the signal into KeyboardInterrupt (SIGTERM ends a simulation
    command as Ctrl-C does)."""
    raise KeyboardInterrupt
