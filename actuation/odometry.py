"""Wheel odometry from the Kobuki's u16 encoder counters (pure: successive readings in, pose out).

The counters wrap at 65536; the tick delta between two readings is taken modulo 2^16 as the
shortest signed step, which is right as long as a wheel moves less than half a counter range
(about 2.8 m) between readings — at 50 Hz and 0.7 m/s it moves 14 mm.

A step longer than MAX_WHEEL_STEP_M between two readings is taken as a counter's jump, not
motion. Never reads a port or a clock.
"""

from __future__ import annotations

from lanewarden.actuation.base import Pose2D
from lanewarden.actuation.kobuki_geometry import (
    TICKS_PER_METRE,
    WHEEL_BASE_M,
    integrate_arc,
    wrap_angle,
)

ENCODER_MODULUS = 1 << 16
#: A wheel step longer than this between two readings is no motion but a counter that jumped (a
#: damaged or hostile device: +30000 ticks a packet had made 468 m of odometry in 3.6 s); the
#: reading only becomes the new reference. 0.25 m is the Kobuki's top speed (0.7 m/s) over a
#: third of a second of packets lost.
MAX_WHEEL_STEP_M = 0.25


def encoder_delta(previous: int, current: int) -> int:
    """Signed tick change from `previous` to `current` on a wrapping u16 counter."""
    half = ENCODER_MODULUS // 2
    return (current - previous + half) % ENCODER_MODULUS - half


class EncoderOdometry:
    """Integrates successive (left, right) encoder readings into a pose in the start frame.

    The first reading only sets the reference (pose stays at the origin). Each later reading
    moves the pose along the arc the two wheel distances describe.
    """

    def __init__(self, ticks_per_metre: float = TICKS_PER_METRE,
                 wheel_base_m: float = WHEEL_BASE_M) -> None:
        self._ticks_per_metre = ticks_per_metre
        self._wheel_base_m = wheel_base_m
        self._last: tuple[int, int] | None = None
        #: readings passed over as a counter's jump (`MAX_WHEEL_STEP_M`)
        self.jumps = 0
        self._x = 0.0
        self._y = 0.0
        self._theta = 0.0

    def update(self, left_ticks: int, right_ticks: int) -> Pose2D:
        """Take one reading; return the pose after it."""
        if self._last is not None:
            left_m = encoder_delta(self._last[0], left_ticks) / self._ticks_per_metre
            right_m = encoder_delta(self._last[1], right_ticks) / self._ticks_per_metre
            if max(abs(left_m), abs(right_m)) > MAX_WHEEL_STEP_M:
                self.jumps += 1
            else:
                # integrate over a unit "time": distance and heading change are what matter
                distance = 0.5 * (left_m + right_m)
                turn = (right_m - left_m) / self._wheel_base_m
                self._x, self._y, theta = integrate_arc(self._x, self._y, self._theta,
                                                        distance, turn, 1.0)
                self._theta = wrap_angle(theta)
        self._last = (left_ticks, right_ticks)
        return self.pose

    @property
    def pose(self) -> Pose2D:
        return Pose2D(self._x, self._y, self._theta)
