"""NullBase: a base that moves nothing and reports what would have been sent (`run --base none`).

For bench-testing the whole pipeline on a recorded clip or the live camera with no robot: its
feedback is always fresh (received at the caller's `now`), has no hazard bits and no battery
reading, and its odometry stays at the origin; every command is kept (`last_command`, counts) so
the runner can show what the wheels would have been told.

Never reads a clock and never sleeps.
"""

from __future__ import annotations

import threading

from lanewarden.actuation.base import STOP, BaseFeedback, Pose2D, VelocityCommand
from lanewarden.actuation.errors import ActuationError
from lanewarden.actuation.kobuki_geometry import require_finite


class NullBase:
    """Sends nothing anywhere. Safe to call from several threads (the runner's operator stop)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._last = STOP
        self._sent = 0
        self._motion = 0
        self._closed = False

    def send(self, command: VelocityCommand, now: float) -> None:
        """Keep `command` as what would be sent. Non-finite: kept as stop, then ActuationError
        (as the real base does)."""
        with self._lock:
            if self._closed:
                raise ActuationError("null base: closed")
            try:
                require_finite(command)
            except ActuationError:
                self._last = STOP
                raise
            self._last = command
            self._sent += 1
            self._motion += 0 if command.is_stop else 1

    def feedback(self, now: float) -> BaseFeedback:
        """Always fresh: received at `now`, no hazards, no battery, odometry at the origin."""
        return BaseFeedback(received_at_s=now, odometry=Pose2D())

    def close(self) -> None:
        with self._lock:
            self._last = STOP
            self._closed = True

    @property
    def last_command(self) -> VelocityCommand:
        """What the wheels would be doing now (stop after close)."""
        with self._lock:
            return self._last

    @property
    def commands_sent(self) -> int:
        with self._lock:
            return self._sent

    @property
    def motion_commands_sent(self) -> int:
        """How many of the sent commands were not a stop."""
        with self._lock:
            return self._motion
