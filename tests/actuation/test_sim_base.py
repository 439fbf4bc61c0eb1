"""SimBase kinematics and limits on injected time (the shared Base contract is elsewhere)."""

from __future__ import annotations

import math

import pytest

from lanewarden.actuation.base import STOP, Pose2D, VelocityCommand
from lanewarden.actuation.config import ActuationConfig, SimBaseConfig
from lanewarden.actuation.errors import ActuationError
from lanewarden.actuation.kobuki_geometry import MAX_ANGULAR_RAD_S
from lanewarden.actuation.sim_base import SimBase, SimBaseParams


def test_accelerates_at_the_limit_then_cruises() -> None:
    sim = SimBase()
    sim.send(VelocityCommand(0.3, 0.0), 0.0)
    sim.advance_to(0.5)
    assert sim.velocity.linear_m_s == pytest.approx(0.15)   # 0.3 m/s² for 0.5 s
    sim.advance_to(3.0)
    assert sim.velocity.linear_m_s == pytest.approx(0.3)
    # 1 s ramp (0.15 m) + 2 s at 0.3 m/s
    assert sim.pose.x_m == pytest.approx(0.15 + 0.6, abs=1e-6)
    assert sim.pose.y_m == pytest.approx(0.0, abs=1e-12)


def test_a_commanded_stop_brakes_harder_than_a_slow_down() -> None:
    braked, slowed = SimBase(), SimBase()
    for sim in (braked, slowed):
        sim.send(VelocityCommand(0.3, 0.0), 0.0)
        sim.advance_to(2.0)
    braked.send(STOP, 2.0)
    slowed.send(VelocityCommand(0.01, 0.0), 2.0)
    braked.advance_to(2.1)
    slowed.advance_to(2.1)
    assert braked.velocity.linear_m_s == pytest.approx(0.3 - 1.5 * 0.1)
    assert slowed.velocity.linear_m_s == pytest.approx(0.3 - 0.3 * 0.1)
    braked.advance_to(5.0)
    # 0.3 m/s stopped at 1.5 m/s²: 0.2 s and 0.03 m
    assert braked.velocity == VelocityCommand(0.0, 0.0)
    assert braked.pose.x_m == pytest.approx(0.15 + 0.3 + 0.03, abs=1e-6)


def test_speed_limits_scale_the_command_and_keep_its_curvature() -> None:
    sim = SimBase()
    sim.send(VelocityCommand(1.4, 1.0), 0.0)
    assert sim.commanded == VelocityCommand(0.7, 0.5)
    sim.send(VelocityCommand(0.1, 10.0), 0.0)
    assert sim.commanded.angular_rad_s == pytest.approx(MAX_ANGULAR_RAD_S)
    assert sim.commanded.linear_m_s / sim.commanded.angular_rad_s == pytest.approx(0.01)


def test_spin_in_place_reaches_the_turn_rate_and_stays_put() -> None:
    sim = SimBase(params=SimBaseParams(accel_angular_rad_s2=3.5))
    sim.send(VelocityCommand(0.0, 1.0), 0.0)
    sim.advance_to(1.0)
    assert sim.velocity.angular_rad_s == pytest.approx(1.0)
    ramp = 1.0 / 3.5
    assert sim.pose.theta_rad == pytest.approx(0.5 * ramp + (1.0 - ramp), abs=1e-6)
    assert (sim.pose.x_m, sim.pose.y_m) == (0.0, 0.0)


def test_a_full_circle_comes_back_to_the_start() -> None:
    params = SimBaseParams(accel_linear_m_s2=1e6, accel_angular_rad_s2=1e6)
    sim = SimBase(Pose2D(1.0, 2.0, 0.5), params)
    sim.send(VelocityCommand(0.5, 1.0), 0.0)
    sim.advance_to(math.pi)  # half a circle of radius 0.5
    half = sim.odometry
    assert (half.x_m, half.y_m) == pytest.approx((0.0, 1.0), abs=1e-4)
    sim.advance_to(2 * math.pi)
    assert (sim.pose.x_m, sim.pose.y_m, sim.pose.theta_rad) == pytest.approx(
        (1.0, 2.0, 0.5), abs=1e-4)


def test_odometry_is_in_the_start_frame() -> None:
    sim = SimBase(Pose2D(5.0, -1.0, math.pi / 2))
    sim.send(VelocityCommand(0.3, 0.0), 0.0)
    sim.advance_to(2.0)
    assert sim.pose.x_m == pytest.approx(5.0, abs=1e-9)
    assert sim.pose.y_m == pytest.approx(-1.0 + 0.45, abs=1e-6)
    odometry = sim.feedback(2.0).odometry
    assert (odometry.x_m, odometry.y_m, odometry.theta_rad) == pytest.approx(
        (0.45, 0.0, 0.0), abs=1e-6)


def test_time_only_moves_when_told_and_never_backwards() -> None:
    sim = SimBase()
    sim.send(VelocityCommand(0.3, 0.0), 10.0)  # the first `now` is the origin
    assert sim.pose == Pose2D()
    sim.advance_to(10.0)
    assert sim.pose == Pose2D()
    with pytest.raises(ActuationError, match="backwards"):
        sim.advance_to(9.0)


def test_cut_link_freezes_feedback() -> None:
    sim = SimBase()
    sim.send(VelocityCommand(0.2, 0.0), 0.0)
    alive = sim.feedback(1.0)
    sim.set_link_alive(False)
    sim.inject(bumper=1)
    frozen = sim.feedback(2.0)
    assert frozen == alive and frozen.received_at_s == 1.0
    assert sim.pose.x_m > alive.odometry.x_m  # the base itself kept driving
    sim.set_link_alive(True)
    back = sim.feedback(3.0)
    assert back.received_at_s == 3.0 and back.bumper == 1


@pytest.mark.parametrize("kwargs", [{"bumper": 8}, {"cliff": -1}, {"wheel_drop": 4}])
def test_inject_checks_bits(kwargs: dict[str, int]) -> None:
    with pytest.raises(ValueError, match="expected bits"):
        SimBase().inject(**kwargs)


def test_params_from_config() -> None:
    config = ActuationConfig(max_linear_m_s=0.5,
                             sim=SimBaseConfig(brake_linear_m_s2=3.0, battery_v=12.0))
    params = SimBaseParams.from_config(config)
    assert (params.max_linear_m_s, params.brake_linear_m_s2, params.battery_v) == (0.5, 3.0,
                                                                                  12.0)
    assert SimBaseParams.from_config(ActuationConfig()) == SimBaseParams()
