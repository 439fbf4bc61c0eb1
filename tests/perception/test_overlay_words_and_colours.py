"""The overlay's words say something true about the confidence, and its Hough segments are drawn
in a colour that a yellow centre line, white tape or the floor cannot hide."""

from __future__ import annotations

import cv2
import numpy as np

from lanewarden.commands.detect import result_text
from lanewarden.perception.observation import LaneEdge, LaneObservation
from lanewarden.perception.overlay import OVERLAY_STYLES, confidence_text, perception_text
from tests.conftest import shared_data

ALL_ONE = {"both_sides": 1.0, "support_left": 1.0, "lane_width": 1.0, "tape_pair_left": 1.0,
           "consistency": 1.0}


def _observation(confidence: float, components: dict[str, float]) -> LaneObservation:
    return LaneObservation(frame_index=0, time_s=0.0,
                           left=LaneEdge(100.0, 470.0, 250.0, 200.0, slope=+1.25),
                           right=LaneEdge(540.0, 470.0, 390.0, 200.0, slope=-1.25),
                           slope_sum=0.0, confidence=confidence, components=components)


def test_with_every_component_at_one_no_component_is_called_the_lowest() -> None:
    """The review: 'lowest both_sides 1.00' when every component was 1 (the first of equals)."""
    assert confidence_text(_observation(1.0, ALL_ONE)) == "confidence 1.00 (all components 1.00)"
    assert confidence_text(_observation(0.77, {**ALL_ONE, "tape_pair_left": 0.6})) == \
        "confidence 0.77 (lowest tape_pair_left 0.60)"
    assert confidence_text(_observation(0.0, {})) == "confidence 0.00"
    assert perception_text(_observation(1.0, ALL_ONE), "straight") == [
        "slope sum +0.00", "confidence 1.00 (all components 1.00)", "decision straight"]


def test_detect_says_it_the_same_way() -> None:
    assert result_text("a.png", _observation(1.0, ALL_ONE), "straight") == (
        "a.png: straight  slope sum +0.00 (left +1.25, right -1.25)  confidence 1.00 "
        "(all components 1.00)")
    assert result_text("b.png", _observation(0.0, {**ALL_ONE, "support_left": 0.0}), "none") == (
        "b.png: none  slope sum +0.00 (left +1.25, right -1.25)  confidence 0.00 "
        "(lowest support_left 0.00)")


def _lab(bgr: np.ndarray) -> np.ndarray:
    """CIELAB (L 0..100, a and b signed) of BGR uint8 colours, shape (..., 3)."""
    lab = cv2.cvtColor(np.asarray(bgr, np.uint8).reshape(-1, 1, 3), cv2.COLOR_BGR2LAB)
    lab = lab.reshape(-1, 3).astype(np.float64)
    return np.column_stack([lab[:, 0] * 100.0 / 255.0, lab[:, 1] - 128.0, lab[:, 2] - 128.0])


#: What a Hough segment is drawn over (BGR): tapes, floors, and in a real frame the Donkeycar
#: tub's yellow dashes (their median colour, measured: a dim, greenish yellow).
BACKGROUNDS = {
    "yellow tape": (40, 200, 230), "dim yellow dash (Donkeycar tub)": (66, 119, 121),
    "white tape": (240, 240, 240), "black tape": (30, 30, 30), "grey floor": (128, 128, 128),
    "concrete": (150, 155, 160), "light wood": (120, 170, 210), "dark wood": (40, 75, 120),
    "beige tile": (170, 200, 220), "terracotta": (60, 90, 180),
}


def test_the_hough_segments_stand_apart_from_tape_floors_and_the_other_colours() -> None:
    """CIELAB distance (ΔE76; 2.3 is just noticeable, over 50 another colour altogether) of the
    segment colour from each background and from every other colour the overlay draws. The old
    orange-yellow was 14 from yellow tape."""
    segment = _lab(np.array([OVERLAY_STYLES["segment"].bgr]))[0]
    for name, bgr in BACKGROUNDS.items():
        distance = float(np.linalg.norm(_lab(np.array([bgr]))[0] - segment))
        assert distance > 60.0, f"{name}: ΔE {distance:.0f}"
    for key, style in OVERLAY_STYLES.items():
        if key != "segment":
            distance = float(np.linalg.norm(_lab(np.array([style.bgr]))[0] - segment))
            assert distance > 60.0, f"{style.label}: ΔE {distance:.0f}"


def test_no_part_of_the_real_track_has_the_segments_colour() -> None:
    """Every 10th frame of the Donkeycar tub (yellow dashed centre line, white edge lines, grey
    floor): not one pixel in a thousand within ΔE 30 of the segment colour (the old one: 6)."""
    frames = sorted(shared_data("donkeycar-tub/images").glob("*.jpg"))[::10]
    assert len(frames) == 100
    pixels = np.concatenate([cv2.imread(str(f)).reshape(-1, 3) for f in frames])
    distance = np.linalg.norm(_lab(pixels) - _lab(np.array([OVERLAY_STYLES["segment"].bgr])),
                              axis=1)
    assert float(np.mean(distance < 30.0)) < 0.001
