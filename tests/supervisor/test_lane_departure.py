"""Leaving the lane: LANE_DEPARTURE (supervisor/lane_evidence.py), and the TURN states' extra
turn rate withheld on the inner side of a bend (supervisor/commands.py).

Expected values are written out from the geometry: an edge line at signed distance `offset`
from the robot's centre and heading `h` passes x metres ahead at offset / cos(h) + x tan(h).
"""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from lanewarden.perception.observation import LaneEdge, LaneObservation
from lanewarden.supervisor.commands import command_for, turn_extra_rad_s
from lanewarden.supervisor.config import SupervisorConfig
from lanewarden.supervisor.lane_evidence import departure_of, read_back_m
from lanewarden.supervisor.state_machine import SupervisorState
from tests.supervisor.rig import LEFT_EDGE, RIGHT_EDGE, Rig, observation

CLEARANCE = 0.175
VIEW = 0.55


def _edge(base: LaneEdge, lateral_at_robot: float, heading: float = 0.0,
          near: float | None = 0.4) -> LaneEdge:
    """An edge whose line passes the robot's centre `lateral_at_robot` to its left (x = 0)."""
    return LaneEdge(base.x1, base.y1, base.x2, base.y2, base.slope, base.support_px,
                    offset_m=lateral_at_robot * math.cos(heading), heading_rad=heading,
                    near_m=near)


def _line(base: LaneEdge, offset: float, heading_deg: float, near: float = 0.0) -> LaneEdge:
    """`base` with its line on the floor at signed distance `offset` from the robot's centre,
    running at `heading_deg`, seen from `near` metres ahead."""
    return replace(base, offset_m=offset, heading_rad=math.radians(heading_deg), near_m=near)


def _obs(left: LaneEdge | None = None, right: LaneEdge | None = None) -> LaneObservation:
    return LaneObservation(0, 0.0, left, right, None if not (left and right) else 0.0, 0.9)


def test_a_left_edge_inside_the_footprint_is_a_departure() -> None:
    text = departure_of(_obs(left=_edge(LEFT_EDGE, 0.12)), CLEARANCE, VIEW)
    assert text is not None and text.startswith("left edge 0.120 m left")


def test_edges_outside_the_footprint_are_no_departure() -> None:
    obs = _obs(left=_edge(LEFT_EDGE, 0.20), right=_edge(RIGHT_EDGE, -0.20))
    assert departure_of(obs, CLEARANCE, VIEW) is None


def test_a_right_edge_inside_the_footprint_is_a_departure() -> None:
    text = departure_of(_obs(right=_edge(RIGHT_EDGE, -0.15)), CLEARANCE, VIEW)
    assert text is not None and text.startswith("right edge 0.150 m right")


def _chord(base: LaneEdge, offset: float, heading: float, near: float,
           far: float | None) -> LaneEdge:
    return replace(base, offset_m=offset, heading_rad=heading, near_m=near, far_m=far)


# A 2 m bend to the left, the lane's inner edges 0.55 m apart, seen as each edge's chord from
# 0.36 to 0.66 m ahead (the 320x240 camera's near line). Written out from the arcs
# y = c + x^2 / 2R: the chord through x = 0.36 and 0.66 is read at 0.36 x 0.66 / 1.02 =
# 0.2329 m ahead, where it passes the arc's point at the robot; half-way to the nearest point
# (0.18 m, the rule before 2026-12-06) it does not.


def test_where_an_edge_is_read_back_to() -> None:
    assert read_back_m(0.36, 0.66) == pytest.approx(0.36 * 0.66 / 1.02)  # 0.2329 m
    assert read_back_m(0.36, 1.6149) == pytest.approx(0.2944, abs=1e-4)  # a long straight line
    assert read_back_m(0.36, None) == 0.18  # no far end: half-way, as a tangent
    assert read_back_m(0.36, 0.36) == 0.18  # nor a far end that is no farther
    assert read_back_m(0.0, 0.5) == 0.0  # seen from the robot's centre on: there


def test_a_bends_inner_edge_read_on_its_chord_is_where_the_tape_is() -> None:
    # left (inner) edge y = 0.205 + x^2 / 3.45: the chord runs at 0.28746 rad, offset 0.130544;
    # 0.205 m from the robot's centre, clear of 0.195 (read half-way: 0.18935 m, a departure)
    cfg = SupervisorConfig()
    chord = _chord(LEFT_EDGE, 0.130544, 0.2874632, 0.36, 0.66)
    assert departure_of(_obs(left=chord), cfg.lane_departure_clearance_m, VIEW) is None
    half_way = departure_of(_obs(left=replace(chord, far_m=None)),
                            cfg.lane_departure_clearance_m, VIEW)
    assert half_way is not None and half_way.startswith("left edge 0.189 m left")


def test_a_bends_outer_edge_read_on_its_chord_shows_the_departure() -> None:
    # right (outer) edge y = -0.19 + x^2 / 4.55, 0.19 m from the robot's centre (inside the
    # 0.195 m clearance): the chord runs at 0.22053 rad, offset -0.236354, closing in on the
    # robot, so read square to it: 0.19 x cos(0.22053) = 0.1854 m, a departure (read half-way:
    # 0.20187 x cos(0.22053) = 0.1970 m, none)
    cfg = SupervisorConfig()
    chord = _chord(RIGHT_EDGE, -0.236354, 0.2205298, 0.36, 0.66)
    text = departure_of(_obs(right=chord), cfg.lane_departure_clearance_m, VIEW)
    assert text is not None and text.startswith("right edge 0.185 m right")
    assert departure_of(_obs(right=replace(chord, far_m=None)),
                        cfg.lane_departure_clearance_m, VIEW) is None


def test_an_edge_on_the_wrong_side_of_the_robot_is_a_departure() -> None:
    # the left tape's edge already passes right of the robot's centre: it is over the tape
    text = departure_of(_obs(left=_edge(LEFT_EDGE, -0.05)), CLEARANCE, VIEW)
    assert text is not None and text.startswith("left edge 0.050 m right")


def test_the_edge_is_read_half_way_back_from_where_it_is_seen() -> None:
    # heading with tan 0.2, seen from 0.4 m: read at 0.2 m ahead, 0.2 * 0.2 = 0.04 m out
    heading = math.atan(0.2)
    assert departure_of(_obs(left=_edge(LEFT_EDGE, 0.15, heading)), CLEARANCE, VIEW) is None
    assert departure_of(_obs(left=_edge(LEFT_EDGE, 0.13, heading)), CLEARANCE,
                        VIEW) is not None  # 0.13 + 0.04 = 0.17 < 0.175


def test_an_edge_crossing_the_path_is_measured_square_to_it() -> None:
    # r00665 (twentieth campaign): the outer tape of a corner crossing the robot's path at 25
    # degrees, seen from the robot's centre on (near 0): its line 0.17 m from the centre,
    # square to it, is inside the footprint; along the robot's y axis it is 0.17 / cos(25) =
    # 0.1876 m away, which read that way would not be a departure
    text = departure_of(_obs(left=_line(LEFT_EDGE, 0.17, -25.0)), CLEARANCE, VIEW)
    assert text is not None and text.startswith("left edge 0.170 m left")
    # seen from 0.2 m ahead, the same line read square to it from 0.1 m ahead on the robot's
    # axis: 0.17 + 0.1 * sin(-25 degrees) = 0.1277 m
    text = departure_of(_obs(left=_line(LEFT_EDGE, 0.17, -25.0, near=0.2)), CLEARANCE, VIEW)
    assert text is not None and text.startswith("left edge 0.128 m left")


def test_an_edge_opening_away_is_read_along_the_robots_y_axis() -> None:
    # seed 1's r00932 and r00623: the inner tape of the lecture's tight corner, its chord at
    # 40-48 degrees opening away from the robot; its line read back behind where it is seen
    # cuts the corner of the bend: 0.16 m square to it, 0.16 / cos(45) = 0.226 m along y
    assert departure_of(_obs(left=_line(LEFT_EDGE, 0.16, 45.0)), CLEARANCE, VIEW) is None
    assert departure_of(_obs(right=_line(RIGHT_EDGE, -0.16, -45.0)), CLEARANCE, VIEW) is None
    # the same line closing in (the right edge at +45 degrees) is read square to it
    text = departure_of(_obs(right=_line(RIGHT_EDGE, -0.16, 45.0)), CLEARANCE, VIEW)
    assert text is not None and text.startswith("right edge 0.160 m right")


def test_an_edge_seen_only_far_ahead_or_not_on_the_floor_does_not_count() -> None:
    assert departure_of(_obs(left=_edge(LEFT_EDGE, 0.05, near=0.6)), CLEARANCE, VIEW) is None
    assert departure_of(_obs(left=LEFT_EDGE), CLEARANCE, VIEW) is None


def _engaged() -> Rig:
    rig = Rig()
    rig.step(start=True)
    while rig.state != "FOLLOW":
        rig.step()
    return rig


def test_departure_frames_in_a_row_halt_and_fewer_do_not() -> None:
    rig = _engaged()
    assert rig.config.lane_departure_frames == 3
    assert rig.step(left_edge_m=0.12).state == "FOLLOW"
    assert rig.step(left_edge_m=0.12).state == "FOLLOW"
    out = rig.step(left_edge_m=0.12)
    assert out.state == "HALT" and out.command.is_stop
    assert rig.controller.halt_reason is not None
    assert rig.controller.halt_reason.startswith("LANE_DEPARTURE")
    assert "left edge 0.120 m left of the robot's centre," in rig.controller.halt_reason


def test_a_clear_frame_resets_the_departure_streak() -> None:
    # each step within reach of the last (0.3 m/s x 1/30 s + 0.03 m = 0.04 m); the default
    # clearance is 0.195 m (footprint 0.175 m and 0.02 m to stop in): 0.20 m is clear
    rig = _engaged()
    assert rig.config.lane_departure_clearance_m == 0.195
    for edge in (0.18, 0.18, 0.20, 0.18, 0.18):
        assert rig.step(left_edge_m=edge).state == "FOLLOW"


def test_the_margin_halts_before_the_tape_reaches_the_footprint() -> None:
    # 0.19 m: still 15 mm clear of the 0.175 m footprint, inside the 0.02 m margin
    rig = _engaged()
    assert rig.step(left_edge_m=0.19).state == "FOLLOW"
    assert rig.step(left_edge_m=0.19).state == "FOLLOW"
    assert rig.step(left_edge_m=0.19).state == "HALT"


def test_a_jump_of_the_edge_counts_only_once_the_robot_could_have_moved_there() -> None:
    # the left edge seen 0.275 m left, then 0.12 m: 0.155 m away, which the robot (at most
    # 0.3 m/s) can reach, with 0.03 m of noise, only n frames later where
    # 0.3 * n / 30 + 0.03 >= 0.155, n >= 12.5: the 13th such frame is the first to count, the
    # 15th the third in a row
    rig = _engaged()
    assert rig.config.limiter_max_linear_m_s == 0.3
    assert rig.config.lane_departure_jump_m == 0.03
    assert rig.step(left_edge_m=0.275).state == "FOLLOW"
    for _ in range(14):
        assert rig.step(left_edge_m=0.12).state == "FOLLOW"
    out = rig.step(left_edge_m=0.12)
    assert out.state == "HALT"
    assert rig.controller.halt_reason is not None
    assert rig.controller.halt_reason.startswith("LANE_DEPARTURE")


def test_a_lane_flickering_to_a_slat_beside_it_is_no_departure() -> None:
    # the tenth campaign run's parquet false halts (r00233, r00690): perception alternates
    # between the true lane (its edge 0.275 m left, the frame untrusted) and a whole lane
    # shifted 0.155 m to one side (confident); the old rule counted the shifted frames across
    # the untrusted ones and halted a centred robot
    rig = _engaged()
    assert rig.step(left_edge_m=0.275).state == "FOLLOW"
    for _ in range(3):
        assert rig.step(left_edge_m=0.12).state != "HALT"
        assert rig.step(left_edge_m=0.12).state != "HALT"
        assert rig.step(left_edge_m=0.275, confidence=0.0).state != "HALT"


def _left_line(rig: Rig, offset: float, heading_deg: float) -> LaneObservation:
    """The next frame's observation, its left edge's line at `offset` and `heading_deg`, seen
    from the robot's centre on."""
    base = observation(rig.index + 1, rig.clock.now() + 1 / 30)
    return replace(base, left=_line(LEFT_EDGE, offset, heading_deg))


def test_an_edge_flickering_to_a_steep_wrong_line_is_no_departure() -> None:
    # seed 1's r00089 (terrazzo): the right edge flickered between the tape (-7 degrees) and
    # texture lines at +-40 degrees, which read square to them 0.17-0.18 m from a robot 7 cm
    # clear of the tape; a direction the robot cannot have turned to (1 rad/s x 1/30 s + 15
    # degrees) is a wrong line: it neither counts nor resets the streak
    rig = _engaged()
    assert rig.config.lane_departure_turn_deg == 15.0
    assert rig.step(obs=_left_line(rig, 0.20, 0.0)).state == "FOLLOW"  # clear: 0.20 m
    for _ in range(10):  # 0.175 m square to a line closing in at 40 degrees: within reach,
        out = rig.step(obs=_left_line(rig, 0.175, -40.0))  # turned too far
        assert "LANE_DEPARTURE" not in {e.value for e in out.events}


def test_an_edge_turning_as_the_robot_can_still_counts() -> None:
    # r00665: the outer tape's direction drifting from -17 to -28 degrees as the robot ran
    # onto it, 4-7 degrees a frame: within the bound, so those frames count
    rig = _engaged()
    assert rig.step(obs=_left_line(rig, 0.20, -17.0)).state == "FOLLOW"
    assert rig.step(obs=_left_line(rig, 0.19, -23.0)).state == "FOLLOW"
    assert rig.step(obs=_left_line(rig, 0.185, -28.0)).state == "FOLLOW"
    out = rig.step(obs=_left_line(rig, 0.18, -24.0))
    assert out.state == "HALT"
    assert "LANE_DEPARTURE" in {e.value for e in out.events}


def test_a_frame_that_is_not_usable_neither_counts_nor_resets_the_streak() -> None:
    rig = _engaged()
    assert rig.step(left_edge_m=0.12).state == "FOLLOW"
    assert rig.step(left_edge_m=0.12).state == "FOLLOW"
    assert rig.step(left_edge_m=0.25, confidence=0.1).state == "DEGRADED"  # untrusted, clear
    out = rig.step(left_edge_m=0.12)
    assert out.state == "HALT"
    assert "LANE_DEPARTURE" in {e.value for e in out.events}


def test_usable_but_unconfident_frames_count_towards_a_departure() -> None:
    # r00665 (twentieth campaign): a robot drifting onto the outer tape of a corner, the lane's
    # shape no longer matching (confidence 0.2-0.5, both edges seen), never had three confident
    # frames in a row before it was over the tape
    rig = _engaged()
    assert rig.config.confidence_usable_min == 0.2
    assert rig.step(left_edge_m=0.12, confidence=0.5).state != "HALT"
    assert rig.step(left_edge_m=0.12, confidence=0.3).state != "HALT"
    out = rig.step(left_edge_m=0.12, confidence=0.25)
    assert out.state == "HALT"
    assert "LANE_DEPARTURE" in {e.value for e in out.events}


CONFIG = SupervisorConfig()


@pytest.mark.parametrize(("direction", "center_offset", "expected"), [
    (1.0, None, 0.2), (1.0, 0.03, 0.2), (1.0, 0.0, 0.2),
    (1.0, -0.025, 0.1), (1.0, -0.05, 0.0), (1.0, -0.2, 0.0),
    (-1.0, None, -0.2), (-1.0, -0.03, -0.2), (-1.0, 0.025, -0.1), (-1.0, 0.06, 0.0),
])
def test_the_turn_extra_is_withheld_on_the_inner_side_of_the_bend(
        direction: float, center_offset: float | None, expected: float) -> None:
    # defaults: turn_extra_angular_rad_s 0.2, turn_extra_fade_m 0.05
    assert turn_extra_rad_s(direction, center_offset, CONFIG) == pytest.approx(expected)


def test_turn_left_inside_the_bend_steers_away_from_the_inner_tape() -> None:
    # r00949's situation: the slope sum reads a sharp left bend (+11) while the lane centre
    # lies 0.13 m to the robot's right: the command must turn right, not onto the left tape
    command = command_for(SupervisorState.TURN_LEFT, 11.0, -0.13, CONFIG)
    # 0.03 * 11 + 3.6 * -0.13 + 0 = -0.138
    assert command.angular_rad_s == pytest.approx(-0.138)
