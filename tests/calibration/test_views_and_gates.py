"""Per-view rejection reasons, outliers, coverage and quality gates, and pattern parsing."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lanewarden.perception.calibration_config import CalibrationConfig
from lanewarden.perception.chessboard import (
    ChessboardPattern,
    ViewDetection,
    common_image_size,
    detect_view,
    larger_pattern,
    parse_pattern,
    reject_other_sizes,
)
from lanewarden.perception.chessboard_calibration import (
    calibrate_views,
    corner_coverage,
    flag_outliers,
    gate_failures,
)
from lanewarden.perception.errors import PerceptionError
from lanewarden.scenarios.chessboard import ChessboardLook, ChessboardRenderer
from tests.calibration.conftest import SyntheticViews

PATTERN = ChessboardPattern(9, 6)


@given(st.text(max_size=12))
@settings(derandomize=True, max_examples=200, deadline=None)
def test_parse_pattern_never_crashes(text: str) -> None:
    try:
        pattern = parse_pattern(text)
    except PerceptionError as exc:
        assert "\n" not in str(exc) and (
            "COLSxROWS" in str(exc) or "at least 3x3" in str(exc) or "at most 100" in str(exc)
        )
    else:
        assert pattern.columns >= 3 and pattern.rows >= 3
        assert parse_pattern(str(pattern)) == pattern


def test_parse_pattern_examples() -> None:
    assert parse_pattern("9x6") == ChessboardPattern(9, 6)
    assert parse_pattern(" 7X5 ").size == (7, 5)
    with pytest.raises(PerceptionError, match="'9by6' is not COLSxROWS"):
        parse_pattern("9by6")
    with pytest.raises(PerceptionError, match="at least 3x3"):
        parse_pattern("2x6")


def test_object_points_follow_opencv_order() -> None:
    points = ChessboardPattern(4, 3).object_points(0.5)
    assert points.shape == (12, 3)
    assert points[1].tolist() == [0.5, 0.0, 0.0] and points[4].tolist() == [0.0, 0.5, 0.0]


def test_blurred_and_dark_views_are_rejected_with_reasons(
    synthetic_views: SyntheticViews,
) -> None:
    config = CalibrationConfig()
    pose = synthetic_views.poses[0]
    blurred = synthetic_views.renderer.render(pose, blur_sigma_px=3.0)
    view = detect_view(blurred, PATTERN, config, name="blurred.png")
    assert view.board_found and not view.accepted
    assert view.rejection is not None and view.rejection.startswith("blurred (edge width")
    assert "calibration.max_edge_width_px 5 px" in view.rejection
    dim = ChessboardRenderer(synthetic_views.camera, look=ChessboardLook(20.0, 45.0, 30.0))
    view = detect_view(dim.render(pose), PATTERN, config, name="dark.png")
    if view.board_found:  # OpenCV may not even find a board this dim
        assert view.rejection is not None and view.rejection.startswith("too little contrast")
    sharp = detect_view(synthetic_views.images[0], PATTERN, config, name="sharp.png")
    assert sharp.accepted and sharp.edge_width_px is not None and sharp.edge_width_px < 3.0


def test_no_board_and_other_sizes() -> None:
    config = CalibrationConfig()
    empty = detect_view(np.full((480, 640), 128, np.uint8), PATTERN, config, name="wall.png")
    assert not empty.board_found
    assert empty.rejection == "board not found (looked for 9x6 inner corners, whole board)"
    views = [ViewDetection("a", (640, 480)), ViewDetection("b", (320, 240)),
             ViewDetection("c", (640, 480)), ViewDetection("d", None, rejection="unreadable")]
    size = common_image_size(views)
    assert size == (640, 480)
    judged = reject_other_sizes(views, size)
    assert judged[1].rejection == "image size 320x240 differs from 640x480 (the size of most views)"
    assert judged[0].rejection is None and judged[3].rejection == "unreadable"


def test_larger_board_is_noticed(synthetic_views: SyntheticViews) -> None:
    image = synthetic_views.images[0]
    assert larger_pattern(image, PATTERN) is None
    assert larger_pattern(image, ChessboardPattern(8, 6)) == PATTERN


def test_outlier_rule() -> None:
    config = CalibrationConfig(outlier_error_factor=2.0, outlier_min_error_px=0.3)
    assert flag_outliers([0.2, 0.21, 0.19, 0.5], config) == [False, False, False, True]
    # Twice the median but tiny in pixels: not an outlier.
    assert flag_outliers([0.05, 0.05, 0.05, 0.2], config) == [False, False, False, False]
    assert flag_outliers([], config) == []


def _views(synthetic_views: SyntheticViews, config: CalibrationConfig) -> list[ViewDetection]:
    return [detect_view(image, PATTERN, config, name=f"view_{i:02d}")
            for i, image in enumerate(synthetic_views.images)]


def test_outlier_view_is_flagged_and_dropped(synthetic_views: SyntheticViews) -> None:
    config = CalibrationConfig()
    views = _views(synthetic_views, config)
    corners = np.asarray(views[3].corners).copy()
    corners += np.random.default_rng(3).normal(0.0, 1.5, corners.shape).astype(np.float32)
    views[3] = ViewDetection("bumped.png", (640, 480), corners=corners, board_found=True)
    run = calibrate_views(views, PATTERN, 0.025, (640, 480), config)
    assert run.outliers == ("bumped.png",)
    dropped = calibrate_views(views, PATTERN, 0.025, (640, 480), config, drop_outliers=True)
    assert dropped.dropped_outliers == ("bumped.png",)
    assert dropped.rms_before_drop == pytest.approx(run.rms)
    assert dropped.rms < run.rms / 2
    assert dropped.calibration.views_used == len(views) - 1
    assert "bumped.png" not in {v.name for v in dropped.per_view}


def test_gates_name_measured_and_allowed_values(synthetic_views: SyntheticViews) -> None:
    strict = CalibrationConfig(max_rms_px=0.01, min_views=20, min_coverage_fraction=0.95)
    run = calibrate_views(_views(synthetic_views, strict), PATTERN, 0.025, (640, 480), strict)
    failures = gate_failures(run, strict)
    assert len(failures) == 3
    assert failures[0].startswith("rms ")
    assert "exceeds calibration.max_rms_px 0.01 px" in failures[0]
    assert failures[1] == "views_used 15 is below calibration.min_views 20"
    assert "is below calibration.min_coverage_fraction 0.95" in failures[2]
    with pytest.raises(PerceptionError, match="only 2 usable chessboard views"):
        calibrate_views(_views(synthetic_views, strict)[:2], PATTERN, 0.025, (640, 480), strict)


def test_coverage_names_the_missing_regions() -> None:
    # Corners only in the bottom-right ninth of a 600x600 image.
    corners = np.array([[450.0, 450.0], [550.0, 550.0], [450.0, 550.0], [550.0, 450.0]])
    coverage = corner_coverage([corners], (600, 600))
    assert coverage.fraction == pytest.approx(4 / 36)
    assert "bottom-right" not in coverage.missing and len(coverage.missing) == 8
    assert coverage.describe_missing() == (
        "no corners in the top third, the middle third, the bottom-left region and the "
        "bottom-centre region"
    )
    top_only = corner_coverage([np.array([[10.0, 10.0], [300.0, 10.0], [590.0, 10.0]])],
                               (600, 600))
    assert top_only.describe_missing() == (
        "no corners in the middle third and the bottom third; few corners in the top third"
    )
    everywhere = corner_coverage(
        [np.stack(np.meshgrid(np.arange(25, 600, 50.0), np.arange(25, 600, 50.0)), -1)],
        (600, 600),
    )
    assert everywhere.fraction == 1.0
    assert everywhere.describe_missing() == "corners in every region of the image"
