"""Synthetic chessboard photos shared by the calibration tests (rendered once per session)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pytest

from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.chessboard import BoardPose, ChessboardRenderer, calibration_poses

SYNTHETIC_VIEWS = 15


@dataclass(frozen=True)
class SyntheticViews:
    camera: CameraModel
    renderer: ChessboardRenderer
    poses: tuple[BoardPose, ...]
    images: tuple[np.ndarray, ...]
    folder: Path  # view_00.png ... written to disk for CLI tests


@pytest.fixture(scope="session")
def synthetic_views(tmp_path_factory: pytest.TempPathFactory) -> SyntheticViews:
    """15 views of a 9x6, 25 mm board through CameraModel()'s K and distortion, seeded."""
    camera = CameraModel()
    renderer = ChessboardRenderer(camera, columns=9, rows=6, square_m=0.025)
    rng = np.random.default_rng(20240501)
    poses = tuple(calibration_poses(renderer, SYNTHETIC_VIEWS, rng))
    images = tuple(renderer.render(p, noise_sigma=2.0, rng=rng) for p in poses)
    folder = tmp_path_factory.mktemp("synthetic_chessboard")
    for i, image in enumerate(images):
        assert cv2.imwrite(str(folder / f"view_{i:02d}.png"), image)
    return SyntheticViews(camera, renderer, poses, images, folder)
