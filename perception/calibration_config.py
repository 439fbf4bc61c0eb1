"""Calibration quality gates and detection settings: the `calibration:` section of the one config.

Every default lives here, with units in the names. A calibration that fails a gate is refused by
`lanewarden calibrate` (exit code 2) and by `check_calibration` before anything moves. This module
only declares numbers: it never reads images or files.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field


class CalibrationConfig(BaseModel):
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
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    max_rms_px: Annotated[float, Field(gt=0.0)] = 1.0
    min_views: Annotated[int, Field(ge=3)] = 10
    min_coverage_fraction: Annotated[float, Field(ge=0.0, le=1.0)] = 0.5
    outlier_error_factor: Annotated[float, Field(gt=1.0)] = 2.0
    outlier_min_error_px: Annotated[float, Field(ge=0.0)] = 0.3
    max_edge_width_px: Annotated[float, Field(gt=0.0)] = 5.0
    min_contrast_levels: Annotated[float, Field(ge=0.0, le=255.0)] = 40.0
    subpix_window_px: Annotated[int, Field(ge=2, le=50)] = 5
    subpix_max_iterations: Annotated[int, Field(ge=1)] = 30
    subpix_epsilon_px: Annotated[float, Field(gt=0.0)] = 0.01
    max_views_per_calibration: Annotated[int, Field(ge=3)] = 60
    capture_min_novelty: Annotated[float, Field(gt=0.0)] = 0.2
