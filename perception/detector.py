"""The lane detector: one camera frame in, one `LaneObservation` out.

Pipeline (the lecture's, made robust):

    gray (perception_gray) -> [Undistorter.apply] -> Gaussian blur -> Canny -> ROI mask
      -> HoughLinesP -> candidate lines (perception.lines)
      -> one edge per side (perception.edge_choice)
      -> bounded slopes and their sum (perception.geometry) -> confidence (perception.confidence)
      -> the lane's offset and heading on the floor (robot frame, metres and radians)

Input: BGR uint8 (H, W, 3), BGRA (H, W, 4) or gray (H, W), any size of at least 16x16. Edge
coordinates are pixels of the (undistorted) image, x right, y down; slopes use the lecture's
y-up convention; offsets and headings are in the robot frame (x forward, y left). Perception
depends on a frame only through its gray version (`perception_gray`): a colour frame and its gray
version give the same observation; and only through `prepare(frame)` (a `PreparedImage`: gray,
undistorted, blurred), which `detect` also takes in place of the frame: what a recording keeps.

Geometry in metres: the detector sees the floor through a ground model
(`perception.ground.GroundModel`: the camera's intrinsics and its pose over the floor; by default
the simulator's camera). The config's floor geometry (tape and lane widths, the region of
interest, the look-ahead) is turned into pixels once per image size by
`perception.size_setup.SizeSetup`, which also refuses a camera that cannot tell the tape from a
seam at the look-ahead distance (`PerceptionConfigError`; for the ground model's own image size
already when the detector is built).

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

from lanewarden.perception import line_kernel
from lanewarden.perception.calibration import Undistorter
from lanewarden.perception.confidence import (
    EdgeEvidence,
    combine,
    consistency_component,
    frozen_components,
    lane_centre,
    lane_components,
)
from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.edge_choice import SideChoice, choose_edges
from lanewarden.perception.errors import PerceptionConfigError, PerceptionError
from lanewarden.perception.floor_view import direction, signed_offset
from lanewarden.perception.geometry import Side, edge_slope, other_side
from lanewarden.perception.ground import (
    GroundModel,
    default_ground_model,
    ground_model_for,
)
from lanewarden.perception.lines import LineRow, LineSet, build_line_set
from lanewarden.perception.observation import LaneEdge, LaneObservation, LaneReference
from lanewarden.perception.one_side import lane_from_one_side, one_side_ceiling
from lanewarden.perception.size_setup import SizeSetup

MIN_IMAGE_SIDE_PX = 16


def too_small(width: int, height: int, use: str = "perception") -> str:
    """'' when a `width` x `height` image is large enough for `use`, else why not, with the
    minimum: '1x1 is too small for perception (at least 16x16 px)'. The one size check of a frame
    (`detect`), of a size the detector is set up for (`setup_for`: a 1x1 frame had been refused
    as a floor region out of view, naming the config key perception.roi) and of a photo a
    command reads before it gets there."""
    if min(width, height) >= MIN_IMAGE_SIDE_PX:
        return ""
    return (f"{width}x{height} is too small for {use} (at least {MIN_IMAGE_SIDE_PX}x"
            f"{MIN_IMAGE_SIDE_PX} px)")


#: Perception's gray of a colour frame (`perception_gray`: OpenCV's BGR2GRAY) as weights of
#: (blue, green, red), for whoever paints it from colours (the simulator's gray texture and
#: camera, `scenarios.texture`, `scenarios.camera_effects`). In it a yellow line (#e3b21c, 176)
#: is about as light as parquet's light slats; `perception.gray.yellow_boost` lifts it out of a
#: colour frame (the simulator then gives perception colour frames; docs/perception.md, "Gray").
GRAY_WEIGHTS_BGR: tuple[float, float, float] = (0.114, 0.587, 0.299)
#: Where Canny's edges cover more than `canny.max_edge_share` of the ROI, its thresholds are
#: raised this many times over (`LaneDetector._edges_within_budget`), in small steps, so a frame
#: just over the budget loses only its weakest steps (a first version raised 1.5 times at once
#: above 8 %: a very dim room's frames, just over it, lost a glossy tape's edge, weakened by a
#: mirrored ceiling light, before their stretched noise; tests/perception/test_glossy_tape.py)...
EDGE_THRESHOLD_STEP = 1.2
#: ...at most this many times (3.0 times the configured thresholds: 119 and 358 by default;
#: beyond it the tapes' own edges go: on the simulator's terrazzo at 5 times, 5 of 6 frames lost
#: their lane, where 3.4 times kept it in all of them).
MAX_EDGE_THRESHOLD_RAISES = 6
#: The floor length over which a reported edge's direction is taken for the lane's width,
#: parallelism, offset and heading (`_evidence`), metres.
EVIDENCE_MIN_M = 0.10


class PreparedImage(np.ndarray):
    """A frame as perception consumes it (`LaneDetector.prepare`): 8-bit gray HxW, undistorted
    when there is a calibration, blurred, before contrast normalisation. `detect` and
    `detect_debug` take it in place of a camera frame and skip those steps; everything else they
    compute depends on a frame only through this image. Made by `prepare` or, for a recording of
    prepared frames, by `array.view(PreparedImage)`."""


@dataclass(frozen=True)
class DetectionDebug:
    """What `detect_debug` adds to an observation, for overlays and diagnosis.

    - `roi_polygon_px`: (K, 2) int32, the ROI (the floor region projected) in pixels, clipped
      to the image.
    - `segments`: (N, 4) int32 Hough segments (x1, y1, x2, y2), pixels.
    - `lines`: the candidate lines they were grouped into.
    - `left` / `right`: the choice made on each side (chain of lines, tape partner), or None.
    - `image_size`: (width, height) of the image that was analysed (after undistortion).
    - `edge_threshold_factor`: what Canny's thresholds were raised by to keep the frame's edges
      within `canny.max_edge_share` of the ROI (1.0: as configured; above it: a textured floor).
    - `image`: the frame as the detector saw it, undistorted (the caller's array when there is
      no undistorter; not a copy; in colour for a colour frame, while perception itself works on
      its gray version; a `PreparedImage` as it came), so an overlay can be drawn on what the
      detector saw.
    """

    roi_polygon_px: NDArray[np.int32]
    segments: NDArray[np.int32]
    lines: LineSet
    left: SideChoice | None
    right: SideChoice | None
    image_size: tuple[int, int]
    image: np.ndarray
    edge_threshold_factor: float


class LaneDetector:
    """Finds the two lane edges in a frame and says how far to trust them.

    `ground`: the camera's ground model (undistorted pixels, any image size: it is scaled to each
    frame's size); None: `assumed_ground_model(undistorter, image_size)` (`image_size`: the
    frames' size when known). Construction sets up the ground model's own image size at once, so
    a config this camera cannot work with is refused here (`PerceptionConfigError`), before any
    frame.

    `detect(image, frame_index, time_s, previous=None)` is the hot path. `previous` (the lanes to
    agree with, `LaneReference`: the control loop passes the frame before and the last lane its
    supervisor trusted, see `ControlLoop._reference`) only feeds the `consistency` confidence
    component; the detector keeps no history of its own, so it is a pure function of its
    arguments and the config.
    """

    def __init__(self, config: PerceptionConfig, undistorter: Undistorter | None = None,
                 ground: GroundModel | None = None,
                 image_size: tuple[int, int] | None = None) -> None:
        self.config = config
        self.undistorter = undistorter
        self.ground = assumed_ground_model(undistorter, image_size) if ground is None else ground
        self._ground_given = ground is not None
        cv2.setNumThreads(config.opencv_threads)
        self._states: dict[tuple[int, int], SizeSetup] = {}
        self._theta_rad = math.radians(config.hough.theta_deg)
        self.setup_for(*self.ground.image_size)
        # (Compiled, or loaded from numba's cache, now rather than on the first frame; a
        # compile is said on stderr through logging, once: the first run after an install.)
        line_kernel.ready()

    # ------------------------------------------------------------------------------ public

    def setup_for(self, width: int, height: int) -> SizeSetup:
        """The per-size setup (ROI, look-ahead row, buffers, scaled pixel parameters), made on
        first use; raises PerceptionError for a size smaller than perception works on
        (`too_small`), PerceptionConfigError when the config does not work at this size."""
        setup = self._states.get((width, height))
        if setup is None:
            if why := too_small(width, height):
                raise PerceptionError(f"frame: {why}")
            ground = self.ground
            if ground.image_size != (width, height):
                ground = ground.scaled_to((width, height))
            try:
                setup = SizeSetup(width, height, self.config, ground)
            except PerceptionConfigError as exc:
                raise PerceptionConfigError(f"{exc}{self._assumed_camera((width, height))}",
                                            exc.suggested_look_ahead_m) from None
            self._states[(width, height)] = setup
        return setup

    def _assumed_camera(self, size: tuple[int, int]) -> str:
        """What a refusal adds when the camera was assumed, not described (a new user who left
        out --calibration was told to change the camera, when the tool had judged another
        one): '' with a ground model given or calibrated."""
        if self._ground_given:
            return ""
        if self.undistorter is None:
            return (" (no camera calibration was given: judged as the simulator's default "
                    "camera; give yours, e.g. --calibration)")
        if self.undistorter.calibration.ground is None:
            _, which = ground_model_for(self.undistorter.calibration, size)
            return f" ({which})"
        return ""

    def describe_ground(self, source: str | None = None,
                        size: tuple[int, int] | None = None) -> str:
        """One line saying which ground model this detector uses (`perception.ground.
        ground_model_for`'s words) and what a pixel covers at the look-ahead, for images of
        `size` (width, height; default: the ground model's own), and the gray it reads when that
        is not OpenCV's luma (`perception.gray.yellow_boost`: two surveys with and without it
        say which is which); `detect` and `run` print it once per image size. `source` names the
        calibration file. Raises PerceptionConfigError as `setup_for` does for a size the config
        does not work at."""
        calibration = None if self.undistorter is None else self.undistorter.calibration
        size = self.ground.image_size if size is None else size
        if self._ground_given:
            which = f"the ground model given to the detector ({self.ground.pose.describe()})"
        else:
            _, which = ground_model_for(calibration, size, source)
        line = f"ground model: {which}; {self.setup_for(*size).describe()}"
        boost = self.config.gray.yellow_boost
        if boost > 0.0:
            line += (f"; gray of colour frames: luma + {boost:g} x max(0, luma - blue) "
                     "(perception.gray.yellow_boost; a gray frame is read as it is)")
        return line

    def detect(
        self,
        image: np.ndarray,
        frame_index: int,
        time_s: float,
        previous: LaneReference = None,
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
        previous: LaneReference = None,
    ) -> tuple[LaneObservation, DetectionDebug]:
        """`detect` plus the intermediate results, for `perception.overlay` and diagnosis."""
        observation, state, segments, choices, frame = self._run(
            image, frame_index, time_s, previous
        )
        # The overlay's picture: the frame undistorted as it came (in colour for a colour frame);
        # perception itself worked on its gray version.
        analysed = (frame if self.undistorter is None or isinstance(frame, PreparedImage)
                    else self.undistorter.apply(frame))
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
            edge_threshold_factor=state.edge_threshold_factor,
        )
        return observation, debug

    def prepare(self, image: np.ndarray) -> PreparedImage:
        """What perception makes of a frame before it looks for edges (a new array): its gray
        version, undistorted, blurred, before contrast normalisation. `detect(prepare(frame))`
        is `detect(frame)` bit for bit; this is what a recording keeps (lanewarden/recording.py).
        Raises PerceptionError as `detect` does for an unusable frame."""
        return self._prepare(image).smooth.copy().view(PreparedImage)

    # ----------------------------------------------------------------------------- stages

    def _run(
        self,
        image: np.ndarray,
        frame_index: int,
        time_s: float,
        previous: LaneReference,
    ) -> tuple[
        LaneObservation,
        SizeSetup,
        NDArray[np.int32] | None,
        tuple[LineSet, SideChoice | None, SideChoice | None],
        np.ndarray,
    ]:
        state = self._prepare(image)
        segments = self._segments(state)
        config = self.config
        lines = build_line_set(segments, state.smooth, state.y_bottom, state.view, config.edges,
                               config.tape)
        rows = lines.rows()
        left, right = choose_edges(rows, state.smooth, state, config)
        observation = self._observe(rows, left, right, state, frame_index, time_s, previous)
        return observation, state, segments, (lines, left, right), image

    def _prepare(self, image: np.ndarray) -> SizeSetup:
        """The frame as perception consumes it, into `state.smooth`: its gray version
        (`perception_gray`), undistorted, blurred; a `PreparedImage` is that already (copied)."""
        _check_image(image)
        if isinstance(image, PreparedImage):
            if image.ndim != 2:
                raise PerceptionError(f"frame: a prepared image is HxW gray, got shape "
                                      f"{image.shape}")
            state = self.setup_for(image.shape[1], image.shape[0])
            np.copyto(state.smooth, image)
            return state
        boost = self.config.gray.yellow_boost
        if self.undistorter is not None:
            # Gray first, then undistort: one channel to remap instead of three.
            gray = self.undistorter.apply(perception_gray(image, yellow_boost=boost))
            state = self.setup_for(gray.shape[1], gray.shape[0])
        else:
            state = self.setup_for(image.shape[1], image.shape[0])
            gray = perception_gray(image, dst=state.gray, yellow_boost=boost)
        if state.blur_kernel[0] > 1:
            cv2.GaussianBlur(
                gray, state.blur_kernel, self.config.blur.sigma_px, dst=state.smooth
            )
        else:
            np.copyto(state.smooth, gray)
        return state

    def _segments(self, state: SizeSetup) -> NDArray[np.int32] | None:
        """(prepared image) -> contrast -> Canny (within the edge budget) -> ROI mask ->
        HoughLinesP, in the buffers."""
        self._normalise_contrast(state)
        state.edge_threshold_factor = self._edges_within_budget(state)
        segments = cv2.HoughLinesP(
            state.edges,
            self.config.hough.rho_px,
            self._theta_rad,
            state.hough_votes,
            minLineLength=state.hough_min_length,
            maxLineGap=state.hough_max_gap,
        )
        return None if segments is None else np.asarray(segments, dtype=np.int32)

    def _edges_within_budget(self, state: SizeSetup) -> float:
        """Canny's edges of `state.smooth`, masked to the ROI, into `state.edges`; where they
        cover more than `canny.max_edge_share` of the ROI (`state.edge_budget_px`), again with
        both thresholds EDGE_THRESHOLD_STEP times higher, at most MAX_EDGE_THRESHOLD_RAISES
        times (a frame still over the budget then keeps those edges). Returns the factor the
        thresholds were raised by (1.0: as configured).

        Why: on a textured floor (terrazzo's chips, carpet's pile) at 320x240 Canny's edges
        cover a fifth of the floor (18-25 %; at 640x480, whose pixels are smaller than the
        chips, about half that), and in such clutter a random line collects
        HoughLinesP's votes: Hough reports hundreds of segments through the texture, and each
        one it follows takes the pixels it crosses, so the tape's own edges, by far the
        strongest steps in the frame, come out in pieces or not at all (campaign runs r00144,
        r00191, r00105: LANE_LOST on terrazzo). The texture's steps are weaker than a tape's:
        raised thresholds drop them first."""
        canny = self.config.canny
        for raises in range(MAX_EDGE_THRESHOLD_RAISES + 1):
            factor = EDGE_THRESHOLD_STEP ** raises
            cv2.Canny(state.smooth, canny.low_threshold * factor, canny.high_threshold * factor,
                      edges=state.edges, apertureSize=canny.aperture_px)
            cv2.bitwise_and(state.edges, state.mask, dst=state.edges)
            if cv2.countNonZero(state.edges) <= state.edge_budget_px:
                break
        return factor

    def _normalise_contrast(self, state: SizeSetup) -> None:
        """Stretch a dim or low-contrast frame's blurred image about its mean, in place, so its
        brightness in the floor region varies by `contrast.target_std_levels` (at most
        `contrast.max_gain` times; see `perception.config.ContrastConfig`). The spread is read on
        a sparse grid of the ROI (`SizeSetup.contrast_samples`), not every pixel."""
        contrast = self.config.contrast
        if contrast.max_gain <= 1.0:
            return
        if len(state.contrast_samples):
            samples = np.take(state.smooth.ravel(), state.contrast_samples,
                              out=state.contrast_buffer)
            mean_std = cv2.meanStdDev(samples)
            mean, spread = float(mean_std[0][0, 0]), float(mean_std[1][0, 0])
        else:
            mean = spread = 0.0  # (no grid point in the ROI: what OpenCV reads under an empty mask)
        if spread >= contrast.target_std_levels:
            return
        gain = min(contrast.max_gain, contrast.target_std_levels / max(spread, 1e-3))
        cv2.addWeighted(state.smooth, gain, state.smooth, 0.0, (1.0 - gain) * mean,
                        dst=state.smooth)

    def _observe(
        self,
        rows: list[LineRow],
        left: SideChoice | None,
        right: SideChoice | None,
        state: SizeSetup,
        frame_index: int,
        time_s: float,
        previous: LaneReference,
    ) -> LaneObservation:
        config = self.config
        left_floor = _evidence(rows, left)
        right_floor = _evidence(rows, right)
        left_edge = self._edge(left, "left", left_floor)
        right_edge = self._edge(right, "right", right_floor)
        components = lane_components(
            height_px=state.size[1], left=left_floor, right=right_floor, config=config
        )
        components["consistency"] = consistency_component(
            left_edge, right_edge, previous, state.view, config
        )
        slope_sum = None
        lane_offset = lane_heading = None
        if left_edge is not None and right_edge is not None:
            slope_sum = left_edge.slope + right_edge.slope
            if left_floor is not None and right_floor is not None:
                lane_offset, lane_heading = lane_centre(left_floor, right_floor)
        observation = LaneObservation(
            frame_index=frame_index,
            time_s=time_s,
            left=left_edge,
            right=right_edge,
            slope_sum=slope_sum,
            confidence=combine(components, config),
            components=frozen_components(components),
            lane_offset_m=lane_offset,
            lane_heading_rad=lane_heading,
        )
        dashed = config.lane.dashed_side
        if (dashed is None or previous is None
                or observation.confidence >= one_side_ceiling(config)):
            return observation  # (a lane from one tape could not score higher)
        # the dashed line out of sight, the other tape seen where the lane was (perception.one_side)
        seen_sides: tuple[Side, ...] = ("left", "right") if dashed == "both" else (
            other_side(dashed),)
        for seen in seen_sides:
            edge, floor = (right_edge, right_floor) if seen == "right" else (left_edge, left_floor)
            if edge is None or floor is None:
                continue
            one_side = lane_from_one_side(seen, edge, floor, state.view, state.size[1], config,
                                          previous, frame_index, time_s)
            if one_side is not None and one_side.confidence > observation.confidence:
                observation = one_side
        return observation

    def _edge(self, choice: SideChoice | None, side: Side,
              floor: EdgeEvidence | None) -> LaneEdge | None:
        if choice is None:
            return None
        offset = heading = near = far = None
        if floor is not None:
            offset = signed_offset(floor.point, floor.direction)
            heading = math.atan2(floor.direction[1], floor.direction[0])
            near, far = floor.point[0], floor.far_m
        x1, y1, x2, y2 = choice.x1, choice.y1, choice.x2, choice.y2
        # (LaneEdge's fields in their order: positional, a quarter cheaper than by keyword)
        return LaneEdge(x1, y1, x2, y2,
                        edge_slope(x1, y1, x2, y2, side, self.config.edges.max_abs_slope),
                        choice.support_px, offset, heading, near, far)


def assumed_ground_model(undistorter: Undistorter | None,
                         image_size: tuple[int, int] | None = None) -> GroundModel:
    """The ground model for this undistorter's frames (`perception.ground.ground_model_for`):
    the calibration's ground pose when it has one (`lanewarden calibrate ground`), else the
    simulator's default mount with the calibration's intrinsics; without a calibration the
    simulator's default camera at `image_size` (the frames' size when known, else 640x480)."""
    if undistorter is None:
        return default_ground_model(image_size or (640, 480))
    model, _ = ground_model_for(undistorter.calibration, undistorter.image_size,
                                camera_matrix=undistorter.camera_matrix)
    return model


def _evidence(rows: list[LineRow], choice: SideChoice | None) -> EdgeEvidence | None:
    """The chosen edge's near part on the floor: from its nearest point along its chain for at
    least EVIDENCE_MIN_M (the near line alone when it is that long, as on a straight lane; a
    Hough piece of a few pixels at the image's corner has no reliable direction). None when it
    has no floor position (it would have to reach the horizon, which the ROI never does)."""
    if choice is None:
        return None
    chain = choice.chain
    line = rows[chain[0]]
    near_x, near_y = near = (line.near_fx, line.near_fy)
    far_x, far_y = line.far_fx, line.far_fy
    for k in chain[1:]:
        if not math.hypot(far_x - near_x, far_y - near_y) < EVIDENCE_MIN_M:
            break
        line = rows[k]
        far_x, far_y = line.far_fx, line.far_fy
    d = direction(near, (far_x, far_y))
    isfinite = math.isfinite
    if (not (isfinite(near_x) and isfinite(near_y) and isfinite(d[0]) and isfinite(d[1]))
            or d == (0.0, 0.0)):
        return None
    # (EdgeEvidence's fields in their order: positional, a quarter cheaper than by keyword)
    return EdgeEvidence(near, d, choice.support_px, choice.tape_score, choice.verified,
                        choice.tape_dark, choice.polarity, choice.line_ids,
                        far_x if isfinite(far_x) else None)


def perception_gray(image: np.ndarray, dst: np.ndarray | None = None,
                    yellow_boost: float = 0.0) -> np.ndarray:
    """The 8-bit gray image perception works on, from an HxW gray, HxWx1, HxWx3 BGR or HxWx4
    BGRA uint8 frame (OpenCV's BGR2GRAY, `GRAY_WEIGHTS_BGR`; `dst`: a preallocated HxW buffer,
    used for a colour frame). With `yellow_boost` b > 0 a colour frame's gray is
    luma + b x max(0, luma - blue), saturated to 0..255 (`perception.config.GrayConfig`): yellow
    is lifted, and a pixel bluer than its luma keeps its luma. Everything
    perception computes from a frame depends on it only through this image, so a recording that
    keeps it keeps all perception needs."""
    if image.ndim == 2:
        return image
    if image.shape[2] == 1:
        return image[:, :, 0]
    code = cv2.COLOR_BGR2GRAY if image.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
    luma = cv2.cvtColor(image, code, dst=dst)
    if yellow_boost > 0.0:
        # luma - blue, saturated at 0 (OpenCV's uint8 subtract): a pixel bluer than its own luma
        # (a white tape under a camera's white balance) is not darkened
        yellowness = cv2.extractChannel(image, 0)
        cv2.subtract(luma, yellowness, dst=yellowness)
        cv2.addWeighted(luma, 1.0, yellowness, yellow_boost, 0.0, dst=luma)
    return luma


def _check_image(image: object) -> None:
    if not isinstance(image, np.ndarray):
        raise PerceptionError(f"frame: expected a numpy image array, got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise PerceptionError(f"frame: expected dtype uint8, got {image.dtype}")
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] in (1, 3, 4))):
        raise PerceptionError(
            f"frame: expected an HxW gray or HxWx3 BGR image, got shape {image.shape}"
        )
    if why := too_small(image.shape[1], image.shape[0]):
        raise PerceptionError(f"frame: {why}")
