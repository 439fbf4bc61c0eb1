"""Calibration quality gates and detection settings: the `calibration:` section of the one config.

Every default lives here, with units in the names. A calibration that fails a gate is refused by
`lanewarden calibrate` (exit code 2) and by `check_calibration` before anything moves. This module
only declares numbers: it never reads images or files.
"""

from __future__ import annotations

from pydantic import ConfigDict, Field

from lanewarden.documents import DocumentModel


class CalibrationConfig(DocumentModel):
    """Quality gates and per-view rules for camera calibration.

    - `max_rms_px`: largest acceptable overall RMS reprojection error, pixels.
    - `min_views`: fewest usable chessboard views for a calibration to be trusted.
    - `min_coverage_fraction`: smallest share of the cells of a 6x6 grid over the image that must
      hold at least one corner of a used view (1.0 = corners seen everywhere). Corners near the
      edges are what pin down the distortion.
    - `outlier_error_factor` / `outlier_min_error_px`: a view is an outlier when its RMS error is
      above `outlier_error_factor` x the median view error AND above `outlier_min_error_px`.
    - `max_edge_width_px`: per-view blur rule; the mean width, in pixels, of the board's
      black-to-white transitions (cv2.estimateChessboardSharpness; ~2-3 px for a sharp view). A
      view above it is rejected as blurred.
    - `min_contrast_levels`: per-view exposure rule; white-square minus black-square brightness,
      grey levels (0-255). A view below it is rejected as too dark or washed out.
    - `subpix_window_px`: half size of the cornerSubPix search window (OpenCV's `winSize`).
    - `subpix_max_iterations` / `subpix_epsilon_px`: cornerSubPix stopping rule.
    - `max_views_per_calibration`: at most this many views go into calibrateCamera (evenly chosen);
      more add little and slow the solver down.
    - `capture_min_novelty`: `calibrate capture` keeps a frame only when its board differs from
      every kept one by at least this much (L1 distance of position, size and tilt, each
      normalised to about 0..1).
    - `max_ground_error_m`: gate of `calibrate ground` from a floor chessboard: the RMS distance
      on the floor between the board's corners and where the solved pose puts them, metres.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    max_rms_px: float = Field(
        default=1.0,
        gt=0.0,
        le=10.0,
        description="Gate: largest acceptable overall RMS reprojection error, px; above it the "
        "calibration is refused",
    )
    min_views: int = Field(
        default=10,
        ge=3,
        le=1000,
        description="Gate: fewest usable chessboard views for a calibration to be trusted",
    )
    min_coverage_fraction: float = Field(
        default=0.5,
        ge=0.0,
        le=1.0,
        description="Gate: smallest share (0-1) of the 6x6 image cells that must hold a corner of "
        "a used view; edge corners pin down the distortion",
    )
    outlier_error_factor: float = Field(
        default=2.0,
        gt=1.0,
        le=100.0,
        description="A view is an outlier when its RMS error is above this times the median view "
        "error (and above outlier_min_error_px)",
    )
    outlier_min_error_px: float = Field(
        default=0.3,
        ge=0.0,
        le=100.0,
        description="A view is an outlier only when its RMS error is also above this, px",
    )
    max_edge_width_px: float = Field(
        default=5.0,
        gt=0.0,
        le=100.0,
        description="Per-view blur rule: reject a view whose mean black-to-white edge width is "
        "above this, px (sharp: ~2-3 px)",
    )
    min_contrast_levels: float = Field(
        default=40.0,
        ge=0.0,
        le=255.0,
        description="Per-view exposure rule: reject a view whose white-minus-black square "
        "brightness is below this, grey levels (0-255)",
    )
    subpix_window_px: int = Field(
        default=5,
        ge=2,
        le=50,
        description="Half size of the cornerSubPix search window (OpenCV's winSize), px",
    )
    subpix_max_iterations: int = Field(
        default=30,
        ge=1,
        le=1000,
        description="cornerSubPix stopping rule: at most this many refinement iterations",
    )
    subpix_epsilon_px: float = Field(
        default=0.01,
        gt=0.0,
        le=10.0,
        description="cornerSubPix stopping rule: stop when a corner moves less than this, px",
    )
    max_views_per_calibration: int = Field(
        default=60,
        ge=3,
        le=1000,
        description="At most this many views (evenly chosen) go into calibrateCamera; more add "
        "little and slow the solver",
    )
    capture_min_novelty: float = Field(
        default=0.2,
        gt=0.0,
        le=5.0,
        description="`calibrate capture` keeps a frame only when its board differs from every "
        "kept one by at least this (L1 of normalised position, size and tilt)",
    )
    max_ground_error_m: float = Field(
        default=0.01,
        gt=0.0,
        le=0.1,
        description="Gate of `calibrate ground` (floor chessboard): largest RMS distance on the "
        "floor between the board's corners and where the solved camera pose puts them, m",
    )
