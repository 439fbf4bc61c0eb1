"""The lane's visibility in rendered frames (`scenarios.metrics.LaneContrast`): the contrast
between each tape and the floor beside it, read where the world's tapes land in the frame."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from lanewarden.actuation.base import Pose2D
from lanewarden.perception.config import PerceptionConfig
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.metrics import LaneContrast
from lanewarden.scenarios.render import CameraRenderer
from lanewarden.scenarios.texture import paint_ground
from lanewarden.scenarios.world import build_world
from tests.scenarios.helpers import spec_from

CAMERA = CameraModel(width_px=320, height_px=240)
#: The lower 60 % of the image (undistorted pixels), as a region of interest.
ROI = np.array([[0.0, 96.0], [319.0, 96.0], [319.0, 239.0], [0.0, 239.0]])
START = Pose2D(0.0, 0.0, 0.0)
#: What the detector can use: its smallest contrast after its largest stretch (8 / 4 levels).
NEEDED = PerceptionConfig().tape.min_contrast_levels / PerceptionConfig().contrast.max_gain


def scene(tape: str, floor: str, color: bool = False,
          yellow_boost: float = 0.0) -> tuple[LaneContrast, np.ndarray]:
    """A straight lane of `tape` on a plain `floor`, its frame at the start (seeded noise)."""
    spec = spec_from({"floor": {"kind": "plain", "color": floor, "variation": 0.0,
                                "grain": 0.0},
                      "tape": {"color": tape}, "lane": {"segments": [{"straight_m": 2.0}]}})
    world = build_world(spec, margin_m=1.0)
    renderer = CameraRenderer(paint_ground(world, 0.004, seed=0, color=color), CAMERA,
                              noise_sigma=2.0, seed=1)
    h, w = CAMERA.height_px, CAMERA.width_px
    frame = (renderer.render_bgr(START, np.empty((h, w, 3), np.uint8)) if color
             else renderer.render_gray(START, np.empty((h, w), np.uint8)))
    return LaneContrast(world, CAMERA, ROI, NEEDED, yellow_boost), frame


def over_exposed(frame: np.ndarray, factor: float) -> np.ndarray:
    """The same frame exposed `factor` times longer: the sensor clips at full scale."""
    return np.clip(frame.astype(np.float64) * factor, 0, 255).astype(np.uint8)


def test_the_threshold_is_the_detectors_own() -> None:
    assert NEEDED == pytest.approx(2.0)  # 8 levels / a stretch of at most 4


def test_white_tape_on_a_grey_floor_is_visible_and_gone_when_both_saturate() -> None:
    meter, frame = scene("#f0f0f0", "#808080")
    contrast = meter.measure(frame, START)
    # Painted 0xf0 - 0x80 = 112 levels apart (the renderer's blur takes a little off).
    assert contrast == pytest.approx([112.0, 112.0], abs=12.0)
    assert meter.visible(contrast)
    blinded = meter.measure(over_exposed(frame, 3.0), START)
    assert blinded.tolist() == [0.0, 0.0]  # tape and floor both at 255
    assert not meter.visible(blinded)


def test_a_dark_tape_on_a_saturated_light_floor_is_still_visible() -> None:
    meter, frame = scene("#202020", "#c8c8c8")
    bright = over_exposed(frame, 3.0)
    assert np.median(bright[120:, :]) == 255  # the floor saturates
    contrast = meter.measure(bright, START)
    # The tape at 3 x 0x20 = 96, the floor clipped at 255.
    assert contrast == pytest.approx([159.0, 159.0], abs=15.0)
    assert meter.visible(contrast)


def test_a_faint_tape_is_visible_only_from_the_detectors_threshold_up() -> None:
    meter, frame = scene("#848484", "#808080")  # 4 levels: a stretch of 4 makes 16
    assert meter.measure(frame, START).tolist() == [4.0, 4.0]
    assert meter.visible(meter.measure(frame, START))
    meter, frame = scene("#818181", "#808080")  # 1 level: a stretch of 4 makes 4 < 8
    assert meter.measure(frame, START).tolist() == [1.0, 1.0]
    assert not meter.visible(meter.measure(frame, START))
    flat = np.full_like(frame, 128)
    assert not meter.visible(meter.measure(flat, START))  # no contrast at all


def test_a_colour_frame_measures_as_its_gray_version() -> None:
    meter, frame = scene("#f0f0f0", "#808080", color=True)
    colour = meter.measure(frame, START)
    gray = meter.measure(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), START)
    assert colour.tolist() == gray.tolist()


def test_a_yellow_tape_measures_in_perceptions_boosted_gray() -> None:
    """Yellow #e3b21c on parquet's light slat colour #a5763f: luma 176 against 126; with
    `perception.gray.yellow_boost` 0.5 (what the detector then sees) 250 against 158."""
    meter, frame = scene("#e3b21c", "#a5763f", color=True)
    assert meter.measure(frame, START) == pytest.approx([50.0, 50.0], abs=6.0)
    meter, frame = scene("#e3b21c", "#a5763f", color=True, yellow_boost=0.5)
    assert meter.measure(frame, START) == pytest.approx([92.0, 92.0], abs=8.0)


def test_the_boost_leaves_a_bluish_white_tape_its_contrast() -> None:
    """A white tape as a camera's grey-world white balance shows it on a warm floor: tinted blue
    (#a8b0c8, luma 176, blue 200) on a warm grey (#8c8478, luma 133, blue 120): 43 levels in
    luma. The boost 0.8 lifts the floor by 0.8 x 13 = 10 and leaves the tape, bluer than its
    luma, as it is: 33. (With luma - blue unclipped it took 0.8 x 24 = 19 off the tape too:
    14 levels, the tape nearly gone into the floor; the 1000-run campaigns' white line on
    parquet.)"""
    meter, frame = scene("#a8b0c8", "#8c8478", color=True)
    assert meter.measure(frame, START).tolist() == [43.0, 43.0]
    meter, frame = scene("#a8b0c8", "#8c8478", color=True, yellow_boost=0.8)
    assert meter.measure(frame, START).tolist() == [33.0, 33.0]


def test_no_tape_in_the_roi_is_no_lane() -> None:
    meter, frame = scene("#f0f0f0", "#808080")
    turned = Pose2D(0.0, 0.0, math.pi)  # facing away from the lane
    contrast = meter.measure(frame, turned)
    assert np.isnan(contrast).all()
    assert not meter.visible(contrast)


def test_a_tape_between_a_darker_and_a_lighter_floor_shows_no_contrast() -> None:
    # Painted straight from the camera model: the lane between the tapes at 40, the tapes at
    # 128, the floor outside them at 220: each tape differs from one side by 88 levels, but is
    # neither darker nor lighter than the floor on BOTH sides (the detector's band rule).
    meter, _ = scene("#f0f0f0", "#808080")
    _, lateral = CAMERA.pixel_ground_points(distorted=True)
    half_lane, half_tape = 0.3, 0.024  # the default lane and tape (tape centres 0.3 m out)
    side = np.abs(np.nan_to_num(lateral, nan=10.0))
    frame = np.where(side < half_lane - half_tape, 40,
                     np.where(side <= half_lane + half_tape, 128, 220)).astype(np.uint8)
    assert meter.measure(frame, START).tolist() == [0.0, 0.0]
    frame[side > half_lane + half_tape] = 40  # the same floor on both sides: a lighter tape
    assert meter.measure(frame, START).tolist() == [88.0, 88.0]
