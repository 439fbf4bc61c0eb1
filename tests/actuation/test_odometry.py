"""Encoder odometry: straight, spin, arcs, and the u16 wrap-around in both directions."""

from __future__ import annotations

import math

import pytest

from lanewarden.actuation.kobuki_geometry import TICKS_PER_METRE, WHEEL_BASE_M
from lanewarden.actuation.odometry import EncoderOdometry, encoder_delta


@pytest.mark.parametrize(("previous", "current", "delta"), [
    (0, 10, 10), (10, 0, -10), (65530, 4, 10), (4, 65530, -10), (0, 32767, 32767),
    (0, 32768, -32768), (65535, 65535, 0),
])
def test_encoder_delta_wraps(previous: int, current: int, delta: int) -> None:
    assert encoder_delta(previous, current) == delta


def _ticks(metres: float) -> int:
    return round(metres * TICKS_PER_METRE)


def test_first_reading_only_sets_the_reference() -> None:
    odometry = EncoderOdometry()
    pose = odometry.update(40000, 1234)
    assert (pose.x_m, pose.y_m, pose.theta_rad) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("start", [0, 65000, 65535])
def test_straight_one_metre_across_the_wrap(start: int) -> None:
    odometry = EncoderOdometry()
    odometry.update(start, start)
    for i in range(1, 101):  # 1 cm per reading
        ticks = (start + _ticks(0.01 * i)) % 65536
        pose = odometry.update(ticks, ticks)
    assert pose.x_m == pytest.approx(1.0, abs=1e-3)
    assert pose.y_m == pytest.approx(0.0, abs=1e-9)
    assert pose.theta_rad == pytest.approx(0.0, abs=1e-9)


def test_backwards_across_the_wrap() -> None:
    odometry = EncoderOdometry()
    odometry.update(100, 100)
    for i in range(1, 51):
        ticks = (100 - _ticks(0.01 * i)) % 65536
        pose = odometry.update(ticks, ticks)
    assert pose.x_m == pytest.approx(-0.5, abs=1e-3)


def test_spin_in_place_quarter_turn() -> None:
    odometry = EncoderOdometry()
    odometry.update(0, 0)
    wheel_m = (math.pi / 2) * WHEEL_BASE_M / 2  # each wheel's arc for 90 degrees
    steps = 30
    for i in range(1, steps + 1):
        pose = odometry.update((-_ticks(wheel_m * i / steps)) % 65536,
                               _ticks(wheel_m * i / steps))
    assert pose.theta_rad == pytest.approx(math.pi / 2, abs=2e-3)
    assert math.hypot(pose.x_m, pose.y_m) < 1e-3


def test_half_circle_of_radius_half_a_metre() -> None:
    odometry = EncoderOdometry()
    odometry.update(0, 0)
    radius = 0.5
    left_total = math.pi * (radius - WHEEL_BASE_M / 2)
    right_total = math.pi * (radius + WHEEL_BASE_M / 2)
    for i in range(1, 201):
        pose = odometry.update(_ticks(left_total * i / 200) % 65536,
                               _ticks(right_total * i / 200) % 65536)
    assert pose.x_m == pytest.approx(0.0, abs=2e-3)
    assert pose.y_m == pytest.approx(2 * radius, abs=2e-3)
    assert abs(pose.theta_rad) == pytest.approx(math.pi, abs=2e-3)


def test_a_counter_that_jumps_is_no_motion() -> None:
    """An attacker's review: a device adding 30000 ticks a packet made 468 m of odometry in
    3.6 s. A step beyond MAX_WHEEL_STEP_M (0.25 m: about 2931 ticks) is passed over, and the
    motion after it counts from the new reading."""
    odometry = EncoderOdometry()
    odometry.update(0, 0)
    for k in range(1, 6):
        odometry.update(30000 * k % 65536, 30000 * k % 65536)
    assert odometry.pose.x_m == 0.0 and odometry.jumps == 5
    step = round(0.1 * TICKS_PER_METRE)  # then 0.1 m straight ahead
    last = 30000 * 5 % 65536
    odometry.update((last + step) % 65536, (last + step) % 65536)
    assert odometry.pose.x_m == pytest.approx(0.1, abs=1e-4) and odometry.jumps == 5
    odometry.update((last + step + 2900) % 65536, (last + step + 2900) % 65536)  # 0.247 m: motion
    assert odometry.jumps == 5
