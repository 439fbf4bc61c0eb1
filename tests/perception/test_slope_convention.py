"""The lecture's slope convention and its near-vertical robustness."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.detector import LaneDetector
from lanewarden.perception.geometry import (
    Side,
    edge_angle_deg,
    edge_slope,
    intersect_lines,
    lecture_slope,
    x_at_row,
)

MAX = 12.0


def slope_of(x1: float, y1: float, x2: float, y2: float, side: Side) -> float:
    """The detector's computation; it must agree with the angle-based definition."""
    value = edge_slope(x1, y1, x2, y2, side, MAX)
    assert value == pytest.approx(lecture_slope(edge_angle_deg(x1, y1, x2, y2), side, MAX))
    return value


def test_y_points_up() -> None:
    # A left edge "/" rising from (100, 400) to (200, 200): dy_image = -200, dx = 100 -> +2.
    assert slope_of(100, 400, 200, 200, "left") == pytest.approx(2.0)
    # Its mirror image on the right: -2. A straight lane seen from the centre sums to 0.
    assert slope_of(540, 400, 440, 200, "right") == pytest.approx(-2.0)
    assert slope_of(100, 400, 200, 200, "left") + slope_of(540, 400, 440, 200, "right") == 0.0


def test_right_bend_makes_the_sum_negative() -> None:
    """Far lane shifted right: the left edge flattens, the right edge steepens towards vertical."""
    straight = slope_of(100, 400, 200, 200, "left") + slope_of(540, 400, 440, 200, "right")
    left = slope_of(100, 400, 300, 250, "left")  # flatter "/"
    right = slope_of(540, 400, 530, 200, "right")  # nearly vertical "\"
    assert left + right < straight
    assert left + right < -6.0


def test_clamped_and_continued_past_vertical() -> None:
    # Exactly vertical and past vertical the "wrong" way: the side's continuation sign.
    assert slope_of(300, 400, 300, 100, "left") == MAX
    assert slope_of(300, 400, 290, 100, "left") == MAX  # left edge leaning "\"
    assert slope_of(300, 400, 300, 100, "right") == -MAX
    assert slope_of(300, 400, 310, 100, "right") == -MAX  # right edge leaning "/"
    # The raw dy/dx of the same one-pixel-apart segments is +-300: the flip this avoids.
    assert -(100 - 400) / (301 - 300) == 300 and -(100 - 400) / (299 - 300) == -300


@settings(derandomize=True, max_examples=300, deadline=None)
@given(
    side=st.sampled_from(["left", "right"]),
    length=st.floats(min_value=20.0, max_value=480.0),
    dx=st.floats(min_value=-40.0, max_value=40.0),
    nudge=st.sampled_from([-1.0, 1.0]),
    which=st.sampled_from(["near", "far"]),
)
def test_one_pixel_near_vertical_is_bounded_and_never_flips(
    side: Side, length: float, dx: float, nudge: float, which: str
) -> None:
    x1, y1, x2, y2 = 320.0, 470.0, 320.0 + dx, 470.0 - length
    before = slope_of(x1, y1, x2, y2, side)
    if which == "near":
        x1 += nudge
    else:
        x2 += nudge
    after = slope_of(x1, y1, x2, y2, side)
    for value in (before, after):
        assert math.isfinite(value) and abs(value) <= MAX
        assert value >= 0.0 if side == "left" else value <= 0.0
    # d(tan)/d(angle) <= 1 + MAX^2 where it is not clamped; one pixel turns the segment by
    # at most 1 / length radians.
    assert abs(after - before) <= (1.0 + MAX**2) / length + 1e-9


@settings(derandomize=True, max_examples=200, deadline=None)
@given(a=st.floats(min_value=0.0, max_value=180.0), b=st.floats(min_value=0.0, max_value=180.0))
def test_slope_is_monotonic_in_the_angle_for_each_side(a: float, b: float) -> None:
    lo, hi = min(a, b), max(a, b)
    for side in ("left", "right"):
        assert lecture_slope(lo, side, MAX) <= lecture_slope(hi, side, MAX)


def _lane_image(top_x_left: int) -> np.ndarray:
    """A dark-tape lane drawn straight in image space; the left tape's top can be moved."""
    image = np.full((480, 640), 180, np.uint8)
    # Left tape: inner edge from (150, 479) up to (top_x_left, 60), 40 px wide at the bottom.
    cv2.fillConvexPoly(
        image, np.array([[110, 479], [150, 479], [top_x_left, 60], [top_x_left - 20, 60]]), 40
    )
    cv2.fillConvexPoly(image, np.array([[490, 479], [530, 479], [440, 60], [420, 60]]), 40)
    return image


def test_detector_near_vertical_edge_does_not_flip() -> None:
    """The left tape's inner edge stands vertical; moving its top one pixel either way moves the
    reported left slope by a bounded amount and never changes its sign."""
    detector = LaneDetector(PerceptionConfig())
    slopes = []
    for top in (149, 150, 151):
        obs = detector.detect(_lane_image(top), 0, 0.0)
        assert obs.left is not None
        slopes.append(obs.left.slope)
    assert all(0.0 < s <= MAX for s in slopes), slopes
    assert max(slopes) - min(slopes) <= 4.0, slopes


def test_line_helpers() -> None:
    assert x_at_row(0, 0, 10, 10, 5) == 5
    assert intersect_lines((0, 0, 10, 10), (0, 10, 10, 0)) == pytest.approx((5.0, 5.0))
    assert intersect_lines((0, 0, 10, 10), (0, 1, 10, 11)) is None
