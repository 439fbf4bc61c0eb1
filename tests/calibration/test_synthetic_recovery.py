"""Calibrating rendered views recovers the camera that rendered them; undistortion straightens."""

from __future__ import annotations

import cv2
import numpy as np

from lanewarden.perception.calibration import Undistorter
from lanewarden.perception.calibration_config import CalibrationConfig
from lanewarden.perception.chessboard import ChessboardPattern, detect_view
from lanewarden.perception.chessboard_calibration import calibrate_views, gate_failures
from lanewarden.scenarios.chessboard import ChessboardRenderer, facing_pose
from tests.calibration.conftest import SyntheticViews


def _straightness_px(corners: np.ndarray, pattern: ChessboardPattern) -> float:
    """Largest distance of a corner from the straight line fitted to its row or column."""
    grid = corners.reshape(pattern.rows, pattern.columns, 2).astype(np.float32)
    worst = 0.0
    for line in list(grid) + list(grid.transpose(1, 0, 2)):
        vx, vy, x0, y0 = cv2.fitLine(line, cv2.DIST_L2, 0, 0.01, 0.01).ravel()
        distance = np.abs((line[:, 0] - x0) * vy - (line[:, 1] - y0) * vx)
        worst = max(worst, float(distance.max()))
    return worst


def test_renderer_puts_corners_where_the_camera_projects_them(
    synthetic_views: SyntheticViews,
) -> None:
    config = CalibrationConfig()
    pattern = ChessboardPattern(9, 6)
    for pose, image in zip(synthetic_views.poses[:5], synthetic_views.images[:5], strict=True):
        view = detect_view(image, pattern, config, name="synthetic")
        assert view.accepted, view.rejection
        truth = synthetic_views.renderer.corners_px(pose)
        found = np.asarray(view.corners, dtype=np.float64)
        # OpenCV may number the corners from the opposite end of the board.
        error = min(np.abs(found - truth).max(), np.abs(found[::-1] - truth).max())
        assert error < 0.25


def test_calibration_recovers_the_rendering_camera(synthetic_views: SyntheticViews) -> None:
    config = CalibrationConfig()
    pattern = ChessboardPattern(9, 6)
    views = [detect_view(image, pattern, config, name=f"view_{i:02d}")
             for i, image in enumerate(synthetic_views.images)]
    assert sum(v.accepted for v in views) == len(views)
    run = calibrate_views(views, pattern, 0.025, (640, 480), config)
    truth = synthetic_views.camera.camera_matrix()
    found = run.calibration
    for got, want in ((found.fx, truth[0, 0]), (found.fy, truth[1, 1]),
                      (found.cx, truth[0, 2]), (found.cy, truth[1, 2])):
        assert abs(got - want) / want < 0.01, (got, want)
    assert abs(found.dist_coeffs[0] - synthetic_views.camera.dist_coeffs[0]) < 0.02
    assert run.rms < 0.2
    assert gate_failures(run, config) == []

    # Lines straight in the world: the rows and columns of a board filling most of the image.
    big = ChessboardRenderer(synthetic_views.camera, columns=15, rows=11, square_m=0.02,
                             border_squares=0.5)
    image = big.render(facing_pose(big, 0.25), noise_sigma=1.0, rng=np.random.default_rng(5))
    big_pattern = ChessboardPattern(15, 11)
    before = detect_view(image, big_pattern, config, name="before")
    after = detect_view(Undistorter(found).apply(image), big_pattern, config, name="after")
    assert before.accepted and after.accepted
    assert _straightness_px(np.asarray(before.corners), big_pattern) > 3.0  # the lens bends them
    assert _straightness_px(np.asarray(after.corners), big_pattern) < 1.0
