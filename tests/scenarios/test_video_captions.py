"""The run video's captions stay inside the frame: a caption too wide for its panel is drawn
smaller, and one still too wide is shortened ('...'), never cut at the frame's edge."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from lanewarden.actuation.base import STOP
from lanewarden.scenarios.texture import paint_ground
from lanewarden.scenarios.video import (
    MIN_CAPTION_CAP_PX,
    MapView,
    VideoRecorder,
    caption_cap_height_px,
    caption_height_px,
    fit_caption,
)
from lanewarden.scenarios.world import build_world
from lanewarden.supervisor.loop import StepRecord
from tests.scenarios.helpers import straight_spec


def _width(text: str, cap: float) -> int:
    from lanewarden.perception.overlay import text_scale

    return int(cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, text_scale(cap), 2)[0][0])


def test_a_caption_that_fits_is_left_alone() -> None:
    lines: list[str | tuple[str, tuple[int, int, int]]] = ["FOLLOW", ("t = 1.0 s", (1, 2, 3))]
    assert fit_caption(lines, 400, 14.0) == (lines, 14.0)


def test_a_wide_caption_shrinks_then_is_shortened() -> None:
    title = "t = 12.3 s  lane-ends, supervised"
    fitted, cap = fit_caption([title, "HALT: DEGRADED_BUDGET_EXHAUSTED"], 380, 14.0)
    assert MIN_CAPTION_CAP_PX <= cap < 14.0
    assert fitted[0] == title, "shrunk, not cut"
    assert max(_width(str(line), cap) for line in fitted) <= 380
    fitted, cap = fit_caption(["x" * 300], 200, 14.0)
    assert cap == MIN_CAPTION_CAP_PX
    assert str(fitted[0]).endswith("...") and _width(str(fitted[0]), cap) <= 200


def test_the_video_frame_has_no_text_at_its_edges(tmp_path: Path) -> None:
    """The sim's own title and a long halt reason, at the demo's 640x480 camera and 480 px map:
    the last columns of each panel's caption stay the caption's background."""
    world = build_world(straight_spec(2.0), margin_m=1.0)
    recorder = VideoRecorder(tmp_path / "video.mp4", (640, 480),
                             MapView(world, paint_ground(world, 0.02, 0), 480), fps=10.0,
                             crf=18, preset="ultrafast",
                             title="fault-perception-exception, supervised, with a title far "
                                   "too long for its panel")
    record = StepRecord(frame_index=0, time_s=12.3, observation=None, filtered_slope_sum=-1.25,
                        slope_sum_variance=None, state="HALT", events=(), command=STOP,
                        halt_reason="DEGRADED_BUDGET_EXHAUSTED: degraded for longer than x")
    recorder.step(world.start_pose, record)
    recorder.add(np.full((480, 640, 3), 90, np.uint8), world.start_pose, 12.3, record, None)
    recorder.close()
    frame = cv2.imread(str(tmp_path / "poster.jpg"))
    band = frame[:caption_height_px(480)].astype(np.int16)
    margin = round(caption_cap_height_px(480) * 0.7)
    panel_w = 640
    for right_edge in (panel_w - 2, frame.shape[1]):  # each panel's last columns
        strip = band[:, right_edge - margin // 2:right_edge]
        assert np.abs(strip - 32).max() <= 24, "text reaches the panel's right edge"
    assert np.abs(band[:, panel_w + margin:] - 32).max() > 100, "the caption is drawn"


def test_a_long_title_is_cut_after_the_time() -> None:
    fitted, _ = fit_caption(["t = 12.3 s  fault-perception-exception, supervised, and more"],
                            300, 14.0)
    assert str(fitted[0]).startswith("t = 12.3 s  fault-") and str(fitted[0]).endswith("...")
