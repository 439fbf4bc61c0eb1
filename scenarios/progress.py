"""Progress of the long commands (`demo`, `sim`, `campaign`, `replay`, `survey`) on stderr, one
way for all.

On a terminal: tqdm's bar, redrawn in place. Without one (a pipe, a CI log, `| tee`): a plain
line every `PLAIN_EVERY_S` seconds (the first after `FIRST_LINE_S`), each complete in itself:

    campaign default: 12/20 runs (60%), 0.45 runs/s, ETA 18 s  safe_halt=10 nominal=2

and, when at least one such line was printed, a last one when the work ends. A piped command is
never silent for long, and a short one prints nothing extra.

The rate is measured on this session's work only (a resumed campaign's stored runs are not
counted), from the start, or with `warm_up` from the first update (a simulation's set-up is
not work, and counted as work it made the first estimate many times too long). Until it can be
measured the line says it is estimating, not "0 runs/s, ETA unknown". With `at_most` (a
simulation that may halt long before its time limit) the ETA is an upper bound and says so.

Wall time is read here for display only (`clock`, injectable); it never feeds a simulation.
Never raises on a closed or broken stream: progress is not worth failing a run for.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from types import TracebackType
from typing import Any, TextIO

#: Without a terminal: a progress line at least this often, s.
PLAIN_EVERY_S = 5.0
#: ... and the first one this soon after the start (a slow start still says it started).
FIRST_LINE_S = 1.0


def _count(value: float) -> float:
    """Whole counts as int (tqdm then writes 5/20, not 5.0/20)."""
    return int(value) if float(value).is_integer() else value


def _rate(per_s: float) -> str:
    return f"{per_s:.0f}" if per_s >= 100 else f"{per_s:.2g}"


def _duration(seconds: float) -> str:
    seconds = max(0.0, seconds)
    if seconds < 60:
        return f"{seconds:.0f} s"
    minutes, secs = divmod(int(round(seconds)), 60)
    if minutes < 60:
        return f"{minutes} min {secs:02d} s"
    hours, minutes = divmod(minutes, 60)
    return f"{hours} h {minutes:02d} min"


class Progress:
    """done/total of one piece of work. `unit`: what is counted ("run", "step", "s simulated");
    `fmt`: how a count is written; `initial`: done before this session (a resumed campaign's
    stored runs: not in the rate); `at_most`: the work may end anywhere before `total` (a
    simulation that halts) and ends by this count at the latest (its time limit and the
    overtime a run still DEGRADED there may take), so the ETA is an upper bound, the time to
    reach it at the rate so far; `warm_up`: the time before the first update is set-up, not
    work, so the rate is measured from the first update on (no estimate before the second).
    `terminal` (default: the stream is one) picks the bar or the lines; `enabled=False` shows
    nothing; `bar_format`: tqdm's, for the bar; `leave`: the bar stays on the terminal when the
    work ends (else it is wiped, for a command whose last lines are its result); `heartbeat`:
    without a terminal, a thread prints the line when it is due even while nothing advances (a
    campaign waiting for its first runs)."""

    def __init__(self, total: float, desc: str, unit: str, *, initial: float = 0.0,
                 enabled: bool = True, stream: TextIO | None = None,
                 terminal: bool | None = None, clock: Callable[[], float] = time.monotonic,
                 every_s: float | None = None, position: int = 0, fmt: str = "{:.0f}",
                 at_most: float | None = None, warm_up: bool = False,
                 bar_format: str | None = None, leave: bool = True,
                 heartbeat: bool = False) -> None:
        self.total = total
        self.desc = desc
        self.unit = unit
        self.done = initial
        self._stream = stream if stream is not None else sys.stderr
        self._clock = clock
        self._every_s = PLAIN_EVERY_S if every_s is None else every_s
        self._fmt = fmt
        self._at_most = at_most
        self._postfix = ""
        self._started = clock()
        #: (time, done) the rate is measured from; with warm_up, set at the first update
        self._rate_from: tuple[float, float] | None = None if warm_up else (
            self._started, initial)
        self._next_line_s = self._started + min(FIRST_LINE_S, self._every_s)
        self._lines = 0
        self._closed = False
        if terminal is None:
            try:
                terminal = self._stream.isatty()
            except (AttributeError, ValueError):
                terminal = False
        self.terminal = bool(terminal)
        self._plain = enabled and not self.terminal
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._ticker: threading.Thread | None = None
        self._bar: Any = None
        if self._plain and heartbeat:
            self._ticker = threading.Thread(target=self._beat, name="progress", daemon=True)
            self._ticker.start()
        if enabled and self.terminal:
            from tqdm import tqdm

            self._bar = tqdm(total=_count(total), initial=_count(initial), desc=desc, unit=unit,
                             file=self._stream, position=position, leave=leave,
                             dynamic_ncols=True, bar_format=bar_format)

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close(finished=exc_type is None)

    # ---- feeding it --------------------------------------------------------------------------
    def update(self, amount: float = 1.0) -> None:
        self.advance_to(self.done + amount)

    def advance_to(self, done: float) -> None:
        step = done - self.done
        self.done = done
        if self._rate_from is None and self._plain:
            self._rate_from = (self._clock(), done)
        if self._bar is not None:
            self._bar.update(_count(step))
        else:
            self.tick()

    def tick(self) -> None:
        """Without a terminal: print the line if it is due."""
        with self._lock:
            if not self._plain or self._closed:
                return
            now = self._clock()
            if now >= self._next_line_s:
                self._next_line_s = now + self._every_s
                self._write(self.line(now))

    def _beat(self) -> None:
        while not self._stop.wait(min(1.0, self._every_s)):
            self.tick()

    def set_total(self, total: float) -> None:
        """The real total once known (a simulation that ended before its time limit)."""
        self.total = total
        if self._bar is not None:
            self._bar.total = total
            self._bar.refresh()

    def set_postfix(self, text: str) -> None:
        self._postfix = text
        if self._bar is not None:
            self._bar.set_postfix_str(text, refresh=False)

    def close(self, finished: bool = True) -> None:
        """End the bar; without a terminal, a last line when lines were printed."""
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join(timeout=2.0)
        with self._lock:
            if self._closed:
                return
            self._closed = True
            if self._bar is not None:
                self._bar.close()
            elif self._plain and self._lines and finished:
                self._write(self.line(self._clock(), final=True))

    # ---- the line ----------------------------------------------------------------------------
    def line(self, now: float, final: bool = False) -> str:
        """'desc: 12/20 runs (60%), 0.45 runs/s, ETA 18 s  postfix'; 'ETA at most 40 s (if it
        runs to its limit)' with `at_most`; 'estimating the time left (6 s so far)' until this
        session's rate can be measured."""
        elapsed = max(now - self._started, 1e-9)
        counts = f"{self._fmt.format(self.done)}/{self._fmt.format(self.total)} {self.unit}"
        share = f" ({100.0 * self.done / self.total:.0f}%)" if self.total > 0 else ""
        rate = self.rate(now)
        if final:
            text = f"{self.desc}: done, {counts} in {_duration(elapsed)}"
        elif rate is None:
            text = (f"{self.desc}: {counts}{share}, estimating the time left "
                    f"({_duration(elapsed)} so far)")
        else:
            text = f"{self.desc}: {counts}{share}, {_rate(rate)} {self.unit}/s, "
            if self._at_most is None:
                text += f"ETA {_duration(max(self.total - self.done, 0.0) / rate)}"
            else:
                left = max(self._at_most - self.done, 0.0) / rate
                text += f"ETA at most {_duration(left)} (if it runs to its limit)"
        return f"{text}  {self._postfix}" if self._postfix else text

    def rate(self, now: float) -> float | None:
        """This session's work per second, measured since the start (with `warm_up`: since the
        first update); None while nothing was measured."""
        if self._rate_from is None:
            return None
        since, done_then = self._rate_from
        if self.done <= done_then or now <= since:
            return None
        return (self.done - done_then) / (now - since)

    def _write(self, text: str) -> None:
        try:
            self._stream.write(text + "\n")
            self._stream.flush()
        except (OSError, ValueError):
            self._plain = False  # the stream went away: the work goes on without it
            return
        self._lines += 1
