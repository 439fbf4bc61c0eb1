"""Perception's section of the one validated config (`perception:` in the YAML file).

Every default lives here or in `perception.floor_config`, with units in the names:
- floor geometry in metres (`tape`, `lane`, `roi`, `edges.look_ahead_m`): what the world looks
  like, turned into pixels through the camera's ground model once per image size, so the same
  config holds for any camera (`perception.floor_config`);
- pixel knobs of the image processing (blur, Canny, Hough, merging and chaining Hough pieces,
  sampling beside a line): `*_px` pixels, `*_frac_of_height` / `*_frac_of_width` a length in
  pixels as a fraction of the image height or width (so they scale with the resolution),
  `*_deg` degrees in the image, `*_levels` grey levels (0-255). The blur kernel is given for a
  480-row image and scaled with the image height (see `BlurConfig`).

This module only declares and validates numbers: it never touches images.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal, Self

from pydantic import (
    ConfigDict,
    Field,
    ValidationError,
    ValidatorFunctionWrapHandler,
    field_validator,
    model_validator,
)

from lanewarden.documents import QUOTED_NUMBER, DocumentModel, text_kind
from lanewarden.perception.floor_config import LaneConfig, RoiConfig, TapeConfig

_FROZEN = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

Fraction = Annotated[float, Field(ge=0.0, le=1.0)]
PositiveFraction = Annotated[float, Field(gt=0.0, le=1.0)]
Weight = Annotated[float, Field(ge=0.0, le=4.0)]


class BlurConfig(DocumentModel):
    """Gaussian blur before Canny.

    `kernel_px` is the kernel size for a 480-row image (odd); at other heights it is scaled with
    the height and rounded to the nearest odd size, at least 3 (5 -> 3 at 240 and 120 rows).
    `sigma_px` 0 lets OpenCV derive sigma from the kernel size.
    """

    model_config = _FROZEN

    kernel_px: int = Field(
        default=5,
        ge=1,
        le=31,
        description=(
            "Gaussian blur kernel size (odd) for a 480-row image; scaled with the image height to "
            "the nearest odd size, at least 3"
        ),
    )
    sigma_px: Annotated[float, Field(ge=0.0, le=20.0)] = Field(
        default=0.0,
        description=(
            "Gaussian sigma in pixels; 0 derives it from the kernel size"
        ),
    )

    @field_validator("kernel_px")
    @classmethod
    def _odd(cls, value: int) -> int:
        if value < 1 or value % 2 == 0 or value > 31:
            raise ValueError(f"must be an odd kernel size between 1 and 31 px, got {value}")
        return value


class CannyConfig(DocumentModel):
    """Canny hysteresis thresholds (gradient magnitude, grey levels per pixel)."""

    model_config = _FROZEN

    low_threshold: Annotated[float, Field(ge=0.0, le=10000.0)] = Field(
        default=40.0,
        description=(
            "Canny lower hysteresis threshold (gradient, grey levels); below high_threshold"
        ),
    )
    high_threshold: Annotated[float, Field(gt=0.0, le=10000.0)] = Field(
        default=120.0,
        description=(
            "Canny upper hysteresis threshold (gradient, grey levels)"
        ),
    )
    aperture_px: int = Field(default=3, ge=3, le=7,
                             description="Sobel aperture of Canny: 3, 5 or 7")
    max_edge_share: PositiveFraction = Field(
        default=0.15,
        description=(
            "The most of the region of interest Canny's edges may cover. Where a frame's edges "
            "cover more (a textured floor: terrazzo's chips, carpet's pile), both thresholds "
            "are raised 1.2 times, at most six times (3 times the configured ones), until they "
            "do not: in such clutter HoughLinesP's random lines through the texture take the "
            "tape's edge pixels. 1: never raised"
        ),
    )

    @field_validator("aperture_px")
    @classmethod
    def _aperture(cls, value: int) -> int:
        if value not in (3, 5, 7):
            raise ValueError(f"must be 3, 5 or 7 (Sobel aperture), got {value}")
        return value

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if not self.low_threshold < self.high_threshold:
            raise ValueError(
                f"low_threshold ({self.low_threshold:g}) must be below high_threshold "
                f"({self.high_threshold:g})"
            )
        return self


class HoughConfig(DocumentModel):
    """Probabilistic Hough transform (cv2.HoughLinesP). Lengths scale with the image height."""

    model_config = _FROZEN

    # The lower bounds keep HoughLinesP's accumulator (180/theta_deg angles x about
    # 2 (width + height)/rho_px distances, 4 bytes each) within 35 MB at 1920x1080 and 170 MB
    # at the largest image `max_image_pixels` allows (50 Mpx, as much as the image's own
    # buffers): 0.0002 degrees had taken a 320x240 photo past 8 GB, and smaller values crashed
    # OpenCV's allocator with a traceback.
    rho_px: Annotated[float, Field(ge=0.5, le=10.0)] = Field(
        default=1.0,
        description=(
            "HoughLinesP distance resolution, pixels (at least 0.5: the accumulator grows as "
            "1/rho_px)"
        ),
    )
    theta_deg: Annotated[float, Field(ge=0.25, le=10.0)] = Field(
        default=1.0,
        description=(
            "HoughLinesP angle resolution, degrees (at least 0.25: the accumulator and the work "
            "per edge pixel grow as 1/theta_deg)"
        ),
    )
    votes_frac_of_height: PositiveFraction = Field(
        default=0.05,
        description=(
            "HoughLinesP accumulator threshold (votes), as a fraction of the image height (at "
            "least 5)"
        ),
    )
    min_line_length_frac_of_height: PositiveFraction = Field(
        default=0.05,
        description=(
            "HoughLinesP minLineLength as a fraction of the image height"
        ),
    )
    max_line_gap_frac_of_height: Fraction = Field(
        default=0.02,
        description=(
            "HoughLinesP maxLineGap as a fraction of the image height"
        ),
    )


class EdgesConfig(DocumentModel):
    """Turning Hough segments into lane-edge candidates.

    - `min_angle_from_horizontal_deg`: flatter segments are dropped (tile joints across the lane,
      the far ends of sharp bends).
    - `max_past_vertical_deg`: how far an edge may lean the "wrong" way for its side (a right edge
      leaning "/") and still count: the inner edge of a sharp bend does this.
    - `cluster_angle_tol_deg` / `cluster_offset_frac_of_width`: segments with directions within
      the angle and lying within the offset of a longer segment's line are one line (dashes,
      Hough's broken pieces of one edge).
    - `chain_gap_frac_of_height` / `chain_max_turn_deg`: a line whose near end starts within the
      gap of another's far end, turning by at most this much, continues it (a bending edge).
    - `look_ahead_m`: the reported edge (and so its slope) ends where the edge crosses the image
      row that sees the floor this far ahead of the robot's centre, or at its far end if it stops
      short: every frame measures the same stretch of floor, so a bend reads steadily instead of
      jumping with how far Hough happened to follow the curve. It must lie in the camera's view,
      and there the camera must tell the tape from a seam (checked at start-up). `auto` (the
      default): the detector picks, per image size, the farthest distance up to
      `max_look_ahead_m` that is in view and where this camera tells the tape from the widest
      seam (`perception.size_setup`), and says which.
    - `max_look_ahead_m`: the farthest `auto` goes. Farther than 0.87 m (1.1 m with the default
      camera) makes the lecture's +-6 trip early in gentle bends (R 2 m), where its fixed turn
      rate then overshoots inside the bend in the closed loop.
    - `max_abs_slope`: the slope clamp (see `perception.geometry`).
    """

    model_config = _FROZEN

    min_angle_from_horizontal_deg: Annotated[float, Field(ge=0.0, lt=80.0)] = Field(
        default=15.0,
        description=(
            "segments flatter than this are dropped (tile joints across the lane)"
        ),
    )
    max_past_vertical_deg: Annotated[float, Field(ge=0.0, le=60.0)] = Field(
        default=35.0,
        description=(
            "how far an edge may lean the wrong way for its side (a right edge leaning '/', as "
            "the inner edge of a sharp bend does) and still count"
        ),
    )
    cluster_angle_tol_deg: Annotated[float, Field(gt=0.0, le=20.0)] = Field(
        default=3.0,
        description=(
            "segments within this angle of a longer one, and on its line, merge into one line "
            "(dashes, broken edges)"
        ),
    )
    cluster_offset_frac_of_width: PositiveFraction = Field(
        default=0.008,
        description=(
            "max distance of a segment's midpoint from the longer segment's line to merge, "
            "fraction of image width"
        ),
    )
    chain_gap_frac_of_height: Fraction = Field(
        default=0.12,
        description=(
            "a line starting within this distance of another's end (fraction of image height) may "
            "continue it (a bending edge)"
        ),
    )
    chain_max_turn_deg: Annotated[float, Field(ge=0.0, le=90.0)] = Field(
        default=35.0,
        description=(
            "max turn between consecutive lines of one bending edge"
        ),
    )
    look_ahead_m: Annotated[float, Field(gt=0.0, le=10.0)] | Literal["auto"] = Field(
        default="auto",
        description=(
            "the reported edge (and its slope) ends where the edge crosses the image row seeing "
            "the floor this far ahead of the robot's centre, or at its far end if shorter: a "
            "fixed stretch of floor every frame, metres; auto: the farthest distance up to "
            "max_look_ahead_m where this camera tells the tape from a seam (said at start-up)"
        ),
    )
    max_look_ahead_m: Annotated[float, Field(gt=0.0, le=10.0)] = Field(
        default=0.87,
        description=(
            "the farthest look-ahead `auto` chooses, metres (farther trips the lecture's +-6 "
            "early in gentle bends)"
        ),
    )
    @field_validator("look_ahead_m", mode="wrap")
    @classmethod
    def _distance_or_auto(cls, value: object, handler: ValidatorFunctionWrapHandler) -> object:
        """One message for both kinds of value (not one per branch of the union); a number in
        quotes is text, refused as every other number in quotes is (the union took "0.40")."""
        expected = "expected a distance in metres above 0 and at most 10, or auto"
        if isinstance(value, str) and value != "auto" and text_kind(value) == QUOTED_NUMBER:
            raise ValueError(f"{expected}; not {QUOTED_NUMBER}")
        try:
            return handler(value)
        except ValidationError:
            raise ValueError(expected) from None

    max_abs_slope: Annotated[float, Field(gt=1.0, le=1000.0)] = Field(
        default=12.0,
        description=(
            "slope clamp; past vertical an edge reports it with its side's sign (left +, right -)"
        ),
    )


class ContrastConfig(DocumentModel):
    """Contrast normalisation of dim and low-contrast frames, before Canny.

    A frame whose blurred floor region (the ROI) varies in brightness by less than
    `target_std_levels` (its standard deviation, grey levels) is stretched about its mean to that
    spread, by at most `max_gain` (1 turns it off), so a dim photo gives its tape edges at
    Canny's fixed thresholds, and the polarity, band and profile checks see its tape's contrast
    in grey levels comparable to a well-lit frame's. A well-exposed frame is left as it is.
    Stretching adds no edge that was not there (sensor noise grows with it; the blur comes
    first), and every rule that tells a tape from a seam is metric, so it makes seams no more
    tape-like.
    """

    model_config = _FROZEN

    target_std_levels: Annotated[float, Field(ge=1.0, le=128.0)] = Field(
        default=24.0,
        description=(
            "a frame whose blurred floor region varies less than this (standard deviation, grey "
            "levels) is stretched to it"
        ),
    )
    max_gain: Annotated[float, Field(ge=1.0, le=16.0)] = Field(
        default=4.0,
        description="largest contrast stretch of a dim frame; 1 turns normalisation off",
    )


class GrayConfig(DocumentModel):
    """How a colour frame becomes the one gray image perception works on.

    OpenCV's luma (BGR2GRAY: 0.114 B + 0.587 G + 0.299 R) by default. In it a yellow line
    (#e3b21c: luma 176) is about as light as the light slats of parquet or a wooden floor, and
    perception loses it (docs/perception.md, "Gray"). `yellow_boost` b lifts yellow out:
    gray = luma + b x max(0, luma - blue). A yellow paint's blue is far below its luma (#e3b21c:
    148 levels), a wooden floor's much less (parquet's light slat #a5763f: 63), and a neutral
    grey's not at all, so white, grey and black tape and grey floors keep their gray levels; so
    does a pixel bluer than its luma (a white tape that a camera's white balance tints blue: with
    luma - blue unclipped, the boost darkened it into a wooden floor). Set it when
    the lane has a yellow line and survey with and without it (the default campaign's yellow
    line sets 0.8: docs/perception.md, "A yellow line"); it applies to colour frames only (a
    gray camera has no blue to take), and in the simulator it makes perception's frames colour
    (`simulation.perception_color`).
    """

    model_config = _FROZEN

    yellow_boost: Annotated[float, Field(ge=0.0, le=2.0)] = Field(
        default=0.0,
        description=(
            "b in gray = luma + b x max(0, luma - blue): lifts a yellow line above a wooden "
            "floor and never darkens a bluish white tape (colour cameras only; try 0.8 and "
            "survey with and without it: docs/perception.md, 'A yellow line'); 0 is OpenCV's "
            "BGR2GRAY"
        ),
    )


class ConfidenceWeights(DocumentModel):
    """Exponents of the confidence components: confidence = product of component ** weight.

    1 makes a component a full multiplicative gate, 0.5 softens it (0.25 ** 0.5 = 0.5), 0 ignores
    it. See `perception.confidence` for what each component measures. `verified_tape` has no
    weight: it is always a full gate (no confident lane without a verified tape).
    """

    model_config = _FROZEN

    both_sides: Weight = Field(default=1.0, description="exponent of the both_sides component")
    support: Weight = Field(
        default=0.5,
        description=(
            "exponent of the support components (shared: half per side)"
        ),
    )
    lane_width: Weight = Field(default=0.5, description="exponent of the lane_width component")
    parallel: Weight = Field(default=0.5, description="exponent of the parallel component")
    tape_pair: Weight = Field(
        default=1.0,
        description=(
            "exponent of the tape_pair components (shared: half per side)"
        ),
    )
    consistency: Weight = Field(default=0.5, description="exponent of the consistency component")


class ConfidenceConfig(DocumentModel):
    """How the confidence score is computed (what counts as trusted is the supervisor's call:
    `supervisor.confidence_usable_min`).

    - `support_full_frac_of_height`: an edge whose segments total this length (fraction of image
      height) gets full support 1; shorter scales linearly.
    - `consistency_offset_tol_m` / `consistency_angle_tol_deg`: how far an edge may move sideways
      on the floor and turn since the previous observation (in the control loop: the frame
      before, or the last lane the supervisor trusted within `supervisor.lane_lost_halt_s`,
      whichever agrees better) and still score 1; the score falls to 0 at twice that.
    """

    model_config = _FROZEN

    weights: ConfidenceWeights = ConfidenceWeights()
    support_full_frac_of_height: PositiveFraction = Field(
        default=0.3,
        description=(
            "Hough support (total segment length) of an edge that scores 1, fraction of image "
            "height"
        ),
    )
    consistency_offset_tol_m: Annotated[float, Field(gt=0.0, le=1.0)] = Field(
        default=0.05,
        description=(
            "sideways move of an edge on the floor since the previous observation that still "
            "scores 1 (0 at twice it), metres"
        ),
    )
    consistency_angle_tol_deg: Annotated[float, Field(gt=0.0, le=90.0)] = Field(
        default=8.0,
        description=(
            "turn of an edge on the floor since the previous observation that still scores 1 (0 "
            "at twice it)"
        ),
    )


class PerceptionConfig(DocumentModel):
    """Every perception tunable. `opencv_threads`: the process-wide OpenCV thread count that
    `LaneDetector` sets (1 by default, see `perception.detector`; -1 restores OpenCV's default)."""

    model_config = _FROZEN

    roi: RoiConfig = RoiConfig()
    blur: BlurConfig = BlurConfig()
    canny: CannyConfig = CannyConfig()
    hough: HoughConfig = HoughConfig()
    edges: EdgesConfig = EdgesConfig()
    gray: GrayConfig = GrayConfig()
    contrast: ContrastConfig = ContrastConfig()
    tape: TapeConfig = TapeConfig()
    lane: LaneConfig = LaneConfig()
    confidence: ConfidenceConfig = ConfidenceConfig()
    opencv_threads: Annotated[int, Field(ge=-1, le=64)] = Field(
        default=1,
        description=(
            "cv2.setNumThreads set by the detector (process-wide); 1 by default, -1 restores "
            "OpenCV's default"
        ),
    )
    max_image_pixels: Annotated[int, Field(ge=4096, le=50_000_000)] = Field(
        default=10_000_000,
        description=(
            "largest image (width x height, pixels) `detect`, `undistort` and the camera accept; "
            "image files are checked from their header before decoding"
        ),
    )

    @property
    def free_width_m(self) -> float:
        """The floor between the two tapes' inner edges the lane should show: `lane.width_m`
        (centre to centre) less half of each side's tape."""
        return self.lane.width_m - self.tape.mean_width_m

    @model_validator(mode="after")
    def _look_ahead_inside_roi(self) -> Self:
        roi = self.roi
        look = self.edges.look_ahead_m
        key = "edges.look_ahead_m"
        if look == "auto":
            look, key = self.edges.max_look_ahead_m, "edges.max_look_ahead_m"
        if not roi.near_m <= look <= roi.far_m:
            raise ValueError(
                f"{key} ({look:g}) must lie within the region of interest, "
                f"roi.near_m ({roi.near_m:g}) to roi.far_m ({roi.far_m:g})"
            )
        return self

    @model_validator(mode="after")
    def _lane_wider_than_a_tape(self) -> Self:
        """A lane's free width must never be mistaken for one tape's: the narrowest gap the
        `lane_width` component still scores (the free width less twice the tolerance) must
        exceed the widest tape as it may measure (its width plus its tolerance)."""
        lane, tape = self.lane, self.tape
        minimum = narrowest_lane_width_m(tape, lane.width_tolerance_fraction)
        if lane.width_m < minimum:
            tape_max = tape.widest_width_m * (1.0 + tape.width_tolerance_fraction)
            narrowest_gap = self.free_width_m - 2.0 * lane.width_tolerance_m
            raise ValueError(
                f"lane.width_m ({lane.width_m:g}) is too narrow for "
                f"{1000 * tape.widest_width_m:g} mm tape: with lane.width_tolerance_fraction "
                f"{lane.width_tolerance_fraction:g} a gap of {1000 * narrowest_gap:.0f} mm "
                f"between the two edges would still count as the lane, and one tape's own two "
                f"edges measure up to {1000 * tape_max:.0f} mm apart; expected lane.width_m "
                f"of at least {minimum:g} m (or a smaller width_tolerance_fraction)"
            )
        return self


def narrowest_lane_width_m(tape: TapeConfig, width_tolerance_fraction: float) -> float:
    """The narrowest `lane.width_m` the config accepts with this tape and lane tolerance: the
    next whole millimetre above the width at which the narrowest gap `lane_width` still scores
    (the free width less twice the tolerance) equals the widest tape as it may measure (its
    width plus its tolerance). Narrower, one tape's own two edges could score as the lane."""
    tape_max = tape.widest_width_m * (1.0 + tape.width_tolerance_fraction)
    minimum = (tape.mean_width_m + tape_max) / (1.0 - 2.0 * width_tolerance_fraction)
    return (math.floor(minimum * 1000.0) + 1) / 1000.0
