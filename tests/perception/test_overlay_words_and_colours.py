"""The overlay's words say something true about the confidence."""

from __future__ import annotations

from lanewarden.commands.detect import result_text
from lanewarden.perception.observation import LaneEdge, LaneObservation
from lanewarden.perception.overlay import confidence_text, perception_text

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
