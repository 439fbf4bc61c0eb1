"""Everything the detector derives from the config and the ground model for one image size, once.

The config speaks metres on the floor (`perception.floor_config`); the detector works in pixels.
`SizeSetup` makes the translation when the detector first meets an image size, never per frame:
- the region of interest: the floor rectangle `roi` (robot frame) projected into the image,
  clipped by the image border (it always lies below the horizon), and its filled mask;
- the look-ahead: `edges.look_ahead_m`, or with `auto` (the default) the farthest distance up to
  `edges.max_look_ahead_m` that is in view and where the camera tells the tape from the widest
  seam, on a whole-centimetre grid; the row where the floor that far ahead is seen, and the
  column of the robot's centre line at the ROI's bottom row (left/right candidates split there);
- the start-up checks, each refusing the config with one line (`PerceptionConfigError`): the ROI
  and the look-ahead must be in view, and at the look-ahead the camera must tell each side's tape
  from a seam (`perception.tape_rules.WidthHypotheses.resolvable`); the message names the
  farthest look-ahead that would work, found by the very check that will judge it (so an advised
  value is always accepted as given);
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
#: Rows of the sparse grid the frame's contrast is read on (`contrast_step`): about 60x80 points.
_CONTRAST_SAMPLE_ROWS = 60


class SizeSetup:
    """Per image size: ROI, look-ahead row, centre column, checks, buffers (see module doc).

    - `ground` / `view`: the ground model at this size and its per-point form.
    - `polygon_px`: (K, 2) int32, the ROI in pixels, clipped to the image; `mask`: its filled
      uint8 mask (255 inside); `y_bottom`: its lowest row (float pixels).
    - `look_ahead_m`: the look-ahead at this size, metres: `edges.look_ahead_m`, or with `auto`
      the farthest that works (`farthest_look_ahead_m`); `look_ahead_auto`: whether auto chose
      it. `look_ahead_row`: the image row seeing the floor that far ahead (centre column).
    - `centre_x_bottom`: column where the robot's centre line (floor y = 0) crosses `y_bottom`.
    - `gray`, `smooth`, `edges`: the preallocated stage buffers (OpenCV writes into them).
    - `contrast_step`, `contrast_samples`: the sparse grid (every `contrast_step`-th row and
      column) on which a frame's contrast is read, and its points inside the ROI (flat indices
      into the frame, in row order; `contrast_buffer` receives their values).
    - `blur_kernel`: (k, k), `kernel_px` scaled to this height (odd, >= 3).
    - `edge_budget_px`: the most edge pixels Canny may leave in the ROI before its thresholds
      are raised (`canny.max_edge_share` of the ROI's pixels); `edge_threshold_factor`: what
      they were raised by for the last frame `edges` holds (`LaneDetector._segments`).
    - `hough_votes`, `hough_min_length`, `hough_max_gap`: HoughLinesP's accumulator threshold,
      minLineLength and maxLineGap in pixels at this size.
    - `at_look_ahead`: the tape and seam hypotheses at the look-ahead distance (the worse side).
    """

    def __init__(self, width: int, height: int, config: PerceptionConfig,
                 ground: GroundModel) -> None:
        self.size = (width, height)
        self.config = config
        self.ground = ground
        self.view = FloorView(ground)
        self.polygon_px = roi_polygon_px(ground, config)
        area = abs(cv2.contourArea(self.polygon_px.astype(np.float32))) if len(
            self.polygon_px) >= 3 else 0.0
        near, far = visible_range_m(ground)
        if area < _MIN_ROI_AREA_PX:
            roi = config.roi
            # (a region in view but a few pixels large, a wide lens high up on a small image,
            # had been called "not in the camera's view", beside a visible range holding it)
            seen = (f"this floor is not in the camera's view at {width}x{height}; expected a "
                    f"region overlapping {_range_text(near, far)}" if area == 0.0 else
                    f"this floor covers only {area:.0f} of the {width}x{height} image's pixels; "
                    f"expected at least {_MIN_ROI_AREA_PX:.0f} (a larger image, a narrower lens "
                    "or a lower camera)")
            raise PerceptionConfigError(
                f"perception.roi (near_m {roi.near_m:g}, far_m {roi.far_m:g}, lateral_m "
                f"{roi.lateral_m:g}): {seen}")
        self.mask = np.zeros((height, width), dtype=np.uint8)
        cv2.fillPoly(self.mask, [self.polygon_px], 255)
        self.edge_budget_px = config.canny.max_edge_share * cv2.countNonZero(self.mask)
        self.edge_threshold_factor = 1.0
        self.y_bottom = float(min(float(self.polygon_px[:, 1].max()), float(height)))
        self.look_ahead_m, self.look_ahead_auto = _look_ahead(self.view, near, far, config,
                                                              self.size)
        self.look_ahead_row = ground.row_at_distance(self.look_ahead_m)
        self.centre_x_bottom = self.view.line_column_at((0.0, 0.0), (1.0, 0.0), self.y_bottom)
        if not math.isfinite(self.centre_x_bottom):
            self.centre_x_bottom = 0.5 * width
        self.at_look_ahead = hypotheses_at(self.view, self.look_ahead_m, config)
        # Contrast is read on a grid of about 80x60 samples of the ROI, whatever the size.
        self.contrast_step = step = max(1, height // _CONTRAST_SAMPLE_ROWS)
        # The grid's points inside the ROI, as flat indices into a frame, in row order: taken
        # into one contiguous row, OpenCV reads them without a mask and without first copying
        # the strided grid (the same sums, so the same mean and spread; half the time).
        rows, cols = np.nonzero(self.mask[::step, ::step])
        self.contrast_samples = (rows * step * width + cols * step).astype(np.intp)
        self.contrast_samples.flags.writeable = False
        self.contrast_buffer = np.empty(len(self.contrast_samples), dtype=np.uint8)
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
        if not self.look_ahead_auto:
            how = "edges.look_ahead_m"
        elif self.look_ahead_m >= self.config.edges.max_look_ahead_m:
            how = "auto: edges.max_look_ahead_m"
        else:
            how = "auto: the farthest where this camera tells tape from seam"
        return (
            f"{self.size[0]}x{self.size[1]}: look-ahead {self.look_ahead_m:.2f} m ({how}); there "
            f"one pixel covers {1000 * hyp.m_per_px:.1f} mm across a tape where the lane's tapes "
            f"run (a tape measures "
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
    """The tape and seam hypotheses `distance_m` ahead where the lane's tapes run, each side with
    its own tape (`tape.left_width_m` at the left tape, `right_width_m` at the right one): the
    side with the smaller margin between tape and seam (the one that decides whether the camera
    can tell them apart there)."""
    half = config.lane.width_m / 2.0
    sides = [width_hypotheses(m_per_px_across_tape(view, distance_m, half),
                              config.tape.for_side("left")),
             width_hypotheses(m_per_px_across_tape(view, distance_m, -half),
                              config.tape.for_side("right"))]
    return min(sides, key=_margin)


def _margin(hyp: WidthHypotheses) -> float:
    """How far apart tape and seam measure, in error units (NaN pixel sizes: never)."""
    if not math.isfinite(hyp.m_per_px) or hyp.error_m <= 0.0:
        return -math.inf if not math.isfinite(hyp.m_per_px) else math.inf
    return (hyp.tape_min_m - hyp.seam_max_m) / hyp.error_m


def _in_view(view: FloorView, distance_m: float, height: int) -> bool:
    row = view.ground.row_at_distance(distance_m)
    return math.isfinite(row) and 0.0 <= row <= height


def farthest_look_ahead_m(view: FloorView, near_m: float, far_m: float,
                          config: PerceptionConfig) -> float | None:
    """The farthest look-ahead, on a whole-centimetre grid, within the ROI, up to
    `edges.max_look_ahead_m` and the farthest floor in view, that is in view and where the
    camera tells the tape from a seam; None when there is none. Each candidate is checked
    exactly as the start-up check will check it when the user sets it (the same float: n/100),
    so the value advised or chosen is always accepted."""
    roi = config.roi
    top = min(config.edges.max_look_ahead_m, roi.far_m, far_m)
    bottom = max(roi.near_m, near_m, 0.0)
    height = view.ground.image_size[1]
    cm = math.floor(top * 100.0 + 1e-9)
    while cm >= 1 and cm / 100.0 >= bottom:
        d = cm / 100.0
        if _in_view(view, d, height) and hypotheses_at(view, d, config).resolvable:
            return d
        cm -= 1
    return None


def resolved_look_ahead_m(ground: GroundModel, config: PerceptionConfig) -> float:
    """`edges.look_ahead_m` for this camera: the value set, or what `auto` chooses
    (`farthest_look_ahead_m`; NaN when nothing in view works). For reports; the detector's own
    start-up check is `SizeSetup`."""
    chosen = config.edges.look_ahead_m
    if chosen != "auto":
        return chosen
    near, far = visible_range_m(ground)
    best = farthest_look_ahead_m(FloorView(ground), near, far, config)
    return math.nan if best is None else best


def _look_ahead(view: FloorView, near: float, far: float, config: PerceptionConfig,
                size: tuple[int, int]) -> tuple[float, bool]:
    """(look-ahead in metres, whether `auto` chose it) for this camera at this size, or
    PerceptionConfigError with the look-ahead that would work."""
    width, height = size
    chosen = config.edges.look_ahead_m
    best = farthest_look_ahead_m(view, near, far, config)
    if chosen == "auto":
        if best is None:
            hyp = hypotheses_at(view, max(near, config.roi.near_m, 0.0), config)
            covers = (f" (one pixel covers at least {1000 * hyp.m_per_px:.1f} mm of floor "
                      "across the tape)" if math.isfinite(hyp.m_per_px) else
                      " (the camera sees no floor there)")
            raise PerceptionConfigError(
                f"perception.edges.look_ahead_m = auto: at {width}x{height} no distance in view "
                f"({_from_text(near)}) tells the {_tapes_text(config)} from seams up to "
                f"{1000 * config.tape.seam_width_m:g} mm{covers}; expected {_REMEDIES}")
        return best, True
    if not _in_view(view, chosen, height):
        raise PerceptionConfigError(
            f"perception.edges.look_ahead_m = {chosen:g}: outside the camera's view at "
            f"{width}x{height}; expected a distance within {_range_text(near, far)}"
            + _advice(best), suggested_look_ahead_m=best,
        )
    hyp = hypotheses_at(view, chosen, config)
    if not hyp.resolvable:
        raise PerceptionConfigError(_unresolvable(hyp, chosen, near, config, size, best),
                                    suggested_look_ahead_m=best)
    return chosen, False


def _tapes_text(config: PerceptionConfig) -> str:
    tape = config.tape
    left, right = tape.side_width_m("left"), tape.side_width_m("right")
    if left == right:
        return f"{1000 * left:g} mm tape (tape.width_m)"
    return (f"{1000 * left:g} mm left tape and the {1000 * right:g} mm right tape "
            "(tape.left_width_m, tape.right_width_m)")


def _advice(best: float | None) -> str:
    if best is None:
        return ""
    return (f"; this camera tells tape from seam up to {best:.2f} m (set "
            f"perception.edges.look_ahead_m: {best:.2f} or auto in a --config file)")


def _unresolvable(hyp: WidthHypotheses, look_ahead: float, near_m: float,
                  config: PerceptionConfig, size: tuple[int, int], best: float | None) -> str:
    why = (
        f"perception.edges.look_ahead_m = {look_ahead:g}: at {size[0]}x{size[1]} one pixel "
        f"covers {1000 * hyp.m_per_px:.1f} mm of floor across the tape there, too coarse to "
        f"tell the {_tapes_text(config)} from seams up to {1000 * config.tape.seam_width_m:g} mm "
        f"(with a pixel of measuring error either way a tape may measure as little as "
        f"{1000 * hyp.tape_min_m:.1f} mm there and a seam as much as "
        f"{1000 * hyp.seam_max_m:.1f} mm: to be told apart they must differ by more than that "
        f"error, {1000 * hyp.error_m:.1f} mm)"
    )
    if best is None:
        return (f"{why}; no distance in view ({_from_text(near_m)}) resolves them: expected "
                f"{_REMEDIES}")
    return (f"{why}; expected a look-ahead of {best:.2f} m or less for this camera (set "
            f"perception.edges.look_ahead_m: {best:.2f} or auto in a --config file, or use a "
            "higher resolution)")


#: What makes a camera tell tape from seam where the lane's tapes run: finer pixels there (the
#: first three), a wider tape, or tapes nearer the middle of the view (a narrower lane).
_REMEDIES = ("a higher resolution, a narrower lens, a lower camera, a wider tape or, if the lane "
             "is in fact narrower, its true width (perception.lane.width_m: the tapes nearer the "
             "middle of the view)")


def _from_text(near_m: float) -> str:
    """Where the floor in view begins, for a refusal ("0.36 m on"; from the robot's centre when
    the camera sees the floor under it)."""
    return f"{near_m:.2f} m on" if near_m > 0.0 else "from the robot's centre on"


def _range_text(near: float, far: float) -> str:
    if not math.isfinite(near):  # even the bottom row looks at or above the horizon
        return ("the floor, but this camera sees none: even its bottom row looks at or above "
                "the horizon (check the calibration's ground_pitch_deg: positive looks down)")
    far_text = "the horizon" if not math.isfinite(far) else f"{far:.2f} m"
    return f"the floor the camera sees, {near:.2f} m to {far_text} ahead of the robot's centre"
