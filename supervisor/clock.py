"""The one clock abstraction: monotonic seconds on a robot, a hand-advanced fake in tests and sims.

Logic never calls this: it receives `now`. Only the robot's ticker (lanewarden/ticker.py, for
`run` and `base drive`), `base info`'s rate window and real driver threads ask a
`MonotonicClock`; tests and simulations own a `FakeClock` and advance it explicitly, so every run
can be replayed. Never sleep here.
"""

from __future__ import annotations

import math
import time
from typing import Protocol


class Clock(Protocol):
    def now(self) -> float:
        """Seconds on a monotonic time base (the origin is arbitrary)."""


class MonotonicClock:
    """`time.monotonic()`: for the robot's ticker and `base info` only (see above)."""

    def now(self) -> float:
        return time.monotonic()


class FakeClock:
    """A clock that moves only when told to. `advance(dt)` returns the new time."""

    def __init__(self, start: float = 0.0) -> None:
        if not math.isfinite(start):
            raise ValueError(f"FakeClock start must be finite, got {start!r}")
        self._now = float(start)

    def now(self) -> float:
        return self._now

    def advance(self, dt: float) -> float:
        if not (math.isfinite(dt) and dt >= 0.0):
            raise ValueError(f"FakeClock.advance: dt must be finite and >= 0, got {dt!r}")
        self._now += float(dt)
        return self._now
