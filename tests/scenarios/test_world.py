"""World geometry: centre line, tapes with gaps/dashes/ends, gates, distances."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lanewarden.scenarios.errors import ScenarioError
from lanewarden.scenarios.world import build_world, tape_intervals
from tests.scenarios.helpers import spec_from, straight_spec


def test_straight_then_right_arc_ends_where_geometry_says() -> None:
    spec = spec_from({"lane": {"start": {"x_m": 1.0, "y_m": 2.0, "heading_deg": 90},
                               "segments": [{"straight_m": 1.0},
                                            {"arc_radius_m": 0.8, "turn_deg": -90, "mark": "A"}]}})
    world = build_world(spec)
    centre = world.centreline
    # North 1 m, then a right quarter circle of radius 0.8: ends 0.8 east, 0.8 further north.
    end = centre.points[-1]
    assert end == pytest.approx([1.8, 3.8], abs=1e-6)
    assert centre.heading[-1] == pytest.approx(0.0, abs=1e-9)
    assert centre.length_m == pytest.approx(1.0 + 0.8 * math.pi / 2, abs=1e-6)
    assert world.marks["A"] == pytest.approx(centre.length_m)
    a, b = world.gate("A")
    assert a == pytest.approx([1.8, 3.5], abs=1e-6) and b == pytest.approx([1.8, 4.1], abs=1e-6)
    # Tapes sit half a lane width either side of the centre line along the whole arc.
    for tape in world.tapes:
        s, lateral, _ = centre.project(tape.pieces[0])
        assert np.allclose(lateral, tape.offset_m, atol=2e-3)
    assert world.tapes[0].side == "left" and world.tapes[0].offset_m == pytest.approx(0.3)


def test_gaps_dashes_and_ends_make_tape_intervals() -> None:
    spec = straight_spec(
        4.0, gaps=[{"tape": "right", "from_m": 1.0, "to_m": 1.5}],
        dashes={"tape": "left", "on_m": 0.5, "off_m": 0.25, "from_m": 2.0},
        ends={"left_m": 3.6, "right_m": 3.8})
    assert tape_intervals(spec, "right", 4.0) == [(0.0, 1.0), (1.5, 3.8)]
    # Dashes from 2.0 m: tape 2.0-2.5, gap, tape 2.75-3.25, gap, tape 3.5 until the end at 3.6.
    left = tape_intervals(spec, "left", 4.0)
    assert np.allclose(left, [(0.0, 2.5), (2.75, 3.25), (3.5, 3.6)])
    world = build_world(spec)
    assert world.markings_end_s == pytest.approx(3.6)
    point, heading = world.lane_end()  # type: ignore[misc]
    assert point == pytest.approx([3.6, 0.0]) and heading == pytest.approx(0.0)


def test_lane_without_ends_never_ends_and_distance_to_tape() -> None:
    world = build_world(straight_spec(3.0))
    assert world.markings_end_s is None and world.lane_end() is None
    d = world.distance_to_tape(np.array([[1.0, 0.0], [1.0, 0.25], [1.0, -0.4]]))
    assert d == pytest.approx([0.3, 0.05, 0.1], abs=1e-9)
    # Tape samples cover the tape surface: all within half a tape width of a tape centre line.
    assert world.distance_to_tape(world.tape_samples).max() <= 0.024 + 1e-9


def test_impossible_geometry_is_a_one_line_error() -> None:
    with pytest.raises(ScenarioError, match=r"arc_radius_m = 0.3: expected more than"):
        build_world(spec_from({"lane": {"segments": [{"arc_radius_m": 0.3, "turn_deg": 90}]}}))
    with pytest.raises(ScenarioError, match=r"lane.ends.left_m = 5.0: expected at most"):
        build_world(straight_spec(2.0, ends={"left_m": 5.0}))


def test_robot_start_offset_and_bounds() -> None:
    world = build_world(spec_from({"lane": {"segments": [{"straight_m": 2.0}]},
                                   "robot": {"offset_m": 0.1, "heading_deg": 10}}),
                        margin_m=1.0)
    assert world.start_pose.y_m == pytest.approx(0.1)
    assert world.start_pose.theta_rad == pytest.approx(math.radians(10))
    assert world.bounds == pytest.approx((-1.3, -1.3, 3.3, 1.3))
