"""Only a lane of both its edges steers the centring (supervisor/center_offset.py).

A lane placed from one tape (`sides_seen` 1), or one whose two edges run more than
`center_max_edge_angle_deg` (30) apart on the floor, leaves the centring to relax towards
straight ahead (the same low-pass, towards 0) instead of following it: in campaign runs such lanes
read the lane turning the wrong way and steered the robot into a tape (docs/campaigns.md).
Default config: 30 frames a second, centring time constant 0.1 s, preview 0.36 m."""

from __future__ import annotations

import math
from dataclasses import replace
from types import MappingProxyType

import pytest

from lanewarden.perception.observation import LaneObservation
from lanewarden.supervisor.center_offset import CenterOffsetFilter, lane_steers
from lanewarden.supervisor.config import SupervisorConfig
from tests.supervisor.rig import DT, Rig, observation

CONFIG = SupervisorConfig()


def headed(left_deg: float | None, right_deg: float | None,
           lane_offset_m: float = 0.0, index: int = 0, time_s: float = 0.0) -> LaneObservation:
    """Both edges seen, with these floor headings (None: not measured on the floor)."""
    obs = observation(index, time_s, lane_offset_m=lane_offset_m)
    assert obs.left is not None and obs.right is not None
    return replace(obs,
                   left=replace(obs.left, heading_rad=None if left_deg is None
                                else math.radians(left_deg)),
                   right=replace(obs.right, heading_rad=None if right_deg is None
                                 else math.radians(right_deg)))


def placed(index: int = 0, time_s: float = 0.0, lane_offset_m: float = 0.0) -> LaneObservation:
    """A lane perception placed from one tape (`perception.one_side`)."""
    return replace(observation(index, time_s, lane_offset_m=lane_offset_m),
                   components=MappingProxyType({"both_sides": 0.5}))


@pytest.mark.parametrize(("left_deg", "right_deg", "steers"), [
    (0.0, 0.0, True),
    (-10.0, 18.0, True),     # 28 degrees apart: a sharp bend's near parts
    (-14.0, 16.5, False),    # 30.5 apart: r00910's patch and tape ran 25-40 apart
    (12.0, -20.0, False),
    (None, 40.0, True),      # not measured on the floor: nothing to compare
])
def test_a_lane_steers_only_with_both_edges_running_alike(
        left_deg: float | None, right_deg: float | None, steers: bool) -> None:
    assert lane_steers(headed(left_deg, right_deg), CONFIG.center_max_edge_angle_deg) is steers


def test_a_lane_placed_from_one_tape_never_steers() -> None:
    assert not lane_steers(placed(), 180.0)
    assert lane_steers(observation(0, 0.0), 180.0)


def test_relaxing_is_the_same_low_pass_towards_straight_ahead() -> None:
    centre = CenterOffsetFilter(CONFIG)
    assert centre.step(0.0, 0.2, 0.0) == 0.2
    assert centre.relax(0.1) == pytest.approx(0.2 * math.exp(-1.0))   # 0.073576 after one tau
    assert centre.relax(0.2) == pytest.approx(0.2 * math.exp(-2.0))   # 0.027067
    assert centre.step(0.3, 0.2, 0.0) == pytest.approx(0.2 + (0.2 * math.exp(-2.0) - 0.2)
                                                       * math.exp(-1.0))


#: After three frames the low-pass has moved this share of the way to what it is given.
THREE_FRAMES = 1.0 - math.exp(-3 * DT / 0.1)  # 0.632


def _following(rig: Rig, lane_offset_m: float) -> tuple[float, float]:
    """Engage, then follow a lane `lane_offset_m` to the left for a second: (the command's
    angular speed, the centring's value: lane_offset_m x (1 - exp(-10)), 0.099995 for 0.1)."""
    rig.engage()
    for _ in range(30):
        out = rig.step(lane_offset_m=lane_offset_m)
    assert out.filtered_center_offset is not None
    assert out.filtered_center_offset == pytest.approx(lane_offset_m * (1.0 - math.exp(-10.0)))
    return out.command.angular_rad_s, out.filtered_center_offset


def test_a_placed_lane_lets_the_steering_relax_instead_of_follow() -> None:
    """Following a lane centred 0.1 m to the left, then three frames of a lane placed from one
    tape saying the same: the centring falls by exp(-3 x DT / 0.1), to 0.0368 m (it would
    stay at 0.1 following them), and the robot turns left less."""
    rig = Rig()
    turning, before = _following(rig, 0.1)
    assert turning > 0.0
    for _ in range(3):
        now = rig.clock.now() + DT
        out = rig.step(obs=placed(rig.index + 1, now, lane_offset_m=0.1))
    assert out.filtered_center_offset == pytest.approx(before * (1.0 - THREE_FRAMES))
    assert out.filtered_center_offset == pytest.approx(0.036786, abs=1e-6)
    assert 0.0 < out.command.angular_rad_s < turning


@pytest.mark.parametrize(("right_deg", "follows"), [
    (20.0, True),     # 20 apart: still the lane, followed
    (40.0, False),    # 40 apart: relaxes
])
def test_a_lane_whose_edges_run_apart_lets_the_steering_relax(right_deg: float,
                                                              follows: bool) -> None:
    rig = Rig()
    _, before = _following(rig, 0.1)
    for _ in range(3):
        now = rig.clock.now() + DT
        out = rig.step(obs=headed(0.0, right_deg, 0.1, rig.index + 1, now))
    towards = 0.1 if follows else 0.0
    assert out.filtered_center_offset == pytest.approx(before + (towards - before) * THREE_FRAMES)


def test_the_limit_is_the_configs() -> None:
    rig = Rig(SupervisorConfig(center_max_edge_angle_deg=45.0))
    _, before = _following(rig, 0.1)
    for _ in range(3):
        now = rig.clock.now() + DT
        out = rig.step(obs=headed(0.0, 40.0, 0.1, rig.index + 1, now))
    assert out.filtered_center_offset == pytest.approx(before + (0.1 - before) * THREE_FRAMES)
