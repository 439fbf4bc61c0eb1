"""The rendered labelled set (`rendered_set.py`): one tape, tape ends, seams, a floor strip, two
different tapes, dim and low-contrast frames, seen by the simulator's camera at 640x480 and
320x240 with the perception config a user describes each floor with.

- Every no-lane frame gives no decision (confidence below the supervisor's usable 0.2 or an edge
  missing): with the lane's real width, and with the narrowest `lane.width_m` the config accepts
  for that tape (the setting most likely to take one tape's two edges for a lane).
- Every lane frame gives a decision with both reported edges on the tapes (two different tapes
  described per side, a dim photo normalised, a grey tape 40 levels off the floor).
"""

from __future__ import annotations

import pytest

from lanewarden.perception.config import PerceptionConfig, narrowest_lane_width_m
from lanewarden.perception.decision import decide
from lanewarden.perception.detector import LaneDetector
from lanewarden.perception.ground import default_ground_model
from tests.perception import rendered_set
from tests.perception.rendered_set import Labelled

FRAMES = rendered_set.labelled_frames()
SIZES = ((640, 480), (320, 240))


def _decision(item: Labelled, size: tuple[int, int], narrow: bool) -> tuple[bool, bool]:
    """(decided, both reported edges on the tapes)."""
    overrides = item.perception_overrides()
    config = PerceptionConfig.model_validate(overrides)
    if narrow:
        width = narrowest_lane_width_m(config.tape, config.lane.width_tolerance_fraction)
        config = PerceptionConfig.model_validate(
            {**overrides, "lane": {**overrides.get("lane", {}), "width_m": width}})
    ground = default_ground_model(size)
    obs = LaneDetector(config, ground=ground).detect(
        rendered_set.render(item.picture, *size), 0, 0.0)
    decided = decide(obs, trust_min_confidence=0.2, turn_slope_sum=6.0) != "none"
    on = (obs.left is not None and obs.right is not None
          and rendered_set.edges_on_tapes(obs.left, item.picture, ground)
          and rendered_set.edges_on_tapes(obs.right, item.picture, ground))
    return decided, on


def test_the_set_has_both_classes_and_unique_names() -> None:
    names = [item.name for item in FRAMES]
    assert len(set(names)) == len(names)
    assert sum(item.expect == "lane" for item in FRAMES) == 14
    assert sum(item.expect == "none" for item in FRAMES) == 22


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
@pytest.mark.parametrize("narrow", [False, True], ids=["lane width", "narrowest lane"])
@pytest.mark.parametrize("item", [f for f in FRAMES if f.expect == "none"], ids=lambda f: f.name)
def test_no_lane_frames_give_no_decision(item: Labelled, size: tuple[int, int],
                                        narrow: bool) -> None:
    decided, _ = _decision(item, size, narrow)
    assert not decided, f"{item.name} ({item.shows}): a false lane"


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
@pytest.mark.parametrize("item", [f for f in FRAMES if f.expect == "lane"], ids=lambda f: f.name)
def test_lane_frames_give_a_decision_with_both_edges_on_the_tapes(item: Labelled,
                                                                 size: tuple[int, int]) -> None:
    decided, on = _decision(item, size, False)
    assert decided and on, f"{item.name} ({item.shows}): decided {decided}, on tapes {on}"
