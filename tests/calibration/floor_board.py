"""Floor chessboard photos through random robot cameras, for the `calibrate ground` tests.

A camera: the scenarios renderer's `CameraModel` with a seeded random mount (height 0.15-0.50 m,
pitch 20-55 deg, HFOV 55-90 deg, roll within +-3 deg, 0.05-0.20 m ahead of the robot's centre) and
the default lens distortion. The board lies flat where the image centre looks, its square as large
as fits in the image (the board a user would choose for that camera).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from lanewarden.perception.chessboard import ChessboardPattern
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.chessboard import ChessboardRenderer, floor_board_pose

PATTERN = ChessboardPattern(7, 5)
SQUARES_M = (0.06, 0.05, 0.04, 0.03, 0.025, 0.02, 0.015, 0.012, 0.01)


@dataclass(frozen=True)
class FloorPhoto:
    camera: CameraModel
    image: np.ndarray
    square_m: float
    centre_xy: tuple[float, float]


def random_camera(rng: np.random.Generator, size: tuple[int, int] = (640, 480)) -> CameraModel:
    return CameraModel(
        width_px=size[0], height_px=size[1], hfov_deg=float(rng.uniform(55.0, 90.0)),
        height_m=float(rng.uniform(0.15, 0.50)), pitch_down_deg=float(rng.uniform(20.0, 55.0)),
        roll_deg=float(rng.uniform(-3.0, 3.0)), forward_offset_m=float(rng.uniform(0.05, 0.20)))


def floor_photo(camera: CameraModel, rng: np.random.Generator,
                pattern: ChessboardPattern = PATTERN) -> FloorPhoto:
    """The board under the image centre (a little off it, seeded), largest square that fits."""
    x, y = camera.ground.image_to_floor(np.array(
        [[camera.width_px / 2.0, camera.height_px * 0.55]]))[0]
    centre = (round(float(x), 3), round(float(y + rng.uniform(-0.01, 0.01)), 3))
    for square in SQUARES_M:
        renderer = ChessboardRenderer(camera, pattern.columns, pattern.rows, square)
        pose = floor_board_pose(renderer, centre)
        if renderer.fits(pose, margin_px=10.0):
            image = renderer.render(pose, noise_sigma=2.0, rng=rng)
            return FloorPhoto(camera, image, square, centre)
    raise AssertionError(f"no board fits the view of {camera}")
