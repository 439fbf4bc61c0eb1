"""Which pictures the survey's report keeps (`survey_run.PictureKeeper`), on results written out
by hand: bounded whatever the length of the recording, the weakest lane frames when any lane
frame is not confident, else the least confident ones."""

from __future__ import annotations

from lanewarden.survey import FrameResult, LabelledFrame
from lanewarden.survey_run import Picture, PictureKeeper


def _lane(order: int, confidence: float, confident: bool) -> FrameResult:
    return FrameResult(LabelledFrame(f"frame {order}", "lane", order),
                       "straight" if confidence >= 0.3 else "none", confidence, confident)


class _Drawn:
    """Stands in for the overlay drawing: a picture named after the frame, and a count."""

    def __init__(self) -> None:
        self.count = 0

    def draw(self, result: FrameResult) -> Picture:
        self.count += 1
        return Picture(result.frame.name, "lane", result.confidence, (), b"",
                       result.confident)


def test_a_long_recording_whose_lane_frames_are_all_confident_keeps_eight() -> None:
    """1600 confident lane frames, each less confident than the one before (every offer a new
    least confident): 8 pictures are kept, the last frame of each stretch of 200."""
    keeper = PictureKeeper(range(1600))
    drawn = _Drawn()
    for order in range(1600):
        result = _lane(order, 1.0 - order / 10_000, confident=True)
        keeper.offer(result, lambda r=result: drawn.draw(r))
    assert [p.name for p in keeper.weak] == [
        "frame 199", "frame 399", "frame 599", "frame 799", "frame 999", "frame 1199",
        "frame 1399", "frame 1599"]
    assert all(p.confident for p in keeper.weak)


def test_once_a_lane_frame_is_not_confident_only_such_frames_are_kept() -> None:
    keeper = PictureKeeper(range(16))
    drawn = _Drawn()
    offers = [(0, 0.9, True), (1, 0.8, True), (5, 0.2, False), (6, 0.1, False),
              (9, 0.7, True), (12, 0.6, True), (13, 0.0, False)]
    for order, confidence, confident in offers:
        result = _lane(order, confidence, confident)
        keeper.offer(result, lambda r=result: drawn.draw(r))
    # stretches of 2 frames: 5 (stretch 2), 6 (stretch 3), 13 (stretch 6); the confident
    # ones are dropped, and those after the first weak one are never drawn
    assert [(p.name, p.confident) for p in keeper.weak] == [
        ("frame 5", False), ("frame 6", False), ("frame 13", False)]
    assert drawn.count == 5
