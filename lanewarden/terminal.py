"""The run's terminal: a one-line live status, and keys s = start, space = stop, r = resume.

- `format_status` (pure): state and reason, fps, confidence, slope sum, speed, battery in one line.
- `StatusPrinter`: on a terminal, rewrites one line in place a few times a second; otherwise
  (a pipe, a log file) prints a plain line when the state or its reason changes and every
  `PLAIN_EVERY_S` seconds. It prints from its own thread (the newest status replaces one not yet
  printed), so a slow or stalled terminal never holds up the control loop. A warning goes to
  stderr as one line, and to stdout too unless both are the same terminal.
- `KeyReader`: reads single keys in cbreak mode (no Enter needed, no echo; Ctrl-C still sends
  SIGINT) from its own thread, and restores the terminal's settings on every way out (the context
  manager's exit, which the runner reaches on a normal end, an error, Ctrl-C or SIGTERM).
"""

from __future__ import annotations

import os
import select
import shutil
import sys
import termios
import threading
import time
import tty
from collections import deque
from collections.abc import Callable
from types import TracebackType
from typing import Any, TextIO

from lanewarden.perception.observation import weakest_component

#: Refresh rate of the in-place status line, Hz.
TTY_REFRESH_HZ = 5.0
#: Without a terminal: a status line at least this often (and on every state change), s.
PLAIN_EVERY_S = 5.0
KEY_HELP = "keys: s start, space stop, r resume, Ctrl-C end"
#: Operator messages waiting for the terminal beyond this are dropped (oldest first).
MAX_PENDING_MESSAGES = 100


def _num(value: Any, fmt: str, missing: str = "-") -> str:
    return missing if value is None else format(value, fmt)


def format_status(status: dict[str, Any]) -> str:
    """One line: 'FOLLOW  30.0 fps  conf 0.82 (weakest lane_width 0.75)  slope +1.20/+1.05  v 0.20
    w +0.05  battery 16.2 V  link ok' (HALT shows its reason's event name; the weakest confidence
    component below 1 says what holds perception back, e.g. while nothing engages). The run's
    last status has its end reason (`end_reason`, run_outcome.py): 'ENDED: safety stop:
    LANE_LOST: ...' in place of the state."""
    state = str(status.get("state"))
    reason = status.get("halt_reason")
    if status.get("end_reason"):
        state = f"ENDED: {status['end_reason']}"
    elif state == "HALT" and reason:
        state = f"HALT ({str(reason).split(':')[0]})"
    command = status.get("command") or {}
    raw = _num(status.get("slope_sum"), "+.2f")
    filtered = _num(status.get("filtered_slope_sum"), "+.2f")
    linear = _num(command.get("linear_m_s"), ".2f")
    angular = _num(command.get("angular_rad_s"), "+.2f")
    confidence = f"conf {_num(status.get('confidence'), '.2f')}"
    weakest = weakest_component(status.get("components") or {})
    if weakest is not None:
        confidence += f" (weakest {weakest[0]} {weakest[1]:.2f})"
    parts = [
        state,
        f"{_num(status.get('fps'), '.1f')} fps",
        confidence,
        f"slope {raw}/{filtered}",
        f"v {linear} w {angular}",
        f"battery {_num(status.get('battery_v'), '.1f', '?')} V",
        f"link {status.get('base_link', '?')}",
    ]
    if status.get("would_send"):
        parts.append("(base none: nothing sent)")
    return "  ".join(parts)


def _same_terminal(a: TextIO, b: TextIO) -> bool:
    try:
        return a.isatty() and b.isatty() and os.path.sameopenfile(a.fileno(), b.fileno())
    except (OSError, ValueError):  # no file descriptor (a test's capture, a StringIO)
        return False


class StatusPrinter:
    """Prints the status from its own thread; `publish` and `message` only hand over a reference
    (the newest status replaces an unprinted one; messages are all printed, in order)."""

    def __init__(self, stream: TextIO, *, tty_mode: bool | None = None,
                 err: TextIO | None = None) -> None:
        self._stream = stream
        self._err = err if err is not None else sys.stderr
        self.tty_mode = stream.isatty() if tty_mode is None else tty_mode
        self._cond = threading.Condition()
        self._status: dict[str, Any] | None = None
        #: (text, a warning: also on stderr)
        self._messages: deque[tuple[str, bool]] = deque(maxlen=MAX_PENDING_MESSAGES)
        self._closed = False
        self._last_key: tuple[object, object, object] | None = None
        self._last_plain_s = -float("inf")
        self._width = 0
        self._thread = threading.Thread(target=self._run, name="status-line", daemon=True)
        self._thread.start()

    def publish(self, status: dict[str, Any]) -> None:
        with self._cond:
            self._status = status
            self._cond.notify()

    def message(self, text: str) -> None:
        """A line of its own (an operator request, say), above the status line."""
        with self._cond:
            self._messages.append((text, False))
            self._cond.notify()

    def warning(self, text: str) -> None:
        """A line of its own on stderr (where a script or a log collects what went wrong), and
        above the status line on stdout unless that is the same terminal."""
        with self._cond:
            self._messages.append((text, True))
            self._cond.notify()

    def _run(self) -> None:
        period = 1.0 / TTY_REFRESH_HZ
        while True:
            with self._cond:
                self._cond.wait_for(
                    lambda: self._closed or self._messages or self._status is not None, 1.0)
                messages = list(self._messages)
                self._messages.clear()
                status, self._status = self._status, None
                closed = self._closed
            try:
                for text, warning in messages:
                    self._write_line(text, warning)
                if status is not None:
                    self._show(status)
            except (OSError, ValueError):
                return  # the terminal went away: the run goes on without it
            if closed:
                return
            if self.tty_mode and status is not None:
                time.sleep(period)  # this thread's own pace; newer statuses replace older ones

    def _show(self, status: dict[str, Any]) -> None:
        line = format_status(status)
        if self.tty_mode:
            width = shutil.get_terminal_size((100, 20)).columns - 1
            line = line[:width]
            self._stream.write("\r" + line.ljust(self._width) + "\r" + line)
            self._width = len(line)
            self._stream.flush()
            return
        key = (status.get("state"), status.get("halt_reason"), status.get("end_reason"))
        now = time.monotonic()
        if key != self._last_key or now - self._last_plain_s >= PLAIN_EVERY_S:
            self._last_key, self._last_plain_s = key, now
            self._stream.write(f"[{status.get('time_s', 0.0):7.2f} s] {line}\n")
            self._stream.flush()

    def _write_line(self, text: str, warning: bool = False) -> None:
        if self.tty_mode and self._width:
            self._stream.write("\r" + " " * self._width + "\r")
            self._stream.flush()
            self._width = 0
        if warning:
            self._err.write(text + "\n")
            self._err.flush()
            if _same_terminal(self._stream, self._err):
                return
        self._stream.write(text + "\n")
        self._stream.flush()

    def close(self) -> None:
        """Print what is pending, stop the thread; on a terminal, end the status line."""
        with self._cond:
            self._closed = True
            self._cond.notify()
        self._thread.join(timeout=2.0)
        if self.tty_mode and self._width:
            try:
                self._stream.write("\n")
                self._stream.flush()
            except (OSError, ValueError):
                pass


class KeyReader:
    """Single keys from a terminal's stdin, handed to `on_key` from a reader thread.

    Does nothing when stdin is not a terminal. Use as a context manager: the terminal's settings
    are restored on exit, whatever the way out."""

    def __init__(self, on_key: Callable[[str], None], stream: TextIO | None = None) -> None:
        self._on_key = on_key
        self._stream = stream if stream is not None else sys.stdin
        self._saved: list[Any] | None = None
        self._paused: list[Any] | None = None
        self._running = threading.Event()
        self._thread: threading.Thread | None = None
        self._fd = -1

    @property
    def active(self) -> bool:
        return self._thread is not None

    def __enter__(self) -> KeyReader:
        try:
            if not self._stream.isatty():
                return self
            self._fd = self._stream.fileno()
            self._saved = termios.tcgetattr(self._fd)
            tty.setcbreak(self._fd)
        except (OSError, ValueError, termios.error):
            return self
        self._running.set()
        self._thread = threading.Thread(target=self._run, name="keys", daemon=True)
        self._thread.start()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self._running.clear()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
            self._thread = None
        self.restore()

    def pause(self) -> None:
        """Give the terminal back as it was (before Ctrl-Z suspends the process: the shell
        gets a normal terminal); `resume()` takes it again."""
        saved = self._saved
        self.restore()
        self._paused = saved

    def resume(self) -> None:
        """After SIGCONT: cbreak mode again (the shell may have changed the settings)."""
        if self._paused is None:
            return
        try:
            self._saved = termios.tcgetattr(self._fd)
            tty.setcbreak(self._fd)
        except (OSError, termios.error):
            self._saved = None
        self._paused = None

    def restore(self) -> None:
        """Put the terminal back as it was (idempotent)."""
        if self._saved is not None:
            try:
                termios.tcsetattr(self._fd, termios.TCSADRAIN, self._saved)
            except (OSError, termios.error):
                pass
            self._saved = None

    def _run(self) -> None:
        while self._running.is_set():
            try:
                ready, _, _ = select.select([self._fd], [], [], 0.1)
                if not ready:
                    continue
                data = os.read(self._fd, 32)
            except OSError:
                return
            if not data:
                return
            for key in data.decode("utf-8", "replace"):
                self._on_key(key)


def key_action(key: str) -> str | None:
    """What a key asks for: 'start', 'stop', 'resume', or None."""
    return {"s": "start", "S": "start", " ": "stop", "r": "resume", "R": "resume"}.get(key)
