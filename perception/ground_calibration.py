"""Ground calibration: the camera's pose over the floor, from its mount or from a floor chessboard.

Two ways, both ending in a camera pose for the calibration file (`GroundCalibration`):

- from the mount (`pose_from_mount`): the user measures height and pitch (roll, offsets);
- from one photo of a chessboard lying flat on the floor, Duckietown style
  (`solve_floor_chessboard`): the board's inner corners (detected in the photo), undistorted with
  the camera's calibration, are matched to their positions on the floor in the robot frame, and
  the camera pose is the perspective-n-point solution (cv2.solvePnPGeneric, IPPE for a planar
  target, then Levenberg-Marquardt refinement). Its quality is measured where it matters, ON THE
  FLOOR: each undistorted corner is projected back onto the floor through the solved ground model
  and compared with where the corner really lies (RMS, metres).

`plausibility_problems` lists what makes a solved pose unusable (camera under the floor, the
horizon below the board, error above the gate, a camera far from the robot), each one line.

Board frame (the user's words: "--board-center-m X,Y, its columns run across the robot"): the
board lies flat with one grid axis across the robot (along y) and the other along x; its centre
(the centre of the inner-corner grid) is at (X, Y) in the robot frame. Which detected axis is
which, and in which direction it runs, is read from the photo itself (the axis more horizontal in
the image runs across the robot; image right is the robot's right, image down is towards the
robot), so neither OpenCV's corner order nor a board turned by 90° or 180° matters.

Pure: arrays in, frozen results out; no files, no printing, no clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.calibration import MIN_MOUNT_HEIGHT_M, CameraCalibration, Undistorter
from lanewarden.perception.chessboard import ChessboardPattern
from lanewarden.perception.errors import PerceptionError
from lanewarden.perception.ground import CameraPose, GroundModel

FloatArray = NDArray[np.float64]

#: A camera this far (horizontally) from the robot's centre is not on a Kobuki: most likely
#: --board-center-m or --square is wrong.
MAX_CAMERA_OFFSET_M = 1.0
#: A camera rolled further than this about its optical axis is not mounted on a robot that
#: follows a lane (the mount keeps it level); most likely the board was not lying flat on the
#: floor (held up, leaning on a wall). A camera really mounted rolled: calibrate from the mount
#: (`--roll-deg`).
MAX_PLAUSIBLE_ROLL_DEG = 10.0


@dataclass(frozen=True, eq=False)
class FloorChessboardSolution:
    """The pose solved from one floor chessboard photo.

    - `pose`: the camera pose (robot frame).
    - `model`: the ground model of that pose with the calibration's K (None when the solved
      camera is under the floor: no floor to project onto).
    - `corners_px`: (N, 2) the board's corners in the UNDISTORTED image, in grid order (rows far
      to near, columns left to right as the robot sees them).
    - `floor_points`: (N, 2) where those corners lie on the floor (robot frame, metres).
    - `floor_errors_m`: (N,) distance on the floor between each corner's true position and where
      the solved pose projects its pixel (NaN when the pixel is at or above the solved horizon).
    - `reprojection_error_m`: RMS of `floor_errors_m` (inf when any is NaN).
    - `image_error_px`: RMS reprojection error in the undistorted image, pixels.
    """

    pose: CameraPose
    model: GroundModel | None
    corners_px: FloatArray
    floor_points: FloatArray
    floor_errors_m: FloatArray
    reprojection_error_m: float
    image_error_px: float


def pose_from_mount(height_m: float, pitch_deg: float, roll_deg: float = 0.0,
                    forward_m: float = 0.0, lateral_m: float = 0.0,
                    yaw_deg: float = 0.0) -> CameraPose:
    """A measured mount as a pose; PerceptionError naming the flag for impossible values."""
    checks = (("--height-m", height_m, MIN_MOUNT_HEIGHT_M, 5.0,
               f"a height above the floor, {MIN_MOUNT_HEIGHT_M:g}..5 m"),
              ("--pitch-deg", pitch_deg, -90.0, 90.0, "-90..90 deg (down is +)"),
              ("--roll-deg", roll_deg, -90.0, 90.0, "-90..90 deg"),
              ("--yaw-deg", yaw_deg, -90.0, 90.0, "-90..90 deg"),
              ("--forward-m", forward_m, -2.0, 2.0, "-2..2 m"),
              ("--lateral-m", lateral_m, -2.0, 2.0, "-2..2 m"))
    for flag, value, low, high, expected in checks:
        if not (math.isfinite(value) and low <= value <= high):
            raise PerceptionError(f"{flag} {value:g}: expected {expected}")
    return CameraPose(height_m=height_m, pitch_deg=pitch_deg, roll_deg=roll_deg,
                      yaw_deg=yaw_deg, forward_m=forward_m, lateral_m=lateral_m)


def board_floor_points(pattern: ChessboardPattern, square_m: float,
                       centre_xy: tuple[float, float], across: int, along: int) -> FloatArray:
    """(along, across, 2) floor positions (robot frame) of a board's inner corners lying with
    `across` corners per row across the robot, rows numbered from the FAR end, columns from the
    robot's LEFT (as the camera sees them: top to bottom, left to right)."""
    if {across, along} != {pattern.columns, pattern.rows} or across * along != pattern.corner_count:
        raise ValueError(f"{across}x{along} is not the pattern {pattern}")
    cx, cy = centre_xy
    cols = np.arange(across, dtype=np.float64)
    rows = np.arange(along, dtype=np.float64)
    y = cy + ((across - 1) / 2.0 - cols) * square_m
    x = cx + ((along - 1) / 2.0 - rows) * square_m
    grid = np.empty((along, across, 2))
    grid[:, :, 0] = x[:, None]
    grid[:, :, 1] = y[None, :]
    return grid


def order_as_seen(corners_px: FloatArray, pattern: ChessboardPattern) -> FloatArray:
    """The detected corners (N, 2, OpenCV's order: rows of `pattern.columns`) as a grid
    (rows, columns, 2) running top to bottom and left to right in the image: the axis more
    horizontal in the image becomes the columns (across the robot)."""
    grid = np.asarray(corners_px, dtype=np.float64).reshape(pattern.rows, pattern.columns, 2)
    fast = (grid[:, -1] - grid[:, 0]).mean(axis=0)  # along a detected row
    slow = (grid[-1, :] - grid[0, :]).mean(axis=0)  # down a detected column
    if abs(fast[0]) / max(np.linalg.norm(fast), 1e-12) < abs(slow[0]) / max(
            np.linalg.norm(slow), 1e-12):
        grid = grid.transpose(1, 0, 2)
        fast, slow = slow, fast
    if fast[0] < 0:
        grid = grid[:, ::-1]
    if slow[1] < 0:
        grid = grid[::-1, :]
    return np.ascontiguousarray(grid)


def solve_floor_chessboard(
    corners_px: FloatArray,
    pattern: ChessboardPattern,
    square_m: float,
    centre_xy: tuple[float, float],
    calibration: CameraCalibration,
) -> FloorChessboardSolution:
    """The camera pose from a floor chessboard's detected (distorted) corners.

    Undistorts the corners with `calibration`, orders them as seen (`order_as_seen`), solves
    the planar PnP (both IPPE solutions are refined and the one putting the camera above the
    floor with the smaller error is kept) and measures the error on the floor."""
    if not (math.isfinite(square_m) and square_m > 0):
        raise PerceptionError(f"--square {square_m}: expected a positive length in metres")
    undistorted = Undistorter(calibration).undistort_points(
        np.asarray(corners_px, dtype=np.float64).reshape(-1, 2))
    grid_px = order_as_seen(undistorted, pattern)
    along, across = grid_px.shape[:2]
    floor = board_floor_points(pattern, square_m, centre_xy, across, along).reshape(-1, 2)
    image = grid_px.reshape(-1, 2)
    k = np.asarray(calibration.camera_matrix, dtype=np.float64)
    obj = np.column_stack([floor, np.zeros(len(floor))])
    try:
        _, rvecs, tvecs, _ = cv2.solvePnPGeneric(obj, image, k, None, flags=cv2.SOLVEPNP_IPPE)
    except cv2.error as exc:
        raise PerceptionError(f"floor chessboard: the pose cannot be solved ({exc.err})") from exc
    best: tuple[bool, float, FloatArray, FloatArray] | None = None
    for rvec, tvec in zip(rvecs, tvecs, strict=True):
        rvec, tvec = cv2.solvePnPRefineLM(obj, image, k, None, rvec.copy(), tvec.copy())
        projected, _ = cv2.projectPoints(obj, rvec, tvec, k, None)
        error = float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - image) ** 2, axis=1))))
        rotation = np.asarray(cv2.Rodrigues(rvec)[0], dtype=np.float64)
        position = -rotation.T @ np.asarray(tvec, dtype=np.float64).reshape(3)
        key = (position[2] > 0, -error)
        if best is None or key > (best[0], -best[1]):
            best = (bool(position[2] > 0), error, rotation, position)
    if best is None:
        raise PerceptionError("floor chessboard: the pose cannot be solved (no PnP solution)")
    _, image_error, rotation, position = best
    pose = CameraPose.from_rotation(rotation, position)
    # A camera under the floor has no ground model: keep the pose for the report, measure
    # nothing on the floor.
    if pose.height_m <= 0:
        nan = np.full(len(floor), np.nan)
        return FloorChessboardSolution(pose, None, image, floor, nan, math.inf, image_error)
    model = GroundModel(k, pose, calibration.image_size)
    seen = model.image_to_floor(image)
    errors = np.linalg.norm(seen - floor, axis=1)
    rms = float(np.sqrt(np.mean(errors ** 2))) if np.all(np.isfinite(errors)) else math.inf
    return FloorChessboardSolution(pose, model, image, floor, errors, rms, image_error)


def plausibility_problems(solution: FloorChessboardSolution, max_error_m: float) -> list[str]:
    """What makes a solved pose unusable, one line each (empty: plausible)."""
    pose = solution.pose
    problems: list[str] = []
    model = solution.model
    if model is None or pose.height_m <= 0:
        problems.append(
            f"the solved camera is {-pose.height_m:.3f} m UNDER the floor: the board is not "
            "lying flat on the floor as seen from above, or the photo is mirrored")
        return problems
    corners = solution.corners_px
    horizon = np.array([model.horizon_v(float(u)) for u in corners[:, 0]])
    above = corners[:, 1] <= horizon
    if np.any(above):
        top = float(corners[:, 1].min())
        problems.append(
            f"the solved horizon (row {model.horizon_v():.0f}) lies below the board (its top "
            f"corners at row {top:.0f}): the board cannot be on the floor (is the photo upside "
            "down, or the board not lying flat?)")
    error = solution.reprojection_error_m
    if not error <= max_error_m:
        problems.append(
            f"reprojection error on the floor {error * 1000:.1f} mm exceeds "
            f"calibration.max_ground_error_m {max_error_m * 1000:g} mm: is the board flat and "
            "--square right?")
    if not abs(pose.roll_deg) <= MAX_PLAUSIBLE_ROLL_DEG:
        problems.append(
            f"the solved camera is rolled {pose.roll_deg:+.1f}° about its axis (a camera on the "
            f"robot is level to within {MAX_PLAUSIBLE_ROLL_DEG:g}°): is the board lying flat on "
            "the floor? (a camera mounted rolled: calibrate from the mount with --roll-deg)")
    offset = math.hypot(pose.forward_m, pose.lateral_m)
    if offset > MAX_CAMERA_OFFSET_M:
        problems.append(
            f"the solved camera is {offset:.2f} m from the robot's centre (at x "
            f"{pose.forward_m:+.2f} m, y {pose.lateral_m:+.2f} m): is --board-center-m right "
            "(metres, robot frame)?")
    return problems

