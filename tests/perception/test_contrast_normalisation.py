"""The contrast normalisation reads a dim frame's spread on a sparse grid of the ROI and stretches
the blurred image about its mean (`LaneDetector._normalise_contrast`, `SizeSetup.contrast_samples`).
Expected values are computed here with numpy from the grid and the ROI mask, not by the code under
test."""

from __future__ import annotations

import numpy as np

from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.detector import LaneDetector

CONFIG = PerceptionConfig()


def _grid_values(image: np.ndarray, mask: np.ndarray, step: int) -> np.ndarray:
    """The image at every `step`-th row and column where the ROI mask is set, in row order."""
    grid = image[::step, ::step]
    return grid[mask[::step, ::step] > 0]


def test_the_samples_are_the_grid_points_inside_the_roi() -> None:
    detector = LaneDetector(CONFIG)
    for width, height in ((320, 240), (640, 480), (224, 224)):
        setup = detector.setup_for(width, height)
        step = setup.contrast_step
        assert step == max(1, height // 60)
        index = np.arange(width * height).reshape(height, width)
        expected = _grid_values(index, setup.mask, step)
        assert len(expected) > 0
        assert setup.contrast_samples.tolist() == expected.tolist()


def test_a_dim_frame_is_stretched_to_the_target_spread_and_a_clear_one_is_left_alone() -> None:
    detector = LaneDetector(CONFIG)
    setup = detector.setup_for(320, 240)
    rng = np.random.default_rng(7)
    dim = (100 + rng.integers(0, 6, size=(240, 320))).astype(np.uint8)  # spread about 1.7 levels
    np.copyto(setup.smooth, dim)
    detector._normalise_contrast(setup)
    values = _grid_values(dim, setup.mask, setup.contrast_step).astype(np.float64)
    gain = min(CONFIG.contrast.max_gain, CONFIG.contrast.target_std_levels / values.std())
    assert gain > 1.0
    stretched = np.clip(np.rint(gain * dim + (1.0 - gain) * values.mean()), 0, 255)
    assert np.abs(setup.smooth.astype(np.int16) - stretched).max() <= 1

    clear = rng.integers(0, 256, size=(240, 320)).astype(np.uint8)  # spread about 74 levels
    np.copyto(setup.smooth, clear)
    detector._normalise_contrast(setup)
    assert np.array_equal(setup.smooth, clear)
