"""Synthetic chessboard photos through a known camera, for calibration tests and demos.

`ChessboardRenderer` draws a planar chessboard at a given pose exactly as a camera with known
intrinsics and lens distortion (`scenarios.camera.CameraModel`) would see it: for every pixel of
the (distorted) image it undistorts the pixel to a viewing ray once (at the first render),
intersects the ray with the board plane and shades the board point. Edges are anti-aliased with
their pixel footprint (a one pixel box filter, from the local gradient of the board
coordinates), so corners land on the true projection to well under 0.1 px. `calibration_poses`
gives varied, seeded board poses that keep the whole board (and its white border) inside the
image; `floor_board_pose` lays the board flat on the floor in front of the robot (the photo
`lanewarden calibrate ground` takes).

Frames:
- board: x along the columns of inner corners, y along the rows, z out of the board, metres;
  inner corner (i, j) is at (i * square_m, j * square_m, 0), matching OpenCV's detection order.
- camera: OpenCV (x right, y down, z forward); a pose (rvec, tvec) maps board to camera points.

Pure image synthesis: no files, no clock; randomness only from a passed-in numpy Generator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.scenarios.camera import CameraModel

FloatArray = NDArray[np.float64]

_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)


@dataclass(frozen=True)
class BoardPose:
    """Board-to-camera pose: p_camera = R(rvec) @ p_board + tvec (metres)."""

    rvec: tuple[float, float, float]
    tvec: tuple[float, float, float]

    def rotation(self) -> FloatArray:
        rot, _ = cv2.Rodrigues(np.asarray(self.rvec, dtype=np.float64))
        return np.asarray(rot, dtype=np.float64)


@dataclass(frozen=True)
class ChessboardLook:
    """Shades of the rendered scene, grey levels 0..255."""

    black: float = 25.0
    white: float = 225.0
    background: float = 110.0


class ChessboardRenderer:
    """Renders a `columns` x `rows` inner-corner chessboard through `camera` (viewing rays are
    computed once here, so each render is only a plane intersection and shading)."""

    def __init__(
        self,
        camera: CameraModel | None = None,
        columns: int = 9,
        rows: int = 6,
        square_m: float = 0.025,
        border_squares: float = 0.75,
        look: ChessboardLook | None = None,
    ) -> None:
        self.camera = camera if camera is not None else CameraModel()
        self.columns = columns
        self.rows = rows
        self.square_m = square_m
        self.border_squares = border_squares
        self.look = look if look is not None else ChessboardLook()

    @cached_property
    def _rays(self) -> FloatArray:
        """(H, W, 3) the viewing ray of every (distorted) pixel, camera frame, z = 1; computed
        on the first render (checking poses with `fits` does not need it)."""
        cam = self.camera
        u, v = np.meshgrid(
            np.arange(cam.width_px, dtype=np.float64), np.arange(cam.height_px, dtype=np.float64)
        )
        pix = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
        norm = cv2.undistortPoints(
            pix, cam.camera_matrix(), cam.distortion(), criteria=_UNDISTORT_CRITERIA
        ).reshape(cam.height_px, cam.width_px, 2)
        return np.dstack([norm, np.ones((cam.height_px, cam.width_px))])

    @property
    def image_size(self) -> tuple[int, int]:
        return (self.camera.width_px, self.camera.height_px)

    def object_points(self) -> FloatArray:
        """(N, 3) inner corners in the board frame, metres, in OpenCV's detection order."""
        grid = np.zeros((self.columns * self.rows, 3))
        grid[:, :2] = np.indices((self.columns, self.rows)).T.reshape(-1, 2) * self.square_m
        return grid

    def outline_points(self) -> FloatArray:
        """(4, 3) outer corners of the board including its white border, board frame."""
        pad = (1.0 + self.border_squares) * self.square_m
        x0, y0 = -pad, -pad
        x1 = (self.columns - 1) * self.square_m + pad
        y1 = (self.rows - 1) * self.square_m + pad
        return np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])

    def project(self, points_board: FloatArray, pose: BoardPose) -> FloatArray:
        """Board points (N, 3) -> distorted pixels (N, 2) through the camera."""
        img, _ = cv2.projectPoints(
            np.asarray(points_board, dtype=np.float64).reshape(-1, 1, 3),
            np.asarray(pose.rvec, dtype=np.float64),
            np.asarray(pose.tvec, dtype=np.float64),
            self.camera.camera_matrix(),
            self.camera.distortion(),
        )
        return np.asarray(img, dtype=np.float64).reshape(-1, 2)

    def corners_px(self, pose: BoardPose) -> FloatArray:
        """Ground truth (N, 2) pixel positions of the inner corners."""
        return self.project(self.object_points(), pose)

    def fits(self, pose: BoardPose, margin_px: float = 4.0) -> bool:
        """True when the whole board with its border projects inside the image, in front of the
        camera."""
        rot = pose.rotation()
        outline = self.outline_points()
        cam_pts = outline @ rot.T + np.asarray(pose.tvec)
        if np.any(cam_pts[:, 2] <= 0.05):
            return False
        # Sample the border densely: distortion bends its straight edges.
        edges = np.concatenate(
            [np.linspace(outline[i], outline[(i + 1) % 4], 25) for i in range(4)]
        )
        px = self.project(edges, pose)
        width, height = self.image_size
        return bool(
            np.all(px[:, 0] >= margin_px) and np.all(px[:, 0] <= width - 1 - margin_px)
            and np.all(px[:, 1] >= margin_px) and np.all(px[:, 1] <= height - 1 - margin_px)
        )

    def board_coordinates(
        self, pose: BoardPose
    ) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
        """For every pixel, the board point it sees, in squares: (a, b, valid) arrays (H, W)."""
        rot = pose.rotation()
        t = np.asarray(pose.tvec, dtype=np.float64)
        normal = rot[:, 2]
        denom = self._rays @ normal
        with np.errstate(divide="ignore", invalid="ignore"):
            depth = float(normal @ t) / denom
        valid = np.isfinite(depth) & (depth > 0)
        depth = np.where(valid, depth, 0.0)
        points = self._rays * depth[..., None] - t
        board = points @ rot  # rot.T applied to each point: camera -> board frame
        return board[..., 0] / self.square_m, board[..., 1] / self.square_m, valid

    def render(
        self,
        pose: BoardPose,
        *,
        noise_sigma: float = 0.0,
        blur_sigma_px: float = 0.0,
        noise_grain_px: float = 1.0,
        rng: np.random.Generator | None = None,
    ) -> NDArray[np.uint8]:
        """A gray uint8 (H, W) image of the board at `pose`.

        Optional lens blur (`blur_sigma_px`, Gaussian) and sensor noise (`noise_sigma` grey levels
        per pixel, spatially correlated over `noise_grain_px` like a real camera's demosaiced and
        compressed noise; 0 gives independent pixels)."""
        a, b, valid = self.board_coordinates(pose)
        grad_a = _gradient_norm(a)
        grad_b = _gradient_norm(b)
        # Squares span [-1, columns] x [-1, rows] in square units; (a, b) = (0, 0) is a corner.
        # Beyond the outermost squares the checker keeps the outer squares' shade (clamped to
        # their centres), so only `in_squares` blends them with the white border.
        soft_a = _soft_square_wave(np.clip(a, -0.5, self.columns - 0.5), grad_a)
        soft_b = _soft_square_wave(np.clip(b, -0.5, self.rows - 0.5), grad_b)
        checker = soft_a * soft_b  # +1 / -1 inside squares, blended across edges
        in_squares = _soft_box(a, -1.0, float(self.columns), grad_a) * _soft_box(
            b, -1.0, float(self.rows), grad_b
        )
        pad = 1.0 + self.border_squares
        on_board = _soft_box(a, -pad, self.columns - 1 + pad, grad_a) * _soft_box(
            b, -pad, self.rows - 1 + pad, grad_b
        )
        look = self.look
        mid = 0.5 * (look.white + look.black)
        amp = 0.5 * (look.white - look.black)
        squares = mid - amp * checker  # (a, b) in (0, 1) x (0, 1) is black: the OpenCV look
        board = look.white + (squares - look.white) * in_squares
        image = look.background + (board - look.background) * np.where(valid, on_board, 0.0)
        if blur_sigma_px > 0:
            image = np.asarray(cv2.GaussianBlur(image, (0, 0), blur_sigma_px), dtype=np.float64)
        if noise_sigma > 0:
            generator = rng if rng is not None else np.random.default_rng(0)
            noise = generator.normal(0.0, 1.0, image.shape)
            if noise_grain_px > 0:
                noise = np.asarray(cv2.GaussianBlur(noise, (0, 0), noise_grain_px))
            image = image + noise * (noise_sigma / max(float(noise.std()), 1e-12))
        return np.clip(np.rint(image), 0, 255).astype(np.uint8)


def _gradient_norm(values: FloatArray) -> FloatArray:
    """|grad| of a per-pixel coordinate, in units per pixel (never zero)."""
    filled = np.nan_to_num(values, nan=0.0, posinf=0.0, neginf=0.0)
    gy, gx = np.gradient(filled)
    return np.maximum(np.hypot(gx, gy), 1e-9)


def _soft_square_wave(coord: FloatArray, grad: FloatArray) -> FloatArray:
    """sign(sin(pi * coord)) box-filtered over one pixel: +-1 away from integers, linear across."""
    nearest = np.rint(coord)
    distance_px = np.abs(coord - nearest) / grad
    sign = np.where(np.floor(coord) % 2 == 0, 1.0, -1.0)
    return sign * np.clip(2.0 * distance_px, 0.0, 1.0)


def _soft_box(coord: FloatArray, low: float, high: float, grad: FloatArray) -> FloatArray:
    """1 inside [low, high], 0 outside, box-filtered over one pixel."""
    inside_px = np.minimum(coord - low, high - coord) / grad
    return np.clip(inside_px + 0.5, 0.0, 1.0)


def calibration_poses(
    renderer: ChessboardRenderer,
    count: int,
    rng: np.random.Generator,
    *,
    distance_m: tuple[float, float] = (0.28, 0.50),
    max_tilt_deg: float = 40.0,
    max_roll_deg: float = 25.0,
) -> list[BoardPose]:
    """`count` varied board poses (position across the image, distance, tilt and roll) that keep
    the whole board inside the image. Seeded by `rng`; raises RuntimeError if the ranges make
    that impossible."""
    cam = renderer.camera
    centre_board = _board_centre(renderer)
    k_inv = np.linalg.inv(cam.camera_matrix())
    poses: list[BoardPose] = []
    attempts = 0
    while len(poses) < count:
        attempts += 1
        if attempts > 200 * count:
            raise RuntimeError("calibration_poses: no pose fits the image; widen the ranges")
        target = np.array(
            [rng.uniform(0.15, 0.85) * cam.width_px, rng.uniform(0.15, 0.85) * cam.height_px, 1.0]
        )
        ray = k_inv @ target
        centre_cam = ray / np.linalg.norm(ray) * rng.uniform(*distance_m)
        tilt_x = math.radians(rng.uniform(-max_tilt_deg, max_tilt_deg))
        tilt_y = math.radians(rng.uniform(-max_tilt_deg, max_tilt_deg))
        roll = math.radians(rng.uniform(-max_roll_deg, max_roll_deg))
        rot = _rot_z(roll) @ _rot_y(tilt_y) @ _rot_x(tilt_x)
        tvec = centre_cam - rot @ centre_board
        rvec = np.asarray(cv2.Rodrigues(rot)[0], dtype=np.float64).reshape(3)
        pose = BoardPose(
            rvec=(float(rvec[0]), float(rvec[1]), float(rvec[2])),
            tvec=(float(tvec[0]), float(tvec[1]), float(tvec[2])),
        )
        if renderer.fits(pose):
            poses.append(pose)
    return poses


def facing_pose(
    renderer: ChessboardRenderer, distance_m: float, offset_px: tuple[float, float] = (0.0, 0.0)
) -> BoardPose:
    """The board square-on to the camera, its centre `distance_m` ahead, seen `offset_px` pixels
    from the principal point."""
    cam = renderer.camera
    centre_board = _board_centre(renderer)
    f = cam.focal_px
    centre_cam = np.array(
        [offset_px[0] / f * distance_m, offset_px[1] / f * distance_m, distance_m]
    )
    tvec = centre_cam - centre_board
    return BoardPose(rvec=(0.0, 0.0, 0.0), tvec=(float(tvec[0]), float(tvec[1]), float(tvec[2])))


def floor_board_pose(renderer: ChessboardRenderer, centre_xy: tuple[float, float]) -> BoardPose:
    """The board lying flat on the floor, the centre of its inner corners at `centre_xy` (robot
    frame, metres), its columns running across the robot (board x along the robot's -y, board y
    along -x: the camera sees columns left to right and rows far to near), through the
    renderer's camera on the robot (`CameraModel`'s pose): the photo `calibrate ground` takes."""
    cam = renderer.camera
    # board axes in the robot frame: x -> -y_robot, y -> -x_robot, z -> down
    board_to_robot = np.array([[0.0, -1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    centre = _board_centre(renderer)
    origin = np.array([centre_xy[0], centre_xy[1], 0.0]) - board_to_robot @ centre
    rot_robot = cam.rotation_robot_to_camera()
    rot = rot_robot @ board_to_robot
    tvec = rot_robot @ (origin - cam.position_robot())
    rvec = np.asarray(cv2.Rodrigues(rot)[0], dtype=np.float64).reshape(3)
    return BoardPose(rvec=(float(rvec[0]), float(rvec[1]), float(rvec[2])),
                     tvec=(float(tvec[0]), float(tvec[1]), float(tvec[2])))


def _board_centre(renderer: ChessboardRenderer) -> FloatArray:
    """Centre of the inner-corner grid, board frame, metres."""
    half = renderer.square_m / 2.0
    return np.array([(renderer.columns - 1) * half, (renderer.rows - 1) * half, 0.0])


def _rot_x(angle: float) -> FloatArray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_y(angle: float) -> FloatArray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot_z(angle: float) -> FloatArray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
