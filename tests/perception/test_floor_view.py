"""The compiled projection of the lines' ends (`line_kernel.floor_points`) gives, point for point,
exactly what `FloorView.to_floor` gives (the line ends of every frame go through the first; the
edge choice measures pairs through the second: the two must agree to the last bit, and say NaN
at the same pixels)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.detector import LaneDetector
from lanewarden.perception.floor_view import MIN_SCALE
from lanewarden.perception.line_kernel import floor_points


@pytest.mark.parametrize("size", [(320, 240), (640, 480)])
def test_the_compiled_projection_is_the_scalar_one_point_for_point(size: tuple[int, int]) -> None:
    view = LaneDetector(PerceptionConfig()).setup_for(*size).view
    rng = np.random.default_rng(7)
    width, height = size
    # Rows from far above the image (the default camera looks down: its horizon lies above
    # the frame's top, and beyond it there is no floor) to its bottom, at random sub-pixel
    # columns, some outside the image.
    v = np.repeat(np.arange(-3.0 * height, height, 0.5), 3)
    u = rng.uniform(-0.2 * width, 1.2 * width, len(v))
    expected = [view.to_floor(float(a), float(b)) for a, b in zip(u, v, strict=True)]
    above = sum(1 for x, _ in expected if math.isnan(x))
    assert 0 < above < len(expected)  # both kinds of pixel are asked about
    # (as line ends: (x|y, near|far, line), the far ends the same points backwards)
    ends = np.array(((u, u[::-1]), (v, v[::-1])))
    on_floor = floor_points(ends, view.image_to_floor_flat, view.below_sign, MIN_SCALE)
    for got in (on_floor[:, 0], on_floor[:, 1, ::-1]):
        for k, (x, y) in enumerate(expected):
            if math.isnan(x):
                assert math.isnan(got[0, k]) and math.isnan(got[1, k]), (u[k], v[k])
            else:
                assert (float(got[0, k]), float(got[1, k])) == (x, y), (u[k], v[k])
