"""Ground-truth metrics on hand-made trajectories (no perception, no supervisor)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lanewarden.actuation.base import Pose2D
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.expectations import check_expectation
from lanewarden.scenarios.metrics import (
    GroundRoi,
    RunTrace,
    TapeVisibility,
    compute_metrics,
    convex_half_planes,
    fault_to_halt,
    first_halt_index,
    motion_after_halt,
    points_in_polygon,
    turns_completed,
)
from lanewarden.scenarios.spec import Expectation
from lanewarden.scenarios.world import build_world
from tests.scenarios.helpers import spec_from, straight_spec

#: A triangle like the lecture's ROI, in undistorted pixels of a 640x480 image.
ROI = np.array([[-384.0, 480.0], [1024.0, 480.0], [320.0, 0.0]])


def trace_along(xs: np.ndarray, ys: np.ndarray, states: list[str], dt: float = 1 / 30,
                reasons: list[str | None] | None = None) -> RunTrace:
    thetas = np.arctan2(np.gradient(ys), np.gradient(xs)) if len(xs) > 1 else np.zeros(len(xs))
    n = len(xs)
    return RunTrace(
        time_s=np.arange(n) * dt, poses=np.column_stack([xs, ys, thetas]), states=states,
        halt_reasons=reasons or [None] * n, events=[()] * n, speed_m_s=np.full(n, 0.2))


def test_points_in_polygon_and_first_halt() -> None:
    square = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], float)
    inside = points_in_polygon(np.array([[1, 1], [3, 1], [-0.1, 0.5], [1.9, 1.9]]), square)
    assert inside.tolist() == [True, False, False, True]
    assert first_halt_index(["HALT", "HALT", "FOLLOW", "DEGRADED", "HALT", "HALT"]) == 4
    assert first_halt_index(["HALT", "FOLLOW", "FOLLOW"]) is None
    assert first_halt_index(["HALT", "HALT"]) == 0  # never engaged counts as halted


def test_straight_run_that_stops_just_past_the_lane_end() -> None:
    world = build_world(straight_spec(5.0, ends={"left_m": 3.0, "right_m": 3.2}))
    n = 101
    xs = np.linspace(0.0, 3.05, n)
    ys = np.full(n, 0.02)
    states = ["HALT"] * 5 + ["FOLLOW"] * 90 + ["HALT"] * 6
    reasons: list[str | None] = [None] * 95 + ["LANE_LOST: gone"] * 6
    visible = xs < 2.9
    m = compute_metrics(world, trace_along(xs, ys, states, reasons=reasons), visible, 2.9)
    assert m["halted"] is True and m["halt_reason"] == "LANE_LOST: gone"
    assert m["halt_time_s"] == pytest.approx(95 / 30, abs=1e-3)
    assert m["max_cross_track_error_m"] == pytest.approx(0.02, abs=1e-6)
    assert m["mean_cross_track_error_m"] == pytest.approx(0.02, abs=1e-6)
    assert m["distance_past_lane_end_m"] == pytest.approx(0.05, abs=1e-6)
    assert m["distance_travelled_m"] == pytest.approx(3.05, abs=1e-6)
    assert m["crossed_tape"] is False
    assert m["states_visited"] == ["HALT", "FOLLOW"]
    first_lost = int(np.argmax(~visible))
    assert m["lane_loss_to_halt_s"] == pytest.approx((95 - first_lost) / 30, abs=1e-3)
    assert m["lane_loss_estimated"] is False


def test_stopping_before_the_end_is_negative_and_halting_early_extrapolates() -> None:
    world = build_world(straight_spec(5.0, ends={"left_m": 3.0, "right_m": 3.0}))
    xs = np.linspace(0.0, 2.5, 60)
    states = ["FOLLOW"] * 50 + ["HALT"] * 10
    m = compute_metrics(world, trace_along(xs, np.zeros(60), states), np.ones(60, bool), 2.8)
    assert m["distance_past_lane_end_m"] == pytest.approx(-0.5, abs=1e-6)
    # Halted at x = 50/59 * 2.5 with tape still in view; at 0.2 m/s it would have lost the tape
    # (at 2.8 m) this much later:
    x_halt = 2.5 * 50 / 59
    assert m["lane_loss_estimated"] is True
    assert m["lane_loss_to_halt_s"] == pytest.approx(-(2.8 - x_halt) / 0.2, abs=1e-3)
    # A halt far back is not a response to the lane end: no lane-loss time at all.
    far = compute_metrics(world, trace_along(xs * 0.4, np.zeros(60), states), np.ones(60, bool),
                          2.8)
    assert far["halted"] is True and far["lane_loss_to_halt_s"] is None


def test_no_lane_end_means_nulls() -> None:
    world = build_world(straight_spec(5.0))
    m = compute_metrics(world, trace_along(np.linspace(0, 2, 30), np.zeros(30), ["FOLLOW"] * 30),
                        None, None)
    assert m["distance_past_lane_end_m"] is None and m["lane_loss_to_halt_s"] is None
    assert m["halted"] is False and m["halt_reason"] is None


def test_a_run_that_never_engaged_gives_what_still_held_it() -> None:
    """A robot started over a tape never engages: every frame from the second on says
    LANE_DEPARTURE. Its halt reason is that (what the survey says of such a still), not the
    "not engaged yet" of its first frame; it halted at its start."""
    world = build_world(straight_spec(4.0))
    n = 30
    waiting = "not engaged yet: waiting for start and a confident lane"
    departing = "LANE_DEPARTURE: a lane edge inside the robot's footprint (left edge 0.124 m)"
    m = compute_metrics(world, trace_along(np.zeros(n), np.full(n, 0.15), ["HALT"] * n,
                                           reasons=[waiting, waiting] + [departing] * (n - 2)),
                        None, None)
    assert m["engaged"] is False and m["halted"] is True
    assert m["halt_reason"] == departing
    assert m["halt_time_s"] == 0.0
    quiet = compute_metrics(world, trace_along(np.zeros(n), np.zeros(n), ["HALT"] * n,
                                               reasons=[waiting] * n), None, None)
    assert quiet["halt_reason"] == waiting


def test_footprint_crossing_a_tape() -> None:
    world = build_world(straight_spec(4.0))
    xs = np.linspace(0, 3, 50)
    # Clearance is 0.30 - 0.024 - 0.175 = 0.101 m from the centre line.
    ok = compute_metrics(world, trace_along(xs, np.full(50, 0.095), ["FOLLOW"] * 50), None, None)
    bad = compute_metrics(world, trace_along(xs, np.full(50, 0.11), ["FOLLOW"] * 50), None, None)
    assert ok["crossed_tape"] is False and bad["crossed_tape"] is True
    assert ok["min_tape_clearance_m"] == pytest.approx(0.006, abs=1e-6)


def test_turn_gates_count_only_inside_the_lane() -> None:
    spec = spec_from({"lane": {"segments": [
        {"straight_m": 1.0}, {"arc_radius_m": 1.0, "turn_deg": -90, "mark": "A"},
        {"straight_m": 1.0}, {"arc_radius_m": 1.0, "turn_deg": 90, "mark": "B"},
        {"straight_m": 1.0}]}})
    world = build_world(spec)
    pts = world.centreline.points[::10]
    poses = np.column_stack([pts, np.zeros(len(pts))])
    assert turns_completed(world, poses) == ["A", "B"]
    # Cutting the corner outside the tapes misses gate A (and everything after).
    a_left, _ = world.gate("A")
    shortcut = np.array([[0.0, 0.0, 0.0], [a_left[0] + 0.5, a_left[1] - 0.5, 0.0],
                         [a_left[0] + 0.5, a_left[1] - 5.0, 0.0]])
    assert turns_completed(world, shortcut) == []


def test_tape_visibility_through_the_camera_and_roi() -> None:
    world = build_world(straight_spec(6.0, ends={"left_m": 3.0, "right_m": 3.25}))
    vis = TapeVisibility(world, CameraModel(), ROI)
    assert vis.visible(Pose2D(0.0, 0.0, 0.0))
    assert not vis.visible(Pose2D(3.3, 0.0, 0.0))  # past both tape ends
    assert not vis.visible(Pose2D(-0.3, 0.0, math.pi))  # before the start, facing away
    loss = vis.loss_arc_length(world)
    assert loss is not None
    # The ROI's near edge is about 0.36 m ahead of the robot (bottom of the image) and the tapes
    # enter the image a little further out, so a centred robot loses the later tape end
    # (3.25 m) from its ROI somewhat before reaching it.
    assert 2.6 < loss < 3.25
    point = world.centreline.at(loss - 0.02)[0]
    assert vis.visible(Pose2D(float(point[0]), float(point[1]), 0.0))


def test_a_convex_roi_is_tested_as_half_planes_with_the_same_answer_as_in_pixels() -> None:
    # The half-plane test (one matrix product per pose) must pick exactly the points the pixel
    # test picks: projected, in front of the camera, in the image, inside the ROI polygon.
    camera = CameraModel()
    clipped = np.array([[0, 160], [110, 77], [530, 77], [640, 160], [640, 480], [0, 480]], float)
    rng = np.random.default_rng(5)
    points = rng.uniform(-4.0, 4.0, (4000, 2))
    for roi in (ROI, clipped):
        fast = GroundRoi(camera, roi)
        slow = GroundRoi(camera, roi)
        slow._robot_planes = None  # the point-by-point pixel test
        assert fast._robot_planes is not None
        picked = 0
        for _ in range(40):
            pose = Pose2D(*rng.uniform(-1.0, 1.0, 2), float(rng.uniform(-math.pi, math.pi)))
            expected = slow.inside(pose, points)
            assert fast.inside(pose, points).tolist() == expected.tolist()
            picked += len(expected)
        assert picked > 1000  # the poses do see points
    # Straight ahead, 1 m out, is inside; behind the robot and far off to the side are not.
    fast = GroundRoi(camera, clipped)
    pts = np.array([[1.0, 0.0], [-1.0, 0.0], [1.0, 3.0]])
    assert fast.inside(Pose2D(0.0, 0.0, 0.0), pts).tolist() == [0]


def test_half_planes_only_for_a_convex_polygon() -> None:
    square = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], float)
    planes = convex_half_planes(square)
    assert planes is not None and planes.shape == (4, 3)
    inside = np.all(np.array([1.0, 1.0, 1.0]) @ planes.T > 0)
    outside = np.all(np.array([3.0, 1.0, 1.0]) @ planes.T > 0)
    assert inside and not outside
    assert convex_half_planes(square[::-1]) is not None  # either winding
    notch = np.array([[0, 0], [2, 0], [1, 1], [2, 2], [0, 2]], float)
    assert convex_half_planes(notch) is None
    assert convex_half_planes(np.array([[0, 0], [1, 1], [2, 2]], float)) is None  # a line


# ---- did the robot stop after HALT? (sim --check and the campaign's judge) ----------------------
TIMES = [i / 10 for i in range(31)]  # 0.0 .. 3.0 s
#: engaged at 0.1 s, HALT from 1.0 s on
STATES = ["HALT"] + ["FOLLOW"] * 9 + ["HALT"] * 21
STOPS = [False] * 31  # every command after HALT a stop


@pytest.mark.parametrize(("commands_nonzero", "final_speed", "times", "expected"), [
    (STOPS, 0.0, TIMES, None),  # stopped
    (STOPS, 0.005, TIMES, None),  # below AT_REST_M_S (0.01)
    (STOPS, 0.2, TIMES, "still moving at 0.20 m/s 1.5 s or more after HALT"),
    (STOPS, 0.2, TIMES[:25], None),  # ended 1.4 s after HALT: may still be braking
    (STOPS, 0.2, TIMES[:26], "still moving at 0.20 m/s 1.5 s or more after HALT"),  # 1.5 s
    ([*STOPS[:12], True, *STOPS[13:]], 0.0, TIMES,
     "non-zero command at 1.200 s after HALT at 1.000 s"),
    ([*STOPS[:9], True, *STOPS[10:]], 0.0, TIMES, None),  # before the HALT: allowed
])
def test_motion_after_halt(commands_nonzero: list[bool], final_speed: float,
                           times: list[float], expected: str | None) -> None:
    n = len(times)
    assert motion_after_halt(times, STATES[:n], commands_nonzero[:n], final_speed) == expected


def test_no_motion_after_halt_without_a_halt_after_engaging() -> None:
    assert motion_after_halt(TIMES, ["FOLLOW"] * 31, STOPS, 0.3) is None  # never halted
    assert motion_after_halt(TIMES, ["HALT"] * 31, STOPS, 0.3) is None  # never engaged


def test_fault_to_halt_is_the_last_fault_before_the_halt() -> None:
    effects = [(0, "camera_freeze", 3.0), (1, "bumper", 2.0), (2, "cliff", 5.0)]
    assert fault_to_halt(effects, 3.133) == {"index": 0, "kind": "camera_freeze",
                                             "took_effect_s": 3.0, "to_halt_s": 0.133}
    assert fault_to_halt(effects, 2.0) == {"index": 1, "kind": "bumper",
                                           "took_effect_s": 2.0, "to_halt_s": 0.0}
    assert fault_to_halt(effects, 1.5) is None  # halted before any fault
    assert fault_to_halt(effects, None) is None  # never halted
    assert fault_to_halt([], 3.0) is None


def test_an_expectation_is_never_met_by_a_halt_the_base_did_not_obey() -> None:
    metrics = {"halted": True, "halt_reason": "BASE_LINK_LOST: no feedback",
               "motion_after_halt": "still moving at 0.20 m/s 1.5 s or more after HALT"}
    moving = ("halted = True, but the robot did not stop: still moving at 0.20 m/s 1.5 s or "
              "more after HALT")
    assert check_expectation(metrics, Expectation(halted=True)) == [moving]
    assert check_expectation(metrics, Expectation(halt_reason_any_of=["BASE_LINK_LOST"])) == [
        moving]  # a halt reason expected: a halt expected
    assert check_expectation({**metrics, "motion_after_halt": None},
                             Expectation(halted=True)) == []
