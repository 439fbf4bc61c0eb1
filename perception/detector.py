"""The lane detector: one camera frame in, one `LaneObservation` out.

Pipeline (the lecture's, made robust):

    [Undistorter.apply] -> gray -> Gaussian blur -> Canny -> ROI mask -> HoughLinesP
      -> candidate lines (perception.lines) -> one edge per side (perception.edge_choice)
      -> bounded slopes and their sum (perception.geometry) -> confidence (perception.confidence)

Input: BGR uint8 (H, W, 3), BGRA (H, W, 4) or gray (H, W), any size of at least 16x16. Output
coordinates are pixels of the (undistorted) image, x right, y down; slopes use the lecture's
y-up convention. Lengths in the config are fractions of the image size, so one config serves
640x480, 320x240 and 160x120.

Performance rules (the hot path is `detect`, once per camera frame):
- Remap tables (in the Undistorter), the ROI mask and the gray/blur/edge buffers are made once per
  image size and reused (OpenCV writes into them through `dst=`), never per frame.
- Everything after HoughLinesP works on a few dozen segments with vectorised numpy; polarity is
  read from the blurred image at a few points along each candidate line, not from a Sobel image.
- Debug data (segment list, ROI polygon) is only assembled by `detect_debug`; drawing lives in
  `perception.overlay`.

OpenCV threads, the one policy: `LaneDetector.__init__` calls `cv2.setNumThreads(
config.opencv_threads)` (default 1). At these image sizes each stage takes about a millisecond and
OpenCV's thread pool costs more than it saves, and the robot's two cores are shared with the
supervisor and the dead-man process. It is process-wide, so nothing else in Lanewarden sets it.

Never reads a clock (the frame time is passed in), never touches motors, never prints.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from lanewarden.perception.calibration import Undistorter
from lanewarden.perception.confidence import (
    combine,
    consistency_component,
    frozen_components,
    lane_components,
)
from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.edge_choice import SideChoice, choose_side
from lanewarden.perception.errors import PerceptionError
from lanewarden.perception.geometry import Side, edge_slope, x_at_row
from lanewarden.perception.lines import LineSet, build_line_set
from lanewarden.perception.observation import LaneEdge, LaneObservation

MIN_IMAGE_SIDE_PX = 16
_REFERENCE_HEIGHT_PX = 480


@dataclass(frozen=True)
class DetectionDebug:
    """What `detect_debug` adds to an observation, for overlays and diagnosis.

    - `roi_polygon_px`: (K, 2) int32, the ROI polygon in pixels (may extend outside the image).
    - `segments`: (N, 4) int32 Hough segments (x1, y1, x2, y2), pixels.
    - `lines`: the candidate lines they were grouped into.
    - `left` / `right`: the choice made on each side (chain of lines, tape partner), or None.
    - `image_size`: (width, height) of the image that was analysed (after undistortion).
    - `image`: that analysed image itself (the caller's array when there is no undistorter; not
      a copy), so an overlay can be drawn on exactly what the detector saw.
    """

    roi_polygon_px: NDArray[np.int32]
    segments: NDArray[np.int32]
    lines: LineSet
    left: SideChoice | None
    right: SideChoice | None
    image_size: tuple[int, int]
    image: np.ndarray


class SizeSetup:
    """Everything that depends only on the image size: computed once, reused every frame.

    - `polygon_px` / `mask`: the ROI in pixels and its filled uint8 mask (255 inside).
    - `y_bottom`: the ROI's bottom row (pixels).
    - `gray`, `smooth`, `edges`: the preallocated stage buffers (OpenCV writes into them).
    - `blur_kernel`: (k, k), `kernel_px` scaled to this height (odd, >= 3).
    - `hough_votes`, `hough_min_length`, `hough_max_gap`: HoughLinesP's accumulator threshold,
      minLineLength and maxLineGap in pixels at this size.
    """

    def __init__(self, width: int, height: int, config: PerceptionConfig) -> None:
        self.size = (width, height)
        self.polygon_px = np.array(
            [[round(x * width), round(y * height)] for x, y in config.roi.polygon_norm],
            dtype=np.int32,
        )
        self.mask = np.zeros((height, width), dtype=np.uint8)
        cv2.fillPoly(self.mask, [self.polygon_px], 255)
        lowest = max(y for _, y in config.roi.polygon_norm)
        self.y_bottom = float(min(lowest, 1.0) * height)
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


class LaneDetector:
    """Finds the two lane edges in a frame and says how far to trust them.

    `detect(image, frame_index, time_s, previous=None)` is the hot path. `previous` (the last
    observation) only feeds the `consistency` confidence component; the detector keeps no
    history of its own, so it is a pure function of its arguments and the config.
    """

    def __init__(self, config: PerceptionConfig, undistorter: Undistorter | None = None) -> None:
        self.config = config
        self.undistorter = undistorter
        cv2.setNumThreads(config.opencv_threads)
        self._states: dict[tuple[int, int], SizeSetup] = {}
        self._theta_rad = math.radians(config.hough.theta_deg)

    # ------------------------------------------------------------------------------ public

    def setup_for(self, width: int, height: int) -> SizeSetup:
        """The per-size setup (mask, buffers, scaled pixel parameters), made on first use."""
        setup = self._states.get((width, height))
        if setup is None:
            setup = self._states[(width, height)] = SizeSetup(width, height, self.config)
        return setup

    def detect(
        self,
        image: np.ndarray,
        frame_index: int,
        time_s: float,
        previous: LaneObservation | None = None,
    ) -> LaneObservation:
        """The lane observation for one frame (see `LaneObservation`). Raises PerceptionError
        for an unusable frame (not an array, wrong dtype or shape, too small, wrong size for
        the calibration)."""
        observation, _, _, _, _ = self._run(image, frame_index, time_s, previous)
        return observation

    def detect_debug(
        self,
        image: np.ndarray,
        frame_index: int,
        time_s: float,
        previous: LaneObservation | None = None,
    ) -> tuple[LaneObservation, DetectionDebug]:
        """`detect` plus the intermediate results, for `perception.overlay` and diagnosis."""
        observation, state, segments, choices, analysed = self._run(
            image, frame_index, time_s, previous
        )
        lines, left, right = choices
        flat = (
            np.zeros((0, 4), dtype=np.int32)
            if segments is None
            else segments.reshape(-1, 4).astype(np.int32)
        )
        debug = DetectionDebug(
            roi_polygon_px=state.polygon_px.copy(),
            segments=flat,
            lines=lines,
            left=left,
            right=right,
            image_size=state.size,
            image=analysed,
        )
        return observation, debug

    # ----------------------------------------------------------------------------- stages

    def _run(
        self,
        image: np.ndarray,
        frame_index: int,
        time_s: float,
        previous: LaneObservation | None,
    ) -> tuple[
        LaneObservation,
        SizeSetup,
        NDArray[np.int32] | None,
        tuple[LineSet, SideChoice | None, SideChoice | None],
        np.ndarray,
    ]:
        _check_image(image)
        if self.undistorter is not None:
            image = self.undistorter.apply(image)
        height, width = image.shape[:2]
        state = self.setup_for(width, height)
        segments = self._segments(image, state)
        config = self.config
        lines = build_line_set(segments, state.smooth, state.y_bottom, config.edges, config.tape)
        rows = lines.rows()
        left = choose_side(rows, state.smooth, "left", state.y_bottom, config)
        right = choose_side(rows, state.smooth, "right", state.y_bottom, config)
        observation = self._observe(lines, left, right, state, frame_index, time_s, previous)
        return observation, state, segments, (lines, left, right), image

    def _segments(self, image: np.ndarray, state: SizeSetup) -> NDArray[np.int32] | None:
        """gray -> blur -> Canny -> ROI mask -> HoughLinesP, into the preallocated buffers."""
        canny = self.config.canny
        if image.ndim == 2:
            gray = image
        elif image.shape[2] == 1:
            gray = image[:, :, 0]
        elif image.shape[2] == 3:
            gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY, dst=state.gray)
        else:
            gray = cv2.cvtColor(image, cv2.COLOR_BGRA2GRAY, dst=state.gray)
        if state.blur_kernel[0] > 1:
            cv2.GaussianBlur(
                gray, state.blur_kernel, self.config.blur.sigma_px, dst=state.smooth
            )
        else:
            np.copyto(state.smooth, gray)
        cv2.Canny(
            state.smooth,
            canny.low_threshold,
            canny.high_threshold,
            edges=state.edges,
            apertureSize=canny.aperture_px,
        )
        cv2.bitwise_and(state.edges, state.mask, dst=state.edges)
        segments = cv2.HoughLinesP(
            state.edges,
            self.config.hough.rho_px,
            self._theta_rad,
            state.hough_votes,
            minLineLength=state.hough_min_length,
            maxLineGap=state.hough_max_gap,
        )
        return None if segments is None else np.asarray(segments, dtype=np.int32)

    def _observe(
        self,
        lines: LineSet,
        left: SideChoice | None,
        right: SideChoice | None,
        state: SizeSetup,
        frame_index: int,
        time_s: float,
        previous: LaneObservation | None,
    ) -> LaneObservation:
        config = self.config
        left_edge = self._edge(left, "left")
        right_edge = self._edge(right, "right")
        left_line = _near_line(lines, left)
        right_line = _near_line(lines, right)
        components = lane_components(
            size=state.size,
            y_bottom=state.y_bottom,
            left_line=left_line,
            right_line=right_line,
            left_support_px=0.0 if left is None else left.support_px,
            right_support_px=0.0 if right is None else right.support_px,
            left_tape=0.0 if left is None else left.tape_score,
            right_tape=0.0 if right is None else right.tape_score,
            config=config,
        )
        components["consistency"] = consistency_component(
            left_edge, right_edge, previous, state.size, state.y_bottom, config
        )
        slope_sum = None
        center_offset = None
        if left_edge is not None and right_edge is not None:
            slope_sum = left_edge.slope + right_edge.slope
            if left_line is not None and right_line is not None:
                half = 0.5 * state.size[0]
                mid = 0.5 * (
                    x_at_row(*left_line, state.y_bottom) + x_at_row(*right_line, state.y_bottom)
                )
                center_offset = (mid - half) / half
        return LaneObservation(
            frame_index=frame_index,
            time_s=time_s,
            left=left_edge,
            right=right_edge,
            slope_sum=slope_sum,
            confidence=combine(components, config),
            components=frozen_components(components),
            center_offset=center_offset,
        )

    def _edge(self, choice: SideChoice | None, side: Side) -> LaneEdge | None:
        if choice is None:
            return None
        return LaneEdge(
            x1=choice.x1,
            y1=choice.y1,
            x2=choice.x2,
            y2=choice.y2,
            slope=edge_slope(
                choice.x1, choice.y1, choice.x2, choice.y2, side, self.config.edges.max_abs_slope
            ),
            support_px=choice.support_px,
        )


def _near_line(
    lines: LineSet, choice: SideChoice | None
) -> tuple[float, float, float, float] | None:
    if choice is None:
        return None
    k = choice.near_line
    return (
        float(lines.near_x[k]),
        float(lines.near_y[k]),
        float(lines.far_x[k]),
        float(lines.far_y[k]),
    )


def _check_image(image: object) -> None:
    if not isinstance(image, np.ndarray):
        raise PerceptionError(f"frame: expected a numpy image array, got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise PerceptionError(f"frame: expected dtype uint8, got {image.dtype}")
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] in (1, 3, 4))):
        raise PerceptionError(
            f"frame: expected an HxW gray or HxWx3 BGR image, got shape {image.shape}"
        )
    if min(image.shape[:2]) < MIN_IMAGE_SIDE_PX:
        raise PerceptionError(
            f"frame: {image.shape[1]}x{image.shape[0]} is too small "
            f"(at least {MIN_IMAGE_SIDE_PX}x{MIN_IMAGE_SIDE_PX} px)"
        )
