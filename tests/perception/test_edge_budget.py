"""The edge budget (`perception.canny.max_edge_share`): on a textured floor Canny's thresholds are
raised until its edges cover at most that share of the region of interest, so HoughLinesP's
random lines through the texture no longer take the tape's edges; a frame within the budget
sees the configured thresholds' edges, unchanged."""

from __future__ import annotations

import functools

import cv2
import numpy as np
import pytest

from lanewarden.perception.calibration import CameraCalibration, Undistorter
from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.detector import LaneDetector
from lanewarden.perception.overlay import overlay_text
from lanewarden.scenarios.realism import rendered_straight
from tests.perception import synthetic as syn

#: The simulator's terrazzo (`realism.FLOOR_SETS`): at 320x240, read without undistortion as
#: below, Canny's edges at the configured thresholds cover a fifth of the floor (21-22 %).
TERRAZZO = {"floor": {"kind": "terrazzo"}, "tape": {"color": "#1c1c1e"}}
#: The scenario's lane: tape centres 0.60 m apart, 48 mm tape: the inner edges 0.552 m apart.
FREE_WIDTH_M = 0.60 - 0.048


def with_share(share: float) -> PerceptionConfig:
    config = PerceptionConfig()
    return config.model_copy(update={"canny": config.canny.model_copy(
        update={"max_edge_share": share})})


@functools.cache
def terrazzo_frames() -> tuple[np.ndarray, ...]:
    frames, _ = rendered_straight(TERRAZZO, True, 12)
    return tuple(frames)


def undistorting(config: PerceptionConfig) -> LaneDetector:
    """A detector for the frames `rendered_straight` gives: the simulator's default camera at
    320x240, lens distortion and all."""
    _, camera = rendered_straight(TERRAZZO, True, 0)
    return LaneDetector(config, Undistorter(CameraCalibration(
        camera.camera_matrix(), camera.distortion(), (320, 240))))


def edge_share(detector: LaneDetector, frame: np.ndarray, factor: float) -> float:
    """The share of the ROI Canny's edges cover at `factor` times the configured thresholds
    (of a well-lit `frame`: the detector's contrast stretch leaves it as it is)."""
    setup = detector.setup_for(frame.shape[1], frame.shape[0])
    canny = detector.config.canny
    edges = cv2.Canny(detector.prepare(frame), canny.low_threshold * factor,
                      canny.high_threshold * factor, apertureSize=canny.aperture_px)
    return cv2.countNonZero(cv2.bitwise_and(edges, setup.mask)) / cv2.countNonZero(setup.mask)


def test_a_textured_floors_thresholds_are_raised_just_enough() -> None:
    detector = LaneDetector(PerceptionConfig())
    for frame in terrazzo_frames()[:3]:
        assert edge_share(detector, frame, 1.0) > 0.2  # the texture, at the configured thresholds
        _, debug = detector.detect_debug(frame, 0, 0.0)
        factor = debug.edge_threshold_factor
        # raised in steps of 1.2, at most six (3 times the configured thresholds)
        assert any(factor == pytest.approx(step)
                   for step in (1.2, 1.44, 1.728, 2.0736, 2.48832, 2.985984)), factor
        # within the budget at the factor chosen, over it one step lower: raised just enough
        assert edge_share(detector, frame, factor) <= 0.15
        assert edge_share(detector, frame, factor / 1.2) > 0.15
        setup = detector.setup_for(320, 240)
        assert cv2.countNonZero(setup.edges) <= 0.15 * cv2.countNonZero(setup.mask)


def test_on_terrazzo_the_raised_thresholds_keep_the_tapes_edges() -> None:
    """Raised thresholds drop the chips' weak steps, not the tapes': every frame of a straight
    lane on terrazzo is confident and its two reported edges lie the lane's free width apart.
    (On bends, where HoughLinesP lost the tapes in the clutter, the closed-loop runs of
    tests/campaign/test_campaign_regressions.py show what the budget changes.)"""
    detector = undistorting(PerceptionConfig())
    for index, frame in enumerate(terrazzo_frames()):
        observation = detector.detect(frame, index, index / 30.0)
        assert observation.confidence >= 0.6, (index, observation.components)
        left, right = observation.left, observation.right
        assert left is not None and right is not None
        assert left.offset_m is not None and right.offset_m is not None
        assert left.offset_m - right.offset_m == pytest.approx(FREE_WIDTH_M, abs=0.03), index


@pytest.mark.parametrize("scene", ["straight", "bend_left", "dashed", "tiles_with_tape"])
def test_a_frame_within_the_budget_keeps_the_configured_thresholds(scene: str) -> None:
    frame = np.ascontiguousarray(syn.render(getattr(syn, scene.upper()), 320, 240))
    budgeted = LaneDetector(PerceptionConfig())
    observation, debug = budgeted.detect_debug(frame, 0, 0.0)
    assert debug.edge_threshold_factor == 1.0
    unlimited = LaneDetector(with_share(1.0))
    assert unlimited.detect(frame, 0, 0.0) == observation
    assert edge_share(budgeted, cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), 1.0) <= 0.15


def test_share_one_never_raises_the_thresholds() -> None:
    detector = LaneDetector(with_share(1.0))
    _, debug = detector.detect_debug(terrazzo_frames()[0], 0, 0.0)
    assert debug.edge_threshold_factor == 1.0


def test_the_overlay_says_when_the_thresholds_were_raised() -> None:
    detector = LaneDetector(PerceptionConfig())
    observation, debug = detector.detect_debug(terrazzo_frames()[0], 0, 0.0)
    # this terrazzo frame needs three steps of 1.2 (1.728)
    assert overlay_text(observation, debug, "straight")[-1] == "Canny x1.73 (textured floor)"
    clean = np.ascontiguousarray(syn.render(syn.STRAIGHT, 320, 240))
    observation, debug = detector.detect_debug(clean, 0, 0.0)
    assert len(overlay_text(observation, debug, "straight")) == 3  # slope, confidence, decision
