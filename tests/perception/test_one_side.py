"""A lane from one tape (`perception.one_side`): with the dashed side's line out of sight
(`lane.dashed_side`), its edge is placed the lane's free width from the other tape, only while a
lane seen just before agrees, and such a lane is never more than half confident. The scene
`ONE_EDGE` shows the left tape only: the right line is the one out of sight. Rendered frames of
the default camera: the lane's tapes are 48 mm wide with centres 0.60 m apart, so the free width
between their inner edges is 0.552 m, the inner edges 0.276 m either side of the centre line."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.detector import LaneDetector
from lanewarden.perception.observation import LaneEdge, LaneObservation
from tests.perception import synthetic as syn

SIZES = [(640, 480), (320, 240)]


def _detector(dashed_side: str | None = "right") -> LaneDetector:
    config = PerceptionConfig.model_validate({"lane": {"dashed_side": dashed_side}})
    return LaneDetector(config)


def _lane(detector: LaneDetector, size: tuple[int, int]) -> LaneObservation:
    lane = detector.detect(syn.frame(syn.STRAIGHT, *size), 0, 0.0)
    assert lane.confidence == pytest.approx(1.0) and lane.sides_seen == 2
    return lane


@pytest.mark.parametrize("size", SIZES)
def test_the_right_tape_out_of_sight_is_placed_the_lanes_width_from_the_left(
        size: tuple[int, int]) -> None:
    detector = _detector()
    seen_before = _lane(detector, size)
    obs = detector.detect(syn.frame(syn.ONE_EDGE, *size), 1, 1 / 30, seen_before)
    assert obs.sides_seen == 1
    assert obs.components["both_sides"] == 0.5
    # usable (the supervisor's 0.2), never confident (its 0.6): one side seen, all else sound
    assert obs.confidence == pytest.approx(0.5)
    assert obs.left is not None and obs.right is not None
    assert obs.left.offset_m == pytest.approx(0.276, abs=0.01)
    assert obs.right.offset_m == pytest.approx(-0.276, abs=0.01)
    assert obs.right.support_px == 0.0  # nothing in the image voted for it
    assert obs.slope_sum == pytest.approx(obs.left.slope + obs.right.slope)
    assert obs.lane_offset_m == pytest.approx(0.0, abs=0.01)


@pytest.mark.parametrize("size", SIZES)
def test_no_lane_from_one_tape_without_a_lane_seen_before(size: tuple[int, int]) -> None:
    """A still (survey, `detect`), the first frame, after a loss: one tape is no lane."""
    detector = _detector()
    obs = detector.detect(syn.frame(syn.ONE_EDGE, *size), 1, 1 / 30, None)
    assert obs.confidence == 0.0
    assert obs.sides_seen == 1 and obs.right is None


@pytest.mark.parametrize("size", SIZES)
def test_no_lane_from_one_tape_where_the_lane_seen_before_was_elsewhere(
        size: tuple[int, int]) -> None:
    """The lane seen before lay 0.12 m further left (twice the consistency tolerance of 5 cm
    and more): the tape seen now is not that lane's."""
    detector = _detector()
    seen_before = _lane(detector, size)
    moved = LaneObservation(
        frame_index=0, time_s=0.0,
        left=_shifted(detector, seen_before.left, size, 0.12),
        right=_shifted(detector, seen_before.right, size, 0.12),
        slope_sum=seen_before.slope_sum, confidence=1.0)
    obs = detector.detect(syn.frame(syn.ONE_EDGE, *size), 1, 1 / 30, moved)
    assert obs.confidence == 0.0


@pytest.mark.parametrize("size", SIZES)
def test_no_lane_from_one_tape_when_the_lane_before_had_one_side_only(
        size: tuple[int, int]) -> None:
    """The reference must show the lane: both its edges (a lone tape seen before is none)."""
    detector = _detector()
    one_tape = detector.detect(syn.frame(syn.ONE_EDGE, *size), 0, 0.0)
    assert one_tape.right is None
    obs = detector.detect(syn.frame(syn.ONE_EDGE, *size), 1, 1 / 30, one_tape)
    assert obs.confidence == 0.0


@pytest.mark.parametrize("dashed_side", [None, "left"])
@pytest.mark.parametrize("size", SIZES)
def test_a_solid_line_out_of_sight_is_never_bridged(size: tuple[int, int],
                                                   dashed_side: str | None) -> None:
    """No dashed line (the default), or the dashed one is the line still seen: the right tape
    out of sight may have ended, and one tape is no lane."""
    detector = _detector(dashed_side)
    seen_before = _lane(detector, size)
    obs = detector.detect(syn.frame(syn.ONE_EDGE, *size), 1, 1 / 30, seen_before)
    assert obs.confidence == 0.0 and obs.sides_seen == 1


@pytest.mark.parametrize("size", SIZES)
def test_with_both_lines_dashed_either_tape_out_of_sight_is_placed(size: tuple[int, int]) -> None:
    """`dashed_side: both` (the `dashed` scenario's lane): the left tape alone places the right
    edge, the right tape alone (the same frame mirrored) the left one; half confident either
    way."""
    detector = _detector("both")
    seen_before = _lane(detector, size)
    left_only = syn.frame(syn.ONE_EDGE, *size)
    right_only = np.ascontiguousarray(left_only[:, ::-1])
    for frame, placed in ((left_only, "right"), (right_only, "left")):
        obs = detector.detect(frame, 1, 1 / 30, seen_before)
        assert obs.sides_seen == 1
        assert obs.confidence == pytest.approx(0.5)
        assert obs.left is not None and obs.right is not None
        assert obs.left.offset_m == pytest.approx(0.276, abs=0.01)
        assert obs.right.offset_m == pytest.approx(-0.276, abs=0.01)
        assert (obs.right if placed == "right" else obs.left).support_px == 0.0
        assert (obs.left if placed == "right" else obs.right).support_px > 0.0


@pytest.mark.parametrize("scene", [syn.TILES_ONLY, syn.NO_LANE], ids=["tiles", "bare"])
def test_no_lane_from_floor_without_a_verified_tape_even_after_a_lane(scene: syn.Scene) -> None:
    """Tile grout beside a lane just seen is no tape: nothing to place a lane from."""
    detector = _detector()
    seen_before = _lane(detector, (640, 480))
    obs = detector.detect(syn.frame(scene), 1, 1 / 30, seen_before)
    assert obs.confidence == 0.0


def test_a_lane_with_both_tapes_is_reported_as_seen_not_placed() -> None:
    detector = _detector()
    seen_before = _lane(detector, (640, 480))
    obs = detector.detect(syn.frame(syn.STRAIGHT), 1, 1 / 30, seen_before)
    assert obs.sides_seen == 2 and obs.components["both_sides"] == 1.0
    assert obs.right is not None and obs.right.support_px > 0.0


def _shifted(detector: LaneDetector, edge: LaneEdge | None, size: tuple[int, int],
             left_m: float) -> LaneEdge:
    """`edge` moved `left_m` to the left on the floor (its image segment re-projected)."""
    assert edge is not None
    view = detector.setup_for(*size).view
    a = view.to_floor(edge.x1, edge.y1)
    b = view.to_floor(edge.x2, edge.y2)
    x1, y1 = view.to_image(a[0], a[1] + left_m)
    x2, y2 = view.to_image(b[0], b[1] + left_m)
    return replace(edge, x1=x1, y1=y1, x2=x2, y2=y2)
