"""Everything the detector derives from the config and the ground model for one image size, once.

The config speaks metres on the floor (`perception.floor_config`); the detector works in pixels.
`SizeSetup` makes the translation when the detector first meets an image size, never per frame:
- the region of interest: the floor rectangle `roi` (robot frame) projected into the image,
  clipped by the image border (it always lies below the horizon), and its filled mask;
- the look-ahead row (where the floor `edges.look_ahead_m` ahead is seen) and the column of the
  robot's centre line at the ROI's bottom row (left/right candidates split there);
- the start-up checks, each refusing the config with one line (`PerceptionConfigError`): the ROI
  and the look-ahead must be in view, and at the look-ahead the camera must tell the tape from a
  seam (`perception.tape_rules.WidthHypotheses.resolvable`); the message names the farthest
  look-ahead that would work;
- the preallocated stage buffers and the pixel knobs scaled to this size (blur kernel, Hough).

Never reads a clock and never looks at a frame.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.errors import PerceptionConfigError
from lanewarden.perception.floor_view import FloorView, direction
from lanewarden.perception.ground import GroundModel
from lanewarden.perception.tape_rules import WidthHypotheses, width_hypotheses

_REFERENCE_HEIGHT_PX = 480
#: Floor closer than this to the camera's image plane (camera-frame depth, metres) is left out of
#: the ROI before projecting it (a point at depth 0 would project to infinity).
_MIN_DEPTH_M = 0.02
#: An ROI smaller than this many pixels in the image is "not in view".
_MIN_ROI_AREA_PX = 64.0
#: Step of the search for the farthest look-ahead that resolves tape from seam, metres.
_SEARCH_STEP_M = 0.01


class SizeSetup:
    """Per image size: ROI, look-ahead row, centre column, checks, buffers (see module doc).

    - `ground` / `view`: the ground model at this size and its per-point form.
    - `polygon_px`: (K, 2) int32, the ROI in pixels, clipped to the image; `mask`: its filled
      uint8 mask (255 inside); `y_bottom`: its lowest row (float pixels).
    - `look_ahead_row`: image row seeing the floor `edges.look_ahead_m` ahead (centre column).
    - `centre_x_bottom`: column where the robot's centre line (floor y = 0) crosses `y_bottom`.
    - `gray`, `smooth`, `edges`: the preallocated stage buffers (OpenCV writes into them).
    - `blur_kernel`: (k, k), `kernel_px` scaled to this height (odd, >= 3).
    - `hough_votes`, `hough_min_length`, `hough_max_gap`: HoughLinesP's accumulator threshold,
      minLineLength and maxLineGap in pixels at this size.
    - `at_look_ahead`: the tape and seam hypotheses at the look-ahead distance (the worse side).
    """

    def __init__(self, width: int, height: int, config: PerceptionConfig,
                 ground: GroundModel) -> None:
        self.size = (width, height)
        self.ground = ground
        self.view = FloorView(ground)
        self.polygon_px = roi_polygon_px(ground, config)
        area = abs(cv2.contourArea(self.polygon_px.astype(np.float32))) if len(
            self.polygon_px) >= 3 else 0.0
        near, far = visible_range_m(ground)
        if area < _MIN_ROI_AREA_PX:
            roi = config.roi
            raise PerceptionConfigError(
                f"perception.roi (near_m {roi.near_m:g}, far_m {roi.far_m:g}, lateral_m "
                f"{roi.lateral_m:g}): this floor is not in the camera's view at {width}x{height}; "
                f"expected a region overlapping {_range_text(near, far)}"
            )
        self.mask = np.zeros((height, width), dtype=np.uint8)
        cv2.fillPoly(self.mask, [self.polygon_px], 255)
        self.y_bottom = float(min(float(self.polygon_px[:, 1].max()), float(height)))
        look_ahead = config.edges.look_ahead_m
        self.look_ahead_row = ground.row_at_distance(look_ahead)
        if not (math.isfinite(self.look_ahead_row) and 0.0 <= self.look_ahead_row <= height):
            raise PerceptionConfigError(
                f"perception.edges.look_ahead_m = {look_ahead:g}: outside the camera's view at "
                f"{width}x{height}; expected a distance within {_range_text(near, far)}",
                suggested_look_ahead_m=_inside(near, far, config),
            )
        self.centre_x_bottom = self.view.line_column_at((0.0, 0.0), (1.0, 0.0), self.y_bottom)
        if not math.isfinite(self.centre_x_bottom):
            self.centre_x_bottom = 0.5 * width
        self.at_look_ahead = hypotheses_at(self.view, look_ahead, config)
        if not self.at_look_ahead.resolvable:
            raise PerceptionConfigError(
                *_unresolvable(self.view, self.at_look_ahead, near, config, self.size)
            )
        self.gray = np.empty((height, width), dtype=np.uint8)
        self.smooth = np.empty((height, width), dtype=np.uint8)
        self.edges = np.empty((height, width), dtype=np.uint8)
        k = config.blur.kernel_px
        if k > 1:
            k = max(3, 2 * round((k * height / _REFERENCE_HEIGHT_PX - 1) / 2) + 1)
        self.blur_kernel = (k, k)
        hough = config.hough
        self.hough_votes = max(5, round(hough.votes_frac_of_height * height))
        self.hough_min_length = max(3.0, hough.min_line_length_frac_of_height * height)
        self.hough_max_gap = hough.max_line_gap_frac_of_height * height

    def describe(self) -> str:
        """One line: the image size and what a pixel covers at the look-ahead (the camera's
        pose is `perception.ground.ground_model_for`'s line)."""
        hyp = self.at_look_ahead
        return (
            f"{self.size[0]}x{self.size[1]}: at the look-ahead one pixel covers "
            f"{1000 * hyp.m_per_px:.1f} mm across the tape (a tape measures "
            f"{1000 * hyp.tape_min_m:.1f} mm or more there, a seam at most "
            f"{1000 * hyp.seam_max_m:.1f} mm)"
        )


def roi_polygon_px(ground: GroundModel, config: PerceptionConfig) -> NDArray[np.int32]:
    """The floor rectangle `config.roi` (robot frame) as an image polygon clipped to the image:
    (K, 2) int32, K = 0 when it is out of view."""
    roi = config.roi
    corners = [(roi.near_m, roi.lateral_m), (roi.far_m, roi.lateral_m),
               (roi.far_m, -roi.lateral_m), (roi.near_m, -roi.lateral_m)]
    ahead = _clip_half_plane(corners, ground)
    if len(ahead) < 3:
        return np.zeros((0, 2), np.int32)
    pixels = ground.floor_to_image(np.array(ahead)).astype(np.float32)
    width, height = ground.image_size
    image = np.array([[0, 0], [width, 0], [width, height], [0, height]], np.float32)
    area, clipped = cv2.intersectConvexConvex(image, pixels)
    if clipped is None or area <= 0.0:
        return np.zeros((0, 2), np.int32)
    return np.rint(np.asarray(clipped, np.float64).reshape(-1, 2)).astype(np.int32)


def _clip_half_plane(polygon: list[tuple[float, float]],
                     ground: GroundModel) -> list[tuple[float, float]]:
    """The part of a convex floor polygon at least _MIN_DEPTH_M in front of the camera
    (Sutherland-Hodgman against one plane)."""
    r = ground.rotation[2]
    c = ground.position

    def depth(p: tuple[float, float]) -> float:
        return float(r[0] * (p[0] - c[0]) + r[1] * (p[1] - c[1]) - r[2] * c[2]) - _MIN_DEPTH_M

    out: list[tuple[float, float]] = []
    for i, p in enumerate(polygon):
        q = polygon[(i + 1) % len(polygon)]
        dp, dq = depth(p), depth(q)
        if dp >= 0.0:
            out.append(p)
        if (dp >= 0.0) != (dq >= 0.0):
            t = dp / (dp - dq)
            out.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
    return out


def visible_range_m(ground: GroundModel) -> tuple[float, float]:
    """Forward distances (robot x) of the floor seen at the bottom and top rows of the image's
    centre column; the far one is +inf when the top row is at or above the horizon."""
    height = ground.image_size[1]
    near = ground.distance_at_row(height - 0.5)
    far = ground.distance_at_row(0.5)
    return near, (far if math.isfinite(far) else math.inf)


def m_per_px_across_tape(view: FloorView, x_m: float, y_m: float) -> float:
    """Floor metres per pixel across a tape running straight ahead through (x_m, y_m)."""
    u, v = view.to_image(x_m, y_m)
    u2, v2 = view.to_image(x_m + 0.05, y_m)
    du, dv = direction((u, v), (u2, v2))
    return view.metres_per_px_across(u, v, du, dv, (0.0, 1.0))


def hypotheses_at(view: FloorView, distance_m: float, config: PerceptionConfig) -> WidthHypotheses:
    """The tape and seam hypotheses `distance_m` ahead where the lane's tapes run (either side;
    the coarser one)."""
    half = config.lane.width_m / 2.0
    m_per_px = max(m_per_px_across_tape(view, distance_m, half),
                   m_per_px_across_tape(view, distance_m, -half))
    return width_hypotheses(m_per_px, config.tape)


def farthest_resolvable_m(view: FloorView, near_m: float, start_m: float,
                          config: PerceptionConfig) -> float | None:
    """The farthest distance from `start_m` down to `near_m` (in _SEARCH_STEP_M steps) where the
    camera tells the tape from a seam, or None."""
    d = start_m
    while d >= near_m:
        if hypotheses_at(view, d, config).resolvable:
            return d
        d -= _SEARCH_STEP_M
    return None


def _unresolvable(view: FloorView, hyp: WidthHypotheses, near_m: float,
                  config: PerceptionConfig, size: tuple[int, int]) -> tuple[str, float | None]:
    tape = config.tape
    look_ahead = config.edges.look_ahead_m
    why = (
        f"perception.edges.look_ahead_m = {look_ahead:g}: at {size[0]}x{size[1]} one pixel covers "
        f"{1000 * hyp.m_per_px:.1f} mm of floor across the tape there, too coarse to tell the "
        f"{1000 * tape.width_m:g} mm tape (tape.width_m) from seams up to "
        f"{1000 * tape.seam_width_m:g} mm (with a pixel of measuring error either way a tape may "
        f"measure as little as {1000 * hyp.tape_min_m:.1f} mm there and a seam as much as "
        f"{1000 * hyp.seam_max_m:.1f} mm)"
    )
    start = math.floor((look_ahead - _SEARCH_STEP_M) / _SEARCH_STEP_M) * _SEARCH_STEP_M
    best = farthest_resolvable_m(view, max(near_m, 0.0), start, config)
    if best is None:
        return (f"{why}; no distance in view ({near_m:.2f} m on) resolves them: expected a "
                "higher resolution, a narrower lens, a lower camera or a wider tape"), None
    best = round(best, 2)
    return (f"{why}; expected a look-ahead of {best:.2f} m or less for this camera (set "
            f"perception.edges.look_ahead_m: {best:.2f} in a --config file, or use a higher "
            "resolution)"), best


def _range_text(near: float, far: float) -> str:
    far_text = "the horizon" if not math.isfinite(far) else f"{far:.2f} m"
    return f"the floor the camera sees, {near:.2f} m to {far_text} ahead of the robot's centre"


def _inside(near: float, far: float, config: PerceptionConfig) -> float | None:
    """The middle of the floor both in view and in the ROI, rounded to centimetres (None when
    there is none)."""
    lo, hi = max(near, config.roi.near_m), min(far, config.roi.far_m)
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return None
    return round(0.5 * (lo + hi), 2)
