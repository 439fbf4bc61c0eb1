"""When a simulated run is over."""

from __future__ import annotations

import pytest

from lanewarden.actuation.base import Pose2D
from lanewarden.config import LanewardenConfig
from lanewarden.scenarios.simulator import (
    NOT_ENGAGED_LIMIT_S,
    EndConditions,
    latest_time_s,
    tick_limits,
)
from lanewarden.scenarios.spec import RunSpec
from lanewarden.scenarios.world import build_world
from tests.scenarios.helpers import straight_spec


def test_halt_ends_the_run_once_settled_and_at_rest() -> None:
    world = build_world(straight_spec(4.0))
    ending = EndConditions(world, RunSpec(halt_settle_s=1.0))
    pose = Pose2D(1.0, 0.0, 0.0)
    assert ending.check(0.0, "HALT", pose, 0.0) is None  # not engaged yet: the initial HALT
    assert ending.check(0.1, "FOLLOW", pose, 0.2) is None
    assert ending.check(2.0, "HALT", pose, 0.1) is None
    assert ending.halt_time == 2.0
    assert ending.check(3.0, "HALT", pose, 0.01) is None  # settled, still rolling
    assert ending.check(3.1, "HALT", pose, 0.0) == "halted"


def test_never_engaged_leaving_the_floor_and_past_the_lane_end() -> None:
    world = build_world(straight_spec(4.0, ends={"left_m": 3.0, "right_m": 3.0}), margin_m=2.5)
    assert EndConditions(world, RunSpec()).check(NOT_ENGAGED_LIMIT_S, "HALT", Pose2D(), 0.0) == \
        "never engaged"
    assert EndConditions(world, RunSpec()).check(1.0, "FOLLOW", Pose2D(0.0, 2.6, 0.0), 0.2) == \
        "left the painted floor"
    ending = EndConditions(world, RunSpec(stop_past_lane_end_m=1.5))
    assert ending.check(1.0, "FOLLOW", Pose2D(4.4, 0.0, 0.0), 0.2) is None
    assert ending.check(1.1, "FOLLOW", Pose2D(4.5, 0.3, 0.0), 0.2) == "1.5 m past the lane end"


def test_the_time_limit_and_the_overtime_of_a_run_still_degraded_there() -> None:
    """Ticks 0 .. 1800 reach the 60 s limit at 30 Hz; a run DEGRADED there may take its 3 s
    budget (90 ticks) and two more. The progress line's 'at most' counts to the last one."""
    assert tick_limits(60.0, 30.0, 3.0) == (1801, 92)
    assert tick_limits(2.0, 15.0, 0.5) == (31, 10)
    config = LanewardenConfig.model_validate({"supervisor": {"degraded_budget_s": 3.0}})
    assert latest_time_s(config, RunSpec(max_time_s=60.0)) == pytest.approx(1892 / 30)
