"""The centring signal: where the lane's centre line lies ahead of the robot, low-passed.

Perception reports the lane's centre line on the floor in the robot frame (`LaneObservation`:
`lane_offset_m`, its signed distance from the robot's centre, left +; `lane_heading_rad`, its
direction relative to the robot's heading, left +). The centring steers towards the point of
that line `center_preview_m` ahead of the robot's centre: its lateral position `y` (metres, left +)
combines both, so the gain is the same for every camera. `y` goes through a first-order low-pass
(`center_offset_time_constant_s`). A frame without a lane centre leaves the value where it was:
the steering that uses it is bounded in DEGRADED and the lane-lost timer halts a blind robot
anyway. Pure: time comes with each call.
"""

from __future__ import annotations

import math

from lanewarden.supervisor.config import SupervisorConfig

#: Headings beyond this (the lane nearly across the robot's path) are taken as this when the
#: preview point is computed, so it stays finite; such a lane is not followed anyway.
MAX_PREVIEW_HEADING_RAD = math.radians(60.0)


def preview_heading(heading_rad: float) -> float:
    """`heading_rad` within +-MAX_PREVIEW_HEADING_RAD, as lines are read ahead of the robot."""
    return max(-MAX_PREVIEW_HEADING_RAD, min(MAX_PREVIEW_HEADING_RAD, heading_rad))


def lateral_offset_at(offset_m: float, heading_rad: float, distance_m: float) -> float:
    """The lateral position (metres, left +) where the line at signed distance `offset_m` from
    the robot's centre, running at `heading_rad` (`preview_heading`), crosses x = `distance_m`
    (robot frame)."""
    heading = preview_heading(heading_rad)
    return offset_m / math.cos(heading) + distance_m * math.tan(heading)


class CenterOffsetFilter:
    def __init__(self, config: SupervisorConfig) -> None:
        self._tau_s = config.center_offset_time_constant_s
        self._preview_m = config.center_preview_m
        self._value: float | None = None
        self._time_s: float | None = None

    @property
    def value(self) -> float | None:
        """Filtered lateral position of the lane centre `center_preview_m` ahead, metres, left
        +; None before the first measurement."""
        return self._value

    def step(self, time_s: float, offset_m: float | None,
             heading_rad: float | None) -> float | None:
        if offset_m is None or heading_rad is None or not (
            math.isfinite(offset_m) and math.isfinite(heading_rad)
        ):
            return self._value
        measured = lateral_offset_at(offset_m, heading_rad, self._preview_m)
        if self._value is None or self._time_s is None or self._tau_s == 0.0:
            self._value = measured
        else:
            dt = max(0.0, time_s - self._time_s)
            alpha = 1.0 - math.exp(-dt / self._tau_s)
            self._value += alpha * (measured - self._value)
        self._time_s = time_s
        return self._value
