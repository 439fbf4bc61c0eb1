"""First-order low-pass on the lane's centre offset (the centring term of the steering).

`center_offset` is in half image widths, positive when the lane centre lies right of the image
centre (see `LaneObservation`). A frame without a centre offset leaves the value where it was: the
steering that uses it is bounded in DEGRADED and the lane-lost timer halts a blind robot anyway.
Pure: time comes with each call.
"""

from __future__ import annotations

import math

from lanewarden.supervisor.config import SupervisorConfig


class CenterOffsetFilter:
    def __init__(self, config: SupervisorConfig) -> None:
        self._tau_s = config.center_offset_time_constant_s
        self._value: float | None = None
        self._time_s: float | None = None

    @property
    def value(self) -> float | None:
        """Filtered centre offset (half image widths), None before the first measurement."""
        return self._value

    def step(self, time_s: float, center_offset: float | None) -> float | None:
        if center_offset is None or not math.isfinite(center_offset):
            return self._value
        if self._value is None or self._time_s is None or self._tau_s == 0.0:
            self._value = float(center_offset)
        else:
            dt = max(0.0, time_s - self._time_s)
            alpha = 1.0 - math.exp(-dt / self._tau_s)
            self._value += alpha * (float(center_offset) - self._value)
        self._time_s = time_s
        return self._value
