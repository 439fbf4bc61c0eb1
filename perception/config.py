"""Perception's section of the one validated config (`perception:` in the YAML file).

Every default lives here, with units in the names. Conventions:
- `*_norm`: normalised image coordinates, x = column / width, y = row / height (origin top-left,
  y down), so one ROI fits every resolution. Values outside [0, 1] are allowed (a triangle whose
  base corners lie outside the image is clipped by it).
- `*_frac_of_height` / `*_frac_of_width`: a length in pixels expressed as a fraction of the image
  height or width, so the same config works at 640x480, 320x240 and 160x120.
- `*_deg`: degrees; `*_levels`: grey levels (0-255).
- Pixel parameters the lecture's pipeline takes as integers (blur kernel) are given for a
  480-row image and scaled with the image height (see `BlurConfig`).

This module only declares and validates numbers: it never touches images.
"""

from __future__ import annotations

import math
from typing import Annotated, Self

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

_FROZEN = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

Fraction = Annotated[float, Field(ge=0.0, le=1.0)]
PositiveFraction = Annotated[float, Field(gt=0.0, le=1.0)]
Weight = Annotated[float, Field(ge=0.0, le=4.0)]


class RoiConfig(BaseModel):
    """The region of interest, a polygon in normalised image coordinates.

    Default: the lecture's triangle rising from the bottom edge. Its base corners lie outside the
    image because with the default camera the lane's two tapes leave the image at its bottom
    corners and converge towards the top centre: a triangle with its corners AT the bottom
    corners would cut the tapes off. Inside the image it keeps the whole bottom and tapers to the
    apex, dropping the top corners (walls, clutter beside the far lane).
    """

    model_config = _FROZEN

    polygon_norm: tuple[tuple[float, float], ...] = Field(
        default=((-0.6, 1.0), (1.6, 1.0), (0.5, 0.0)),
        description=(
            "ROI polygon [[x, y], ...] in normalised image coordinates (x = column/width, y = "
            "row/height, y down); may extend outside the image. Default: the lecture's triangle "
            "rising from the bottom edge, base corners outside the image so the default camera's "
            "tapes stay inside"
        ),
    )

    @field_validator("polygon_norm")
    @classmethod
    def _polygon(cls, value: tuple[tuple[float, float], ...]) -> tuple[tuple[float, float], ...]:
        if len(value) < 3:
            raise ValueError(f"needs at least 3 vertices [x, y], got {len(value)}")
        for x, y in value:
            if not (math.isfinite(x) and math.isfinite(y)) or not (
                -2.0 <= x <= 3.0 and -2.0 <= y <= 3.0
            ):
                raise ValueError(
                    f"vertex [{x}, {y}] must be finite and within [-2, 3] (normalised image units)"
                )
        area2 = sum(
            x0 * y1 - x1 * y0
            for (x0, y0), (x1, y1) in zip(value, value[1:] + value[:1], strict=True)
        )
        if abs(area2) < 1e-6:
            raise ValueError("polygon has zero area (vertices collinear or repeated)")
        inside = [(x, y) for x, y in value if 0.0 <= y <= 1.0]
        if not inside:
            raise ValueError("polygon lies entirely above or below the image (all y outside 0..1)")
        return value


class BlurConfig(BaseModel):
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


class CannyConfig(BaseModel):
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


class HoughConfig(BaseModel):
    """Probabilistic Hough transform (cv2.HoughLinesP). Lengths scale with the image height."""

    model_config = _FROZEN

    rho_px: Annotated[float, Field(gt=0.0, le=10.0)] = Field(
        default=1.0,
        description=(
            "HoughLinesP distance resolution, pixels"
        ),
    )
    theta_deg: Annotated[float, Field(gt=0.0, le=10.0)] = Field(
        default=1.0,
        description=(
            "HoughLinesP angle resolution, degrees"
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


class EdgesConfig(BaseModel):
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
    - `look_ahead_y_norm`: the reported edge (and so its slope) ends where the edge crosses this
      image row, or at its far end if it stops short: every frame measures the same stretch of
      floor (to about 0.87 m ahead with the default camera), so a bend reads steadily instead of
      jumping with how far Hough happened to follow the curve. Farther (0.3: 1.1 m) makes the
      lecture's +-6 trip early in gentle bends (R 2 m), where its fixed turn rate then
      overshoots inside the bend in the closed loop.
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
    look_ahead_y_norm: Annotated[float, Field(ge=-1.0, le=1.0)] = Field(
        default=0.4,
        description=(
            "the reported edge (and its slope) ends where the edge crosses this image row "
            "(normalised), or at its far end if shorter: a fixed stretch of floor every frame"
        ),
    )
    max_abs_slope: Annotated[float, Field(gt=1.0, le=1000.0)] = Field(
        default=12.0,
        description=(
            "slope clamp; past vertical an edge reports it with its side's sign (left +, right -)"
        ),
    )


class TapeConfig(BaseModel):
    """Telling a tape (two parallel edges of opposite polarity, tape-wide apart) from a seam.

    - `width_min/max_frac_of_width`: the tape's width, measured horizontally and projected to the
      bottom of the ROI using `LaneGeometryConfig.horizon_y_norm` (perspective makes far tape
      thinner), as a fraction of image width. A 48 mm tape is ~8.6% with the default camera;
      4 mm tile grout ~0.7%. `expected_width_frac_of_width` is the tape's usual width on the
      same scale (used to tell whether a missing partner would be outside the image).
    - `min_gap_px`: two edges closer than this (pixels, where measured) are the two sides of one
      thin line (grout) however the perspective scales them: a resolution limit, not a length.
    - `pair_angle_tol_deg`: the two edges of one tape converge slightly; at most this apart.
    - `polarity_offset_frac_of_width`: how far either side of a line the brightness is sampled.
    - `polarity_samples`: points sampled along each line (a cheap stand-in for Sobel sign).
    - `min_contrast_levels`: a side difference smaller than this has no polarity (0).
    - `min_band_fraction`: at least this fraction of the points sampled along a tape candidate
      must show the band darker (or lighter) than the floor outside both edges (dashed tape
      passes with its gaps).
    - `min_profile_fraction`: an edge without a Hough partner counts as a tape edge when the
      brightness profile across it looks like a tape on its outer side along at least this
      fraction of its length (see `perception.edge_choice.tape_profile_fraction`).
    - `unpaired_preference`: weight of an edge with no tape partner when choosing, relative to
      one that is part of a tape (support is multiplied by it).
    - `unverifiable_score`: tape score of an unpaired edge whose partner would lie outside the
      image (cut off by the border), where the pair cannot be checked.
    """

    model_config = _FROZEN

    expected_width_frac_of_width: PositiveFraction = Field(
        default=0.086,
        description=(
            "usual tape width at the ROI bottom, fraction of image width (48 mm tape, default "
            "camera: 0.086)"
        ),
    )
    width_min_frac_of_width: PositiveFraction = Field(
        default=0.035,
        description=(
            "narrowest tape width at the ROI bottom, fraction of image width (4 mm grout is "
            "~0.007)"
        ),
    )
    width_max_frac_of_width: PositiveFraction = Field(
        default=0.18,
        description=(
            "widest tape width at the ROI bottom, fraction of image width"
        ),
    )
    min_gap_px: Annotated[float, Field(ge=0.0, le=100.0)] = Field(
        default=5.0,
        description=(
            "two edges closer than this (pixels, where measured) are the two sides of one thin "
            "line, never a tape"
        ),
    )
    pair_angle_tol_deg: Annotated[float, Field(gt=0.0, le=30.0)] = Field(
        default=10.0,
        description=(
            "max angle between the two edges of one tape"
        ),
    )
    polarity_offset_frac_of_width: PositiveFraction = Field(
        default=0.006,
        description=(
            "how far either side of a line brightness is sampled for its polarity, fraction of "
            "image width"
        ),
    )
    polarity_samples: Annotated[int, Field(ge=1, le=64)] = Field(
        default=6,
        description=(
            "points sampled along a line (polarity, tape band, tape profile)"
        ),
    )
    min_contrast_levels: Annotated[float, Field(ge=0.0, le=255.0)] = Field(
        default=8.0,
        description=(
            "smallest brightness difference that counts (polarity, tape band and profile), grey "
            "levels"
        ),
    )
    min_band_fraction: PositiveFraction = Field(
        default=0.3,
        description=(
            "share of samples along a tape pair whose band must look like tape (uniform, darker "
            "or lighter than the floor on both sides)"
        ),
    )
    min_profile_fraction: PositiveFraction = Field(
        default=0.6,
        description=(
            "share of samples along an unpaired edge whose brightness profile must show a tape on "
            "its outer side"
        ),
    )
    unpaired_preference: Fraction = Field(
        default=0.1,
        description=(
            "value factor of a lone line refuted as a tape edge, against a tape (edge choice)"
        ),
    )
    unverifiable_score: Fraction = Field(
        default=0.6,
        description=(
            "tape score of an edge whose tape's far side lies outside the image (cannot be "
            "checked)"
        ),
    )

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        lo, mid, hi = (
            self.width_min_frac_of_width,
            self.expected_width_frac_of_width,
            self.width_max_frac_of_width,
        )
        if not lo <= mid <= hi or lo == hi:
            raise ValueError(
                f"need width_min_frac_of_width ({lo:g}) <= expected_width_frac_of_width "
                f"({mid:g}) <= width_max_frac_of_width ({hi:g}), min below max"
            )
        return self


class LaneGeometryConfig(BaseModel):
    """What a lane looks like from this camera (defaults: `scenarios.camera.CameraModel()`).

    - `horizon_y_norm`: image row of the horizon (y_norm; negative = above the image). The two
      edges of a straight lane meet there. Default camera: -0.167.
    - `vanishing_y_tolerance_norm` / `vanishing_x_tolerance_norm`: the edges' intersection scores
      1 within this distance of (0.5, horizon_y_norm), falling to 0 at twice the distance.
    - `width_at_bottom_frac_of_width`: expected distance between the two chosen (inner) edges at
      the bottom of the ROI; `width_tolerance_frac_of_width`: scores 1 within it, 0 at twice it.
    """

    model_config = _FROZEN

    horizon_y_norm: Annotated[float, Field(ge=-3.0, le=0.9)] = Field(
        default=-0.167,
        description=(
            "image row of the horizon, normalised (negative: above the image; default camera "
            "-0.167)"
        ),
    )
    vanishing_y_tolerance_norm: Annotated[float, Field(gt=0.0, le=3.0)] = Field(
        default=0.3,
        description=(
            "vanishing_point scores 1 within this vertical distance of the horizon, 0 at twice it "
            "(normalised)"
        ),
    )
    vanishing_x_tolerance_norm: Annotated[float, Field(gt=0.0, le=3.0)] = Field(
        default=0.3,
        description=(
            "vanishing_point scores 1 within this horizontal distance of the image centre, 0 at "
            "twice it (normalised)"
        ),
    )
    width_at_bottom_frac_of_width: Annotated[float, Field(gt=0.0, le=3.0)] = Field(
        default=0.98,
        description=(
            "expected distance between the two (inner) edges at the ROI bottom, fraction of image "
            "width"
        ),
    )
    width_tolerance_frac_of_width: Annotated[float, Field(gt=0.0, le=3.0)] = Field(
        default=0.3,
        description=(
            "lane_width scores 1 within this of the expected width, 0 at twice it"
        ),
    )


class ConfidenceWeights(BaseModel):
    """Exponents of the confidence components: confidence = product of component ** weight.

    1 makes a component a full multiplicative gate, 0.5 softens it (0.25 ** 0.5 = 0.5), 0 ignores
    it. See `perception.confidence` for what each component measures.
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
    vanishing_point: Weight = Field(
        default=0.5, description="exponent of the vanishing_point component"
    )
    tape_pair: Weight = Field(
        default=1.0,
        description=(
            "exponent of the tape_pair components (shared: half per side)"
        ),
    )
    consistency: Weight = Field(default=0.5, description="exponent of the consistency component")


class ConfidenceConfig(BaseModel):
    """How the confidence score is computed (what counts as trusted is the supervisor's call:
    `supervisor.confidence_usable_min`).

    - `support_full_frac_of_height`: an edge whose segments total this length (fraction of image
      height) gets full support 1; shorter scales linearly.
    - `consistency_offset_tol_frac_of_width` / `consistency_angle_tol_deg`: how far an edge may
      move (at the ROI bottom) and turn since the previous observation and still score 1; the
      score falls to 0 at twice that.
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
    consistency_offset_tol_frac_of_width: PositiveFraction = Field(
        default=0.08,
        description=(
            "edge shift at the ROI bottom since the previous observation that still scores 1 (0 "
            "at twice it), fraction of image width"
        ),
    )
    consistency_angle_tol_deg: Annotated[float, Field(gt=0.0, le=90.0)] = Field(
        default=8.0,
        description=(
            "edge turn since the previous observation that still scores 1 (0 at twice it)"
        ),
    )


class PerceptionConfig(BaseModel):
    """Every perception tunable. `opencv_threads`: the process-wide OpenCV thread count that
    `LaneDetector` sets (1 by default, see `perception.detector`; -1 restores OpenCV's default)."""

    model_config = _FROZEN

    roi: RoiConfig = RoiConfig()
    blur: BlurConfig = BlurConfig()
    canny: CannyConfig = CannyConfig()
    hough: HoughConfig = HoughConfig()
    edges: EdgesConfig = EdgesConfig()
    tape: TapeConfig = TapeConfig()
    lane: LaneGeometryConfig = LaneGeometryConfig()
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
