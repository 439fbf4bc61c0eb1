"""The ground pose from a floor chessboard photo (rendered by the scenarios renderer through
random robot cameras), its plausibility rules, and what the pose means for the detector (horizon,
pixel size, slope sums in bends)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from lanewarden.perception.calibration import CameraCalibration
from lanewarden.perception.calibration_config import CalibrationConfig
from lanewarden.perception.chessboard import ChessboardPattern, detect_view
from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.errors import PerceptionError
from lanewarden.perception.ground import CameraPose, GroundModel, default_ground_model
from lanewarden.perception.ground_calibration import (
    FloorChessboardSolution,
    board_floor_points,
    order_as_seen,
    plausibility_problems,
    pose_from_mount,
    solve_floor_chessboard,
)
from lanewarden.perception.ground_report import bend_slope_sum, summarize_ground
from lanewarden.scenarios.camera import CameraModel
from tests.calibration.floor_board import PATTERN, floor_photo, random_camera

CAMERAS = 12
GATE_M = CalibrationConfig().max_ground_error_m


def intrinsics_only(camera: CameraModel) -> CameraCalibration:
    return replace(camera.calibration(), ground=None)


def solve(camera: CameraModel, rng: np.random.Generator) -> FloorChessboardSolution:
    photo = floor_photo(camera, rng)
    view = detect_view(photo.image, PATTERN, CalibrationConfig(), name="floor")
    assert view.accepted and view.corners is not None, view.rejection
    return solve_floor_chessboard(view.corners, PATTERN, photo.square_m, photo.centre_xy,
                                  intrinsics_only(camera))


def test_random_cameras_are_recovered_from_one_floor_chessboard() -> None:
    rng = np.random.default_rng(9)
    worst = {"height_m": 0.0, "pitch_deg": 0.0, "roll_deg": 0.0, "forward_m": 0.0}
    for _ in range(CAMERAS):
        camera = random_camera(rng)
        solution = solve(camera, rng)
        pose = solution.pose
        assert abs(pose.height_m - camera.height_m) < 0.01, (camera, pose)
        assert abs(pose.pitch_deg - camera.pitch_down_deg) < 1.0, (camera, pose)
        assert abs(pose.roll_deg - camera.roll_deg) < 1.0, (camera, pose)
        assert abs(pose.yaw_deg) < 1.0 and abs(pose.lateral_m) < 0.01, (camera, pose)
        assert abs(pose.forward_m - camera.forward_offset_m) < 0.01, (camera, pose)
        assert plausibility_problems(solution, GATE_M) == []
        assert solution.reprojection_error_m < 0.002
        worst["height_m"] = max(worst["height_m"], abs(pose.height_m - camera.height_m))
        worst["pitch_deg"] = max(worst["pitch_deg"], abs(pose.pitch_deg - camera.pitch_down_deg))
    # Far better than the acceptance bounds (1 cm, 1 deg): measured 0.2 mm and 0.04 deg.
    assert worst["height_m"] < 0.002 and worst["pitch_deg"] < 0.2, worst


def test_the_corner_order_does_not_matter() -> None:
    rng = np.random.default_rng(4)
    camera = random_camera(rng)
    photo = floor_photo(camera, rng)
    view = detect_view(photo.image, PATTERN, CalibrationConfig(), name="floor")
    assert view.corners is not None
    calibration = intrinsics_only(camera)
    poses = [solve_floor_chessboard(corners, PATTERN, photo.square_m, photo.centre_xy,
                                    calibration).pose
             for corners in (view.corners, view.corners[::-1].copy())]
    assert poses[0].height_m == pytest.approx(poses[1].height_m, abs=1e-9)
    assert poses[0].pitch_deg == pytest.approx(poses[1].pitch_deg, abs=1e-7)


def test_grids_are_ordered_as_the_camera_sees_them() -> None:
    pattern = ChessboardPattern(3, 4)
    # detected rows of 3 running right to left, rows from the bottom of the image up
    u, v = np.meshgrid(np.array([300.0, 200.0, 100.0]), np.array([400.0, 350.0, 300.0, 250.0]))
    grid = order_as_seen(np.column_stack([u.ravel(), v.ravel()]), pattern)
    assert grid.shape == (4, 3, 2)
    assert grid[0, 0].tolist() == [100.0, 250.0] and grid[-1, -1].tolist() == [300.0, 400.0]
    # a board turned by 90 degrees: OpenCV's rows of 3 run DOWN the image
    u, v = np.meshgrid(np.array([100.0, 150.0, 200.0, 250.0]), np.array([300.0, 350.0, 400.0]))
    detected = np.column_stack([u.T.ravel(), v.T.ravel()])  # rows of 3 going down
    grid = order_as_seen(detected, pattern)
    assert grid.shape == (3, 4, 2)
    assert grid[0, 0].tolist() == [100.0, 300.0] and grid[0, -1].tolist() == [250.0, 300.0]


def test_board_corners_on_the_floor_in_the_robot_frame() -> None:
    grid = board_floor_points(ChessboardPattern(3, 4), 0.1, (0.5, 0.0), across=3, along=4)
    # rows from the far end, columns from the robot's left
    assert grid.shape == (4, 3, 2)
    assert grid[0, 0].tolist() == pytest.approx([0.65, 0.1])
    assert grid[0, 2].tolist() == pytest.approx([0.65, -0.1])
    assert grid[3, 1].tolist() == pytest.approx([0.35, 0.0])


def _solution(pose: CameraPose, corners_px: np.ndarray, error_m: float = 0.001,
              model: GroundModel | None = None) -> FloorChessboardSolution:
    k = np.array([[457.0, 0.0, 320.0], [0.0, 457.0, 240.0], [0.0, 0.0, 1.0]])
    if model is None and pose.height_m > 0:
        model = GroundModel(k, pose, (640, 480))
    n = len(corners_px)
    return FloorChessboardSolution(pose, model, corners_px, np.zeros((n, 2)),
                                   np.full(n, error_m), error_m, 0.1)


BOARD_LOW = np.array([[280.0, 300.0], [360.0, 300.0], [280.0, 360.0], [360.0, 360.0]])
LEVEL_ENOUGH = CameraPose(height_m=0.3, pitch_deg=30.0, forward_m=0.1)


def test_a_plausible_pose_passes() -> None:
    assert plausibility_problems(_solution(LEVEL_ENOUGH, BOARD_LOW), 0.01) == []


def test_a_camera_under_the_floor_is_refused() -> None:
    problems = plausibility_problems(_solution(replace(LEVEL_ENOUGH, height_m=-0.3), BOARD_LOW),
                                     0.01)
    assert len(problems) == 1 and problems[0].startswith("the solved camera is 0.300 m UNDER")


def test_a_horizon_below_the_board_is_refused() -> None:
    # pitched 30 deg UP: the horizon is at row 240 + 457 tan 30 = 504, below the whole board
    up = CameraPose(height_m=0.3, pitch_deg=-30.0)
    problems = plausibility_problems(_solution(up, BOARD_LOW), 0.01)
    assert problems == ["the solved horizon (row 504) lies below the board (its top corners at "
                        "row 300): the board cannot be on the floor (is the photo upside down, or "
                        "the board not lying flat?)"]
    # one corner above the horizon is enough
    level = CameraPose(height_m=0.3, pitch_deg=0.0)  # horizon at row 240
    corners = np.vstack([BOARD_LOW, [[320.0, 239.0]]])
    assert len(plausibility_problems(_solution(level, corners), 0.01)) == 1
    assert plausibility_problems(_solution(level, BOARD_LOW), 0.01) == []


def test_an_error_above_the_gate_is_refused() -> None:
    problems = plausibility_problems(_solution(LEVEL_ENOUGH, BOARD_LOW, error_m=0.0125), 0.01)
    assert problems == ["reprojection error on the floor 12.5 mm exceeds "
                        "calibration.max_ground_error_m 10 mm: is the board flat and --square "
                        "right?"]
    assert plausibility_problems(_solution(LEVEL_ENOUGH, BOARD_LOW, error_m=0.0099), 0.01) == []
    nan = plausibility_problems(_solution(LEVEL_ENOUGH, BOARD_LOW, error_m=math.inf), 0.01)
    assert len(nan) == 1 and "exceeds" in nan[0]


def test_a_camera_far_from_the_robot_is_refused() -> None:
    far = replace(LEVEL_ENOUGH, forward_m=-1.2)
    problems = plausibility_problems(_solution(far, BOARD_LOW), 0.01)
    assert len(problems) == 1 and "1.20 m from the robot's centre" in problems[0]


def test_a_rolled_camera_is_refused() -> None:
    """A board held up or leaning solves to a camera rolled about its axis (OpenCV's left05.jpg:
    +17.1°, accepted and written before): no robot carries its camera so."""
    problems = plausibility_problems(_solution(replace(LEVEL_ENOUGH, roll_deg=17.0), BOARD_LOW),
                                     0.01)
    assert problems == ["the solved camera is rolled +17.0° about its axis (a camera on the robot "
                        "is level to within 10°): is the board lying flat on the floor? (a camera "
                        "mounted rolled: calibrate from the mount with --roll-deg)"]
    level_enough = replace(LEVEL_ENOUGH, roll_deg=-9.9)
    assert plausibility_problems(_solution(level_enough, BOARD_LOW), 0.01) == []


@pytest.mark.parametrize(("kwargs", "message"), [
    (dict(height_m=0.0, pitch_deg=30.0), "--height-m 0: expected a height above the floor"),
    (dict(height_m=0.001, pitch_deg=30.0),
     "--height-m 0.001: expected a height above the floor, 0.02..5 m"),
    (dict(height_m=0.3, pitch_deg=95.0), "--pitch-deg 95: expected -90..90"),
    (dict(height_m=0.3, pitch_deg=30.0, roll_deg=math.nan), "--roll-deg nan"),
    (dict(height_m=0.3, pitch_deg=30.0, forward_m=3.0), "--forward-m 3: expected -2..2 m"),
])
def test_impossible_mounts_name_the_flag(kwargs: dict[str, float], message: str) -> None:
    with pytest.raises(PerceptionError, match=message.replace(".", r"\.")):
        pose_from_mount(**kwargs)


def test_the_pose_is_recovered_from_its_rotation() -> None:
    rng = np.random.default_rng(1)
    for _ in range(50):
        pose = CameraPose(height_m=float(rng.uniform(0.1, 1.0)),
                          pitch_deg=float(rng.uniform(-80.0, 80.0)),
                          roll_deg=float(rng.uniform(-60.0, 60.0)),
                          yaw_deg=float(rng.uniform(-120.0, 120.0)),
                          forward_m=float(rng.uniform(-0.3, 0.3)),
                          lateral_m=float(rng.uniform(-0.3, 0.3)))
        back = CameraPose.from_rotation(pose.rotation_robot_to_camera(), pose.position())
        for field in ("height_m", "pitch_deg", "roll_deg", "yaw_deg", "forward_m", "lateral_m"):
            assert getattr(back, field) == pytest.approx(getattr(pose, field), abs=1e-9)


# ----------------------------------------------------------------------- what the pose means

def test_the_default_camera_summary() -> None:
    summary = summarize_ground(default_ground_model((640, 480)), PerceptionConfig())
    assert summary.horizon_y_px == pytest.approx(-80.0, abs=0.1)  # 240 - 457.0 tan 35
    # perception's look-ahead, 0.87 m ahead of the robot's centre, lands on row 192.4
    assert summary.look_ahead_m == pytest.approx(0.87, abs=1e-9)
    assert summary.look_ahead_y_px == pytest.approx(192.4, abs=0.05)
    # 0.72 m ahead of the camera, 0.40 m below it: 0.824 m along the ray / 457.0 px
    assert summary.mm_per_px_across_at_look_ahead == pytest.approx(1.80, abs=0.01)


def test_sharp_bends_pass_the_lecture_threshold_and_wide_ones_do_not() -> None:
    # the default camera with its principal point on the middle of the pixel grid (319.5), so
    # that left and right bends are exact mirror images
    default = default_ground_model((640, 480))
    k = default.camera_matrix.copy()
    k[0, 2] = 319.5
    model = GroundModel(k, default.pose, (640, 480))
    row, clamp = 192.0, PerceptionConfig().edges.max_abs_slope
    lane = (0.60, 0.048)  # the lecture's lane: tape centres 0.60 m apart, 48 mm tape
    sharp_right = bend_slope_sum(model, 0.5, "right", row, clamp, *lane)
    sharp_left = bend_slope_sum(model, 0.5, "left", row, clamp, *lane)
    wide_right = bend_slope_sum(model, 2.0, "right", row, clamp, *lane)
    assert sharp_right is not None and sharp_left is not None and wide_right is not None
    # entering a sharp bend the inner edge swings past vertical: clamped at -12, the outer
    # edge leans at about +1
    assert sharp_right == pytest.approx(-11.04, abs=0.01)
    assert sharp_left == pytest.approx(-sharp_right, abs=1e-9)  # no roll: a mirror image
    assert wide_right == pytest.approx(-4.26, abs=0.01)  # inside the lecture's +-6
    straight = bend_slope_sum(model, 1e4, "right", row, clamp, *lane)
    assert straight is not None and abs(straight) < 0.01
