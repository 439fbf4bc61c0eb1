"""The ground check picture keeps its look-ahead row in sight: the caption moves off it."""

from __future__ import annotations

import numpy as np

from lanewarden.perception.ground import CameraPose, GroundModel
from lanewarden.perception.ground_report import caption_top, draw_ground_check
from lanewarden.scenarios.camera import CameraModel

#: The lecture's camera (as in tests/calibration/test_ground_cli.py).
CAMERA = CameraModel(height_m=0.22, pitch_down_deg=50.0, hfov_deg=62.0, forward_offset_m=0.12)
YELLOW = (0, 220, 240)  # BGR


def test_the_caption_goes_where_the_look_ahead_row_is_not() -> None:
    # two caption lines are a block 36 px tall in a 480 px picture
    assert caption_top(480, 36, 240.0) == 4, "top-left when the row is lower"
    assert caption_top(480, 36, None) == 4
    assert caption_top(480, 36, 31.0) == 440, "bottom-left when the row is near the top"
    assert caption_top(480, 36, 3.5) == 440
    # the block covers rows 4 to 40; the row keeps 4 px clear of it
    assert caption_top(480, 36, 43.0) == 440
    assert caption_top(480, 36, 44.0) == 4
    # a short picture with the row near both corners: just below the row, or just above it
    assert caption_top(80, 36, 40.0) == 44
    assert caption_top(80, 36, 42.0) == 2
    assert caption_top(76, 36, 38.0) == 4, "room for none: the top (the row drawn over it)"


def test_the_review_s_row_31_stays_yellow_from_edge_to_edge() -> None:
    """The caption box (black, from the top-left corner) covered the row's left part."""
    calibration = CAMERA.calibration()
    model = GroundModel(calibration.camera_matrix, CameraPose(height_m=0.22, pitch_deg=38.0),
                        calibration.image_size)
    picture = draw_ground_check(None, model, ["camera: h 0.220 m, pitch 38.0 deg, 0.120 m "
                                              "ahead of the robot's centre",
                                              "from the mount (measured)"],
                                look_ahead_v=31.0, lane_width_m=0.6)
    assert picture.shape == (480, 640, 3)
    row = picture[31]
    yellow = np.all(np.abs(row.astype(int) - YELLOW) <= 40, axis=1)
    assert yellow[:300].mean() > 0.9, "the row's left part, where the caption was, is yellow"
    # the caption now sits in the bottom-left corner: black behind white text
    assert (picture[444:476, 4:300] == 0).all(axis=2).mean() > 0.5
    assert not (picture[4:40, 4:300] == 0).all(axis=2).any(), "nothing black at the top"
