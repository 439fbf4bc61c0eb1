"""A lane placed from one tape that jumps is not usable (supervisor/lane_evidence.py).

The twenty-seventh campaign's seed 1 r00278: at the lecture's corner A on parquet, with the white
line out of view, perception placed the lane from a slat it took for that line, and the placed
right edge read 0.11 and 0.21 m right of the robot by turns (the tape was 0.30-0.39 m away). The
robot cannot move 0.10 m sideways in a frame (at most `limiter_max_linear_m_s` 0.3 m/s x 1/30 s,
plus `lane_departure_jump_m` 0.03 m: 0.04 m), so such a frame is a slat, not the tape: it is not
usable (LANE_UNTRUSTED, no measurement for the slope filter, no reset of the lane-lost timer). A
placed lane that stays put, and a two-sided lane that jumps, stay usable.
"""

from __future__ import annotations

import math
from dataclasses import replace

from lanewarden.perception.observation import LaneEdge, LaneObservation
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.events import Event
from lanewarden.supervisor.lane_evidence import LaneEvidence
from tests.supervisor.rig import LEFT_EDGE, RIGHT_EDGE

DT = 1.0 / 30.0
PLACED = {"both_sides": 0.5}
SEEN = {"both_sides": 1.0}


def _edge(base: LaneEdge, offset: float) -> LaneEdge:
    return replace(base, offset_m=offset, heading_rad=math.radians(5.0), near_m=0.3)


def _lane(index: int, right_m: float, components: dict[str, float],
          confidence: float = 0.5) -> LaneObservation:
    """A lane 0.55 m wide (its left edge 0.55 m left of its right one), at frame `index`."""
    return LaneObservation(index, index * DT, _edge(LEFT_EDGE, right_m + 0.55),
                           _edge(RIGHT_EDGE, right_m), 0.25, confidence, components)


def test_a_placed_lane_that_jumps_is_not_usable() -> None:
    evidence = LaneEvidence(SupervisorConfig())
    first = evidence.assess(_lane(0, -0.21, PLACED))
    assert (first.usable, first.slope_sum) == (True, 0.25)
    assert first.events == {Event.ONE_EDGE_LOST}
    jumped = evidence.assess(_lane(1, -0.11, PLACED))  # 0.10 m in 1/30 s: more than 0.04 m
    assert (jumped.usable, jumped.slope_sum) == (False, None)
    assert jumped.events == {Event.ONE_EDGE_LOST, Event.LANE_UNTRUSTED}
    back = evidence.assess(_lane(2, -0.21, PLACED))  # where the last usable one was
    assert (back.usable, back.slope_sum) == (True, 0.25)


def test_a_placed_lane_that_stays_put_is_usable() -> None:
    """The dashes' gaps and a tape out of view for a few frames: the lane placed from the seen
    tape moves as the robot does (here 0.01 m a frame) and steers as before."""
    evidence = LaneEvidence(SupervisorConfig())
    usable = [evidence.assess(_lane(k, -0.28 + 0.01 * k, PLACED)).usable for k in range(6)]
    assert usable == [True] * 6


def test_a_jump_is_measured_from_the_last_usable_lane_and_grows_with_time() -> None:
    """The reference is the last lane that counted: 0.105 m from it is reachable once 0.03 m +
    0.3 m/s x the time since then reaches 0.105 m, after 0.25 s: not at frame 7 (0.10 m), at
    frame 8 (0.11 m)."""
    evidence = LaneEvidence(SupervisorConfig())
    evidence.assess(_lane(0, -0.21, PLACED))
    usable = [evidence.assess(_lane(k, -0.105, PLACED)).usable for k in range(1, 9)]
    assert usable == [False] * 7 + [True]


def test_a_two_sided_lane_that_jumps_stays_usable() -> None:
    """Two tapes seen are judged by the lane's shape; only the departure rule sets the jump
    aside (tests/supervisor/test_lane_departure.py)."""
    evidence = LaneEvidence(SupervisorConfig())
    evidence.assess(_lane(0, -0.21, SEEN, confidence=0.9))
    jumped = evidence.assess(_lane(1, -0.11, SEEN, confidence=0.9))
    assert (jumped.usable, jumped.slope_sum) == (True, 0.25)
    assert jumped.events == frozenset()
