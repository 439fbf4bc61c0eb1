"""The centring signal: where the lane's centre line lies ahead of the robot, low-passed.

Perception reports the lane's centre line on the floor in the robot frame (`LaneObservation`:
`lane_offset_m`, its signed distance from the robot's centre, left +; `lane_heading_rad`, its
direction relative to the robot's heading, left +). The centring steers towards the point of
that line `center_preview_m` ahead of the robot's centre: its lateral position `y` (metres, left +)
combines both, so the gain is the same for every camera. `y` goes through a first-order low-pass
(`center_offset_time_constant_s`). A frame without a lane centre leaves the value where it was:
the steering that uses it is bounded in DEGRADED and the lane-lost timer halts a blind robot
anyway.

A lane that is not both of the lane's edges does not steer (`lane_steers`): one placed from one
tape (`sides_seen` 1: the other edge is only the lane's width away from it by assumption), or
one whose two edges run more than `center_max_edge_angle_deg` apart on the floor (a lane's two
tapes run nearly parallel; a stray tape patch or a shadow taken for one edge need not). On such a
frame the value relaxes towards straight ahead (`relax`, the same low-pass towards 0) instead of
following it. In campaign runs such lanes read the lane turning the wrong way while the robot's
heading error grew to 30-50 degrees, and steered the robot into a tape (docs/campaigns.md, the
twenty-sixth run). Pure: time comes with each call.
"""

from __future__ import annotations

import math

from lanewarden.perception.observation import LaneObservation
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


def lane_steers(observation: LaneObservation, max_edge_angle_deg: float) -> bool:
    """Whether this lane may steer the centring: both of its edges seen (`sides_seen` 2) and, where
    both have a floor heading, running within `max_edge_angle_deg` of each other."""
    if observation.sides_seen != 2:
        return False
    left, right = observation.left, observation.right
    if left is None or right is None or left.heading_rad is None or right.heading_rad is None:
        return True
    return abs(math.degrees(left.heading_rad - right.heading_rad)) <= max_edge_angle_deg


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
        return self._follow(time_s, lateral_offset_at(offset_m, heading_rad, self._preview_m))

    def relax(self, time_s: float) -> float | None:
        """A frame whose lane may not steer (`lane_steers`): the value moves towards 0 (straight
        ahead) as it would follow a lane centred on the robot."""
        return self._follow(time_s, 0.0)

    def _follow(self, time_s: float, measured: float) -> float:
        if self._value is None or self._time_s is None or self._tau_s == 0.0:
            self._value = measured
        else:
            dt = max(0.0, time_s - self._time_s)
            alpha = 1.0 - math.exp(-dt / self._tau_s)
            self._value += alpha * (measured - self._value)
        self._time_s = time_s
        return self._value
