"""Image-plane geometry of lane edges, and the lecture's slope convention.

Frames: pixels, origin at the top-left corner, x to the right, y DOWN (OpenCV's convention). An
edge is stored as a segment from its NEAR end (larger y, closer to the robot) to its FAR end.

Slope convention (the lecture's): the y axis points UP, so for an edge from (x1, y1) to (x2, y2)

    slope = -(y2 - y1) / (x2 - x1)

and, on a straight lane seen from its centre, the left edge leans "/" (positive slope), the right
edge leans "\\" (negative slope), and their sum is about 0. When the lane bends to the RIGHT its far
part shifts right in the image: the left edge flattens (smaller positive slope) and the right edge
steepens towards vertical (large negative slope), so the sum goes negative; below
-`turn_slope_sum` (the lecture's -6) means "turn right". A left bend mirrors this (sum > +6).

Near-vertical robustness: the raw dy/dx explodes and flips sign as an edge passes vertical (one
pixel of noise at the far end can turn +50 into -50). `lecture_slope` is bounded and side-aware:
- |slope| is clamped to `max_abs_slope`;
- an edge rotated past vertical the "wrong" way for its side (a right edge leaning "/", which a
  sharp right bend's inner edge does; a left edge leaning "\\") reports the clamp value with its
  side's continuation sign (right edge -> -max_abs_slope, left edge -> +max_abs_slope).
So each side's slope is a continuous, monotonic function of the edge's angle that never changes
sign (left >= 0, right <= 0) and never exceeds the clamp: no infinities, no flips.

Pure math on floats and numpy arrays: no images, no state.
"""

from __future__ import annotations

import math
from typing import Literal

Side = Literal["left", "right"]


def other_side(side: Side) -> Side:
    """The lane's other side."""
    return "right" if side == "left" else "left"


def edge_angle_deg(x1: float, y1: float, x2: float, y2: float) -> float:
    """Direction of the segment from its near end (x1, y1) to its far end (x2, y2), in degrees,
    counter-clockwise from the +x axis with y UP: in [0, 180] for a segment that rises.
    Below 90 the edge leans "/", above 90 it leans "\\", 90 is vertical."""
    return math.degrees(math.atan2(y1 - y2, x2 - x1))


def lecture_slope(angle_deg: float, side: Side, max_abs_slope: float) -> float:
    """Bounded, side-aware slope (y up) of an edge at `angle_deg` (see `edge_angle_deg`).

    Left edges: tan(angle) for "/" edges, clamped to +max_abs_slope, and +max_abs_slope for
    vertical or past-vertical ("\\") edges. Right edges: mirror image, in [-max_abs_slope, 0].
    Monotonic non-decreasing in the angle for both sides, continuous, never sign-flipping.
    """
    if side == "left":
        if angle_deg >= 90.0:
            return max_abs_slope
        if angle_deg <= 0.0:
            return 0.0
        return min(math.tan(math.radians(angle_deg)), max_abs_slope)
    if angle_deg <= 90.0:
        return -max_abs_slope
    if angle_deg >= 180.0:
        return 0.0
    return max(math.tan(math.radians(angle_deg)), -max_abs_slope)


def edge_slope(
    x1: float, y1: float, x2: float, y2: float, side: Side, max_abs_slope: float
) -> float:
    """`lecture_slope` of the segment from its near end (x1, y1) to its far end (x2, y2),
    computed from dy/dx directly (exact where unclamped): -(y2 - y1) / (x2 - x1), bounded and
    side-aware."""
    dx = x2 - x1
    dy_up = y1 - y2
    if side == "left":
        if dx <= 0.0:  # vertical or leaning "\": past vertical for a left edge
            return max_abs_slope if dy_up >= 0.0 else 0.0
        return min(max(dy_up / dx, 0.0), max_abs_slope)
    if dx >= 0.0:  # vertical or leaning "/": past vertical for a right edge
        return -max_abs_slope if dy_up >= 0.0 else 0.0
    return max(min(dy_up / dx, 0.0), -max_abs_slope)


def x_at_row(x1: float, y1: float, x2: float, y2: float, row: float) -> float:
    """Column where the infinite line through the two points crosses image row `row`; for a
    horizontal line (never a lane edge), the middle of the two points."""
    if y2 == y1:
        return 0.5 * (x1 + x2)
    return x1 + (row - y1) * (x2 - x1) / (y2 - y1)


def intersect_lines(
    a: tuple[float, float, float, float], b: tuple[float, float, float, float]
) -> tuple[float, float] | None:
    """Intersection of the infinite lines through segments a and b (x1, y1, x2, y2), or None
    when they are (nearly) parallel."""
    ax, ay = a[2] - a[0], a[3] - a[1]
    bx, by = b[2] - b[0], b[3] - b[1]
    den = ax * by - ay * bx
    if abs(den) < 1e-9 * (math.hypot(ax, ay) * math.hypot(bx, by) + 1e-12):
        return None
    t = ((b[0] - a[0]) * by - (b[1] - a[1]) * bx) / den
    return a[0] + t * ax, a[1] + t * ay
