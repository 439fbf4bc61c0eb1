"""The robot's real-time pace: where Lanewarden's control code reads the monotonic clock.

`lanewarden run` (runner.py) and `lanewarden base drive` step their `ControlLoop` through one
`Ticker` each: `now()` reads CLOCK_MONOTONIC (through `supervisor.clock.MonotonicClock`) and is
handed to everything else as `now` or as a clock callable; `wait()` sleeps until the next tick. A
step that overran its tick restarts the schedule from now: the watchdog sees the late step, and no
burst of catch-up steps follows. Simulations and tests never use it: they step the same loop on a
FakeClock, faster than real time.

Outside the control path only these read a clock: the dead-man process and its link (heartbeats
are CLOCK_MONOTONIC stamps by protocol, docs/actuation.md), the operator's displays (the status
line's and the live view's refresh), `base info`'s feedback-rate window, and wall-time figures in
reports. Never used by logic: logic takes `now`.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from lanewarden.supervisor.clock import Clock, MonotonicClock

#: While a wait can be cut short (`Ticker.wait`'s `interrupted`), it sleeps in slices at most
#: this long, asking between them: a stop signal (Ctrl-C) is acted on within this, not at the
#: next tick (`base drive` ticks every 50 ms: a new user's Ctrl-C still let two more motion
#: packets out, the first stop 32-39 ms later).
WAKE_SLICE_S = 0.005


class Ticker:
    """A schedule of ticks `period_s` apart on the monotonic clock, started by `restart()`."""

    def __init__(self, period_s: float, clock: Clock | None = None,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        self.period_s = period_s
        self._clock = clock or MonotonicClock()
        self._sleep = sleep  # (a test's fake clock advances itself instead)
        self._next_s = self._clock.now()

    def now(self) -> float:
        return self._clock.now()

    def restart(self) -> float:
        """Start the schedule now; returns now."""
        self._next_s = self._clock.now()
        return self._next_s

    def wait(self, until_s: float | None = None,
             interrupted: Callable[[], bool] | None = None) -> bool:
        """Sleep until the next tick (or `until_s`, if that comes first). An overrun (the next
        tick already past) does not sleep, and the schedule restarts from now. With
        `interrupted` (e.g. "a stop signal came"), asked before sleeping and every
        WAKE_SLICE_S while asleep: the wait ends as soon as it says so. Returns whether it did
        (the schedule is kept: the caller is about to stop)."""
        self._next_s += self.period_s
        wake_s = self._next_s if until_s is None else min(self._next_s, until_s)
        delay = wake_s - self._clock.now()
        if delay <= 0:
            if wake_s == self._next_s:
                self._next_s = self._clock.now()
            return False
        if interrupted is None:
            self._sleep(delay)
            return False
        while delay > 0:
            if interrupted():
                return True
            self._sleep(min(delay, WAKE_SLICE_S))
            delay = wake_s - self._clock.now()
        return interrupted()
