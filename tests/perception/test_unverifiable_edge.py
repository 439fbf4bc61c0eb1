"""A lone edge whose tape cannot be checked (the tape's far side lies beyond the image's border)
stands in for a tape only when it shows a tape's contrast: at least
`edge_choice.UNVERIFIABLE_MIN_CONTRAST_SHARE` (half) of the step across the verified tape's inner
edge on the other side (docs/perception.md, rule 3 of edge choice).

Rendered: the bend scenes, whose inner (left) tape runs out of the image at its left border and
is never verified, with the left tape lighter than the right one. Real: a JetBot no-lane frame
(one tape) shifted by a third of a pixel, where a faint floor shading in the image's lower-left
corner passed for the lane's other tape at confidence 0.77 (confident) before the rule."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
import yaml

from lanewarden.config import config_from_mapping
from lanewarden.perception.calibration import Undistorter, load_calibration
from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.detector import LaneDetector
from lanewarden.perception.observation import LaneObservation
from tests.conftest import PROJECT_ROOT
from tests.perception import synthetic as syn

JETBOT = PROJECT_ROOT / "data" / "real" / "jetbot-tape-lane"
SIZES = [(640, 480), (320, 240)]


def bend_with_left_tape(level: float, size: tuple[int, int]) -> LaneObservation:
    """The left bend (floor 175, right tape 45: a step of 130 levels), its left tape at `level`."""
    scene = replace(syn.BEND_LEFT, left_tape_level=level)
    image = np.ascontiguousarray(syn.frame(scene, *size))
    return LaneDetector(PerceptionConfig()).detect(image, 0, 0.0)


@pytest.mark.parametrize("size", SIZES)
def test_a_tape_at_the_border_with_a_tapes_contrast_still_stands_in(size: tuple[int, int]) -> None:
    """Left tape at 90 (a step of 85, 0.65 of the right tape's): the lane as with matching tapes,
    the left side unverifiable (0.6), the left edge 0.18-0.19 m left of the robot."""
    for level in (45.0, 90.0):
        obs = bend_with_left_tape(level, size)
        assert obs.components["tape_pair_left"] == pytest.approx(0.6)
        assert obs.confidence == pytest.approx(0.7746, abs=1e-3)
        assert obs.left is not None and obs.left.offset_m == pytest.approx(0.185, abs=0.01)


@pytest.mark.parametrize("size", SIZES)
def test_a_faint_edge_at_the_border_does_not_stand_in_for_a_tape(size: tuple[int, int]) -> None:
    """Left tape at 125 (a step of 50, 0.38 of the right tape's): Canny and Hough still find its
    edge where the image shows it (at 0.77 confidence without the rule), but it is no tape edge:
    the left side scores 0 and so does the lane."""
    obs = bend_with_left_tape(125.0, size)
    assert obs.left is not None  # the edge is there to be refused
    assert obs.components["tape_pair_left"] == 0.0
    assert obs.confidence == 0.0


def test_a_floor_shading_in_a_real_frames_corner_is_no_lane_edge() -> None:
    """JetBot `road/xy_079_050_...`, labelled no-lane (one tape), shifted by (-0.050, +0.296) px
    as a camera's next frame might be: the tape is verified on the right; on the left the only
    edge is a floor shading at the image's lower-left corner (a step of about 20 levels against
    the tape's 54). It gave a confident lane (0.77); now its left side scores 0 and the frame
    has no decision."""
    config = config_from_mapping(yaml.safe_load((JETBOT / "camera.yaml").read_text()))
    detector = LaneDetector(config.perception,
                            Undistorter(load_calibration(JETBOT / "calibration.yaml")),
                            image_size=(224, 224))
    image = cv2.imread(str(JETBOT / "road" / "xy_079_050_37aafab4-f571-11ec-b631-16f63a1aa8c9.jpg"))
    shift = np.float32([[1.0, 0.0, -0.049660633350713024], [0.0, 1.0, 0.29632427028729424]])
    shifted = cv2.warpAffine(image, shift, (224, 224), flags=cv2.INTER_LINEAR,
                             borderMode=cv2.BORDER_REPLICATE)
    obs = detector.detect(shifted, 0, 0.0)
    assert obs.components["tape_pair_right"] == 1.0 and obs.components["verified_tape"] == 1.0
    assert obs.components["tape_pair_left"] == 0.0
    assert obs.confidence == 0.0


@pytest.mark.parametrize("size", SIZES)
def test_a_lane_with_one_dashed_line_holds_no_edge_to_the_other_lines_contrast(
        size: tuple[int, int]) -> None:
    """With `lane.dashed_side: left` (a road's dashed centre line, often another paint: yellow
    dashes beside a white line step a third as strongly in gray), the faint left line at the
    border stands in as before (unverifiable, 0.6), its contrast not held to the right line's;
    with `both` (two dashed lines of one tape) it is."""
    image = np.ascontiguousarray(syn.frame(replace(syn.BEND_LEFT, left_tape_level=125.0), *size))
    config = PerceptionConfig()
    for dashed, expected in (("left", 0.6), ("both", 0.0)):
        lane = config.lane.model_copy(update={"dashed_side": dashed})
        obs = LaneDetector(config.model_copy(update={"lane": lane})).detect(image, 0, 0.0)
        assert obs.components["tape_pair_left"] == pytest.approx(expected), dashed


def test_a_faint_right_edge_at_the_border_does_not_stand_in_either() -> None:
    """The right bend, its inner (right) tape at the border and faint (125 against the left
    tape's 45): refused as on the left."""
    for level, expected in ((45.0, 0.6), (125.0, 0.0)):
        scene = replace(syn.BEND_RIGHT, tape_level=level, left_tape_level=45.0)
        obs = LaneDetector(PerceptionConfig()).detect(
            np.ascontiguousarray(syn.frame(scene)), 0, 0.0)
        assert obs.components["tape_pair_right"] == pytest.approx(expected), level


def test_two_tapes_of_different_widths_hold_no_edge_to_the_others_contrast() -> None:
    """Per-side widths that differ say the two lines are different tapes: the faint left line
    is not held to the right one's contrast (unverifiable, 0.6)."""
    image = np.ascontiguousarray(syn.frame(replace(syn.BEND_LEFT, left_tape_level=125.0)))
    config = PerceptionConfig()
    tape = config.tape.model_copy(update={"left_width_m": 0.046})
    obs = LaneDetector(config.model_copy(update={"tape": tape})).detect(image, 0, 0.0)
    assert obs.components["tape_pair_left"] == pytest.approx(0.6)
