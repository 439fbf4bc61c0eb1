"""The ground model as the detector uses it per frame: single points and lines, in plain floats.

A frame has a few dozen candidate lines and a handful of tape candidates; projecting their points
one at a time through the floor <-> image homographies in plain Python is several times faster
than numpy on arrays of two points. `FloorView` holds both homographies of one
`perception.ground.GroundModel` (one camera at one image size) as tuples.

Frames: image = undistorted pixels (u right, v down); floor = robot frame metres (x forward,
y left). A floor line is given by two floor points; directions are unit vectors.

Pure math: no images, no clock.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.ground import GroundModel

Point = tuple[float, float]
FloatArray = NDArray[np.float64]

#: A pixel whose ray meets the floor at a homogeneous scale below this is at or above the
#: horizon (no floor there).
MIN_SCALE = 1e-12


def _as_tuple(h: np.ndarray) -> tuple[float, ...]:
    return tuple(float(v) for v in np.asarray(h, dtype=np.float64).reshape(9))


class FloorView:
    """Floor <-> image for one ground model, point by point. `ground` is kept for callers that
    need the numpy API (`GroundModel.image_to_floor` on many points at once)."""

    def __init__(self, ground: GroundModel) -> None:
        self.ground = ground
        self._to_image = _as_tuple(ground.floor_to_image_h)
        self._to_floor = _as_tuple(ground.image_to_floor_h)
        # The sign the homogeneous scale of image_to_floor has for pixels BELOW the horizon
        # (looking at the floor in front of the camera), taken at the floor straight ahead.
        ahead = ground.position[0] + 1.0, ground.position[1]
        u, v = self.to_image(*ahead)
        h = self._to_floor
        self.below_sign = 1.0 if h[6] * u + h[7] * v + h[8] > 0 else -1.0
        #: image_to_floor's nine values, row by row (for compiled code: `perception.line_kernel`)
        self.image_to_floor_flat = np.array(self._to_floor)
        self.image_to_floor_flat.flags.writeable = False

    def to_image(self, x: float, y: float) -> Point:
        """Floor point -> undistorted pixel (NaN behind the camera)."""
        h = self._to_image
        w = h[6] * x + h[7] * y + h[8]
        if w <= MIN_SCALE:
            return math.nan, math.nan
        return (h[0] * x + h[1] * y + h[2]) / w, (h[3] * x + h[4] * y + h[5]) / w

    def to_floor(self, u: float, v: float) -> Point:
        """Undistorted pixel -> floor point (NaN at or above the horizon)."""
        h = self._to_floor
        w = h[6] * u + h[7] * v + h[8]
        if w * self.below_sign <= MIN_SCALE:
            return math.nan, math.nan
        return (h[0] * u + h[1] * v + h[2]) / w, (h[3] * u + h[4] * v + h[5]) / w

    def metres_per_px_across(self, u: float, v: float, du: float, dv: float,
                             floor_normal: Point, floor_at: Point | None = None) -> float:
        """How far, in metres along `floor_normal` (unit), one pixel step perpendicular to the
        image direction (du, dv) (unit) at pixel (u, v) moves on the floor: the size of one pixel
        of error in a width measured across a line running that way. NaN above the horizon.
        `floor_at`: `to_floor(u, v)` when the caller has it already."""
        x0, y0 = self.to_floor(u, v) if floor_at is None else floor_at
        x1, y1 = self.to_floor(u - dv, v + du)
        return abs((x1 - x0) * floor_normal[0] + (y1 - y0) * floor_normal[1])

    def line_column_at(self, a: Point, b: Point, v: float) -> float:
        """Column where the image of the floor line through a and b crosses image row v (NaN if
        it runs along the row or a point is behind the camera)."""
        return column_at(self.image_line(a, b), v)

    def image_line(self, a: Point, b: Point) -> tuple[float, float, float, float]:
        """The images (ua, va, ub, vb) of floor points a and b, for `column_at` at many rows."""
        return (*self.to_image(*a), *self.to_image(*b))


def column_at(image_line: tuple[float, float, float, float], v: float) -> float:
    """Column where the image line through (ua, va) and (ub, vb) (`FloorView.image_line`)
    crosses image row v (NaN if it runs along the row or a point is behind the camera)."""
    ua, va, ub, vb = image_line
    if not (math.isfinite(ua) and math.isfinite(ub)) or abs(vb - va) < 1e-12:
        return math.nan
    return ua + (v - va) * (ub - ua) / (vb - va)


def direction(a: Point, b: Point) -> Point:
    """Unit vector from a to b ((0, 0) when they coincide)."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = math.hypot(dx, dy)
    if n < 1e-15:
        return 0.0, 0.0
    return dx / n, dy / n


def distance_to_line(p: Point, a: Point, d: Point) -> float:
    """Unsigned distance from p to the line through a with unit direction d."""
    return abs(d[0] * (p[1] - a[1]) - d[1] * (p[0] - a[0]))


def signed_offset(a: Point, d: Point) -> float:
    """Signed distance from the robot's origin to the line through a with unit direction d:
    positive when the line passes LEFT of the origin (for d pointing forward)."""
    return d[0] * a[1] - d[1] * a[0]
