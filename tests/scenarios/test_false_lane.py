"""Ground truth for the lane the supervisor drove on (`scenarios.false_lane`): where a reported
edge lies on the floor, its distance from the real tapes, and the stretches on a false lane."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from lanewarden.perception.observation import LaneEdge, LaneObservation
from lanewarden.scenarios.false_lane import (
    FALSE_LANE_TOLERANCE_M,
    edge_point_robot,
    false_lane_metrics,
    frame_edge_errors,
)
from lanewarden.scenarios.world import build_world
from tests.scenarios.helpers import straight_spec

# the helper's straight lane: along world x from the origin, 0.6 m between tape centres, tapes
# 48 mm wide, so their inner edges run at y = +0.276 (left) and -0.276 (right)
INNER = 0.3 - 0.024


@dataclass(frozen=True)
class Step:
    state: str
    observation: LaneObservation | None
    lane_trusted: bool | None


def edge(offset_m: float, heading_deg: float = 0.0, near_m: float = 0.3) -> LaneEdge:
    return LaneEdge(0.0, 0.0, 0.0, 0.0, 0.0, offset_m=offset_m,
                    heading_rad=math.radians(heading_deg), near_m=near_m)


def seen(time_s: float, left: LaneEdge | None, right: LaneEdge | None) -> LaneObservation:
    return LaneObservation(0, time_s, left, right, 0.0, 1.0)


def test_an_edges_point_is_the_middle_of_its_near_part() -> None:
    # straight ahead: 5 cm past near_m (half of the 10 cm perception measures from), offset_m
    # to the side
    assert edge_point_robot(edge(0.2)) == pytest.approx((0.35, 0.2))
    # turned 30 degrees to the left: the point near_m ahead lies on the line offset_m from the
    # robot's centre (its distance from the centre along the line's normal)
    x, y = edge_point_robot(edge(0.2, 30.0))  # type: ignore[misc]
    assert x == pytest.approx(0.35)
    normal = (-math.sin(math.radians(30.0)), math.cos(math.radians(30.0)))
    assert x * normal[0] + y * normal[1] == pytest.approx(0.2)
    assert edge_point_robot(LaneEdge(0.0, 0.0, 0.0, 0.0, 0.0)) is None  # not measured


def test_edges_on_the_tapes_have_no_error_and_edges_off_them_their_distance() -> None:
    world = build_world(straight_spec(4.0))
    times = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    poses = np.array([[1.0, 0.0, 0.0]] * 5)
    steps = [
        Step("FOLLOW", seen(0.0, edge(INNER), edge(-INNER)), True),  # on the tapes' edges
        Step("FOLLOW", seen(0.1, edge(INNER + 0.15), edge(-INNER)), True),  # 0.10 m beyond
        Step("FOLLOW", seen(0.2, edge(INNER + 0.03), edge(-INNER - 0.04)), True),  # on the tapes
        Step("FOLLOW", seen(0.3, edge(INNER + 0.15), None), False),  # not trusted
        Step("HALT", seen(0.4, edge(INNER + 0.15), None), True),  # not engaged
    ]
    errors = frame_edge_errors(world, times, poses, steps)
    assert errors[0] == pytest.approx(0.0, abs=1e-9)
    assert errors[1] == pytest.approx(0.15 - 0.048, abs=1e-9)  # past the tape's far side
    assert errors[2] == pytest.approx(0.0, abs=1e-9)
    assert np.isnan(errors[3]) and np.isnan(errors[4])


def test_the_pose_is_the_one_when_the_frame_was_taken() -> None:
    """A frame judged late (its time before the step's): measured from the pose it was taken
    at. From the later pose, 0.2 m to the left, the same edge would lie 0.2 m off the tape."""
    world = build_world(straight_spec(4.0))
    times = np.array([0.0, 0.1])
    poses = np.array([[1.0, 0.0, 0.0], [1.0, 0.2, 0.0]])
    steps = [Step("FOLLOW", None, None), Step("FOLLOW", seen(0.0, edge(INNER), None), True)]
    assert frame_edge_errors(world, times, poses, steps)[1] == pytest.approx(0.0, abs=1e-9)


def test_a_dashed_lines_gaps_count_as_tape() -> None:
    world = build_world(straight_spec(4.0, dashes={"tape": "left", "on_m": 0.3, "off_m": 0.3}))
    # the left edge's point at x = 0.7 + 0.35 = 1.05: in the gap between dashes (0.9 to 1.2 m)
    steps = [Step("FOLLOW", seen(0.0, edge(INNER), edge(-INNER)), True)]
    errors = frame_edge_errors(world, np.array([0.0]), np.array([[0.7, 0.0, 0.0]]), steps)
    assert errors[0] == pytest.approx(0.0, abs=1e-9)


def test_stretches_on_a_false_lane() -> None:
    """Frames 1-2 and 5-7 are on a false lane; an unmeasured frame (6) does not break a
    stretch, a frame on the true lane (3) does."""
    times = np.arange(9) * 0.1
    errors = np.array([0.01, 0.2, 0.3, 0.0, np.nan, 0.1, np.nan, 0.09, 0.02])
    assert FALSE_LANE_TOLERANCE_M == 0.08
    assert false_lane_metrics(times, errors) == {
        "max_edge_error_m": 0.3, "false_lane_frames": 4, "false_lane_longest_s": 0.3}
    assert false_lane_metrics(times, np.full(9, np.nan)) == {
        "max_edge_error_m": None, "false_lane_frames": 0, "false_lane_longest_s": 0.0}
    assert false_lane_metrics(times, np.full(9, 0.08)) == {
        "max_edge_error_m": 0.08, "false_lane_frames": 0, "false_lane_longest_s": 0.0}
