"""A photo or frame smaller than perception works on (`MIN_IMAGE_SIDE_PX` a side) is refused in
one line naming the file (or frame, or camera), its size and the minimum; exit 2.

A 1x1 image had been refused as a config problem ("perception.roi (near_m 0, far_m 1.6, ...):
this floor is not in the camera's view at 1x1"; a 12x10 one as perception.edges.look_ahead_m),
naming no file in survey, replay and run; `calibrate` and `calibrate capture` were a traceback
(OpenCV's findChessboardCorners fails an assertion under 15 px a side).
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from lanewarden.cli import main
from lanewarden.config import LanewardenConfig
from lanewarden.perception.detector import MIN_IMAGE_SIDE_PX, LaneDetector
from lanewarden.perception.errors import PerceptionConfigError, PerceptionError

MINIMUM = f"at least {MIN_IMAGE_SIDE_PX}x{MIN_IMAGE_SIDE_PX} px"


def write(path: Path, width: int, height: int) -> str:
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.full((height, width, 3), 128, np.uint8))
    return str(path)


@pytest.mark.parametrize(("width", "height"), [(1, 1), (12, 10), (640, 8)])
def test_the_detector_says_the_size_not_a_config_key(width: int, height: int) -> None:
    detector = LaneDetector(LanewardenConfig().perception)
    with pytest.raises(PerceptionError) as raised:
        detector.describe_ground(None, (width, height))
    assert not isinstance(raised.value, PerceptionConfigError)
    assert str(raised.value) == (f"frame: {width}x{height} is too small for perception "
                                 f"({MINIMUM})")


def cases(folder: Path) -> dict[str, tuple[list[str], str]]:
    """name: (argv, the one line's words after 'lanewarden: error: ')."""
    tiny = write(folder / "tiny.png", 1, 1)
    small = write(folder / "small.png", 12, 10)
    for name in ("survey/lane/a.png", "survey/no-lane/b.png", "frames/f_0.png", "frames/f_1.png"):
        write(folder / name, 1, 1)
    return {
        "detect": (["detect", tiny],
                   f"1 of 1 images not analysed: {tiny}: frame: 1x1 is too small for perception "
                   f"({MINIMUM})"),
        "detect 12x10": (["detect", small],
                         f"1 of 1 images not analysed: {small}: frame: 12x10 is too small for "
                         f"perception ({MINIMUM})"),
        "survey": (["survey", str(folder / "survey"), "--out", str(folder / "s")],
                   f"FOLDER '{folder / 'survey'}': lane/a.png: 1x1 is too small for perception "
                   f"({MINIMUM})"),
        "replay": (["replay", str(folder / "frames"), "--no-video", "--out", str(folder / "r")],
                   f"SOURCE '{folder / 'frames'}': frame 0 (f_0.png): 1x1 is too small for "
                   f"perception ({MINIMUM})"),
        "run": (["run", "--camera", f"{folder}/frames/f_%d.png", "--base", "none", "--duration",
                 "1", "--record", str(folder / "rec")],
                f"--camera {folder}/frames/f_%d.png: its first frame: 1x1 is too small for "
                f"perception ({MINIMUM})"),
        "calibrate": (["calibrate", "--images", tiny, "--pattern", "9x6", "--square", "0.025",
                       "--out", str(folder / "cam.yaml")],
                      "only 0 of 1 views are usable, need calibration.min_views 10 (at least 3 to "
                      "solve at all): 1 x image 1x1 is too small for a chessboard "
                      f"({MINIMUM}); nothing written"),
        "calibrate capture": (["calibrate", "capture", "--camera", f"{folder}/frames/f_%d.png",
                               "--pattern", "9x6", "--out", str(folder / "shots")],
                              f"--camera {folder}/frames/f_%d.png: its first frame: 1x1 is too "
                              f"small for a chessboard ({MINIMUM})"),
    }


CASES = ["detect", "detect 12x10", "survey", "replay", "run", "calibrate", "calibrate capture"]


@pytest.mark.parametrize("name", CASES)
def test_a_tiny_image_is_one_line_naming_it_its_size_and_the_minimum(
        name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv, line = cases(tmp_path)[name]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert err == f"lanewarden: error: {line}\n"
    assert not any((tmp_path / out).exists() for out in ("s", "r", "rec"))  # nothing written
