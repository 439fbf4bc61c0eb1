"""`lanewarden calibrate capture` on a rendered image sequence, and `lanewarden undistort`."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from lanewarden.cli import main
from lanewarden.perception.calibration import CameraCalibration, load_calibration, save_calibration
from lanewarden.perception.undistort_preview import side_by_side
from tests.calibration.conftest import SyntheticViews
from tests.conftest import shared_data


def _write_sequence(folder: Path, frames: list[np.ndarray]) -> str:
    folder.mkdir()
    for i, frame in enumerate(frames):
        assert cv2.imwrite(str(folder / f"frame_{i:03d}.png"), frame)
    return str(folder / "frame_%03d.png")


def test_capture_keeps_only_new_whole_boards_then_calibrates(
    synthetic_views: SyntheticViews, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    images = list(synthetic_views.images)
    wall = np.full((480, 640), 100, np.uint8)
    # A stream: empty frames, the same view held still (3 frames), then the other views.
    frames = [wall, images[0], images[0], images[0], wall, *images[1:], wall]
    source = _write_sequence(tmp_path / "stream", frames)
    shots = tmp_path / "shots"
    code = main(["calibrate", "capture", "--camera", source, "--pattern", "9x6",
                 "--out", str(shots), "--count", "25"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    kept = sorted(shots.glob("view_*.jpg"))
    summary = captured.out.strip().splitlines()[-1]
    assert summary.startswith(f"kept {len(kept)} of 25 views from {len(frames)} frames")
    assert "3 without the whole board" in summary
    assert 12 <= len(kept) <= 15  # the held-still repeats never count twice
    assert "fewer than 25 views kept" in captured.err  # the source ended first
    # The kept views calibrate the camera that rendered them.
    out = tmp_path / "cam.yaml"
    code = main(["calibrate", "--images", str(shots / "*.jpg"), "--pattern", "9x6",
                 "--square", "0.025", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    fx = load_calibration(out).fx
    assert fx == pytest.approx(synthetic_views.camera.focal_px, rel=0.01)


def test_a_numbered_sequence_with_a_gap_says_where_it_stopped(
    synthetic_views: SyntheticViews, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """frame_003.png missing: OpenCV reads 'frame_%03d.png' only up to the gap, and the capture
    had advised showing the board in new places (a new user's left10.jpg was missing)."""
    source = _write_sequence(tmp_path / "stream", list(synthetic_views.images[:6]))
    (tmp_path / "stream" / "frame_003.png").unlink()
    assert main(["calibrate", "capture", "--camera", source, "--pattern", "9x6", "--out",
                 str(tmp_path / "shots")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == (
        f"stopped after 3 frames with fewer than 25 views kept: {tmp_path / 'stream'}"
        "/frame_003.png is missing: a numbered sequence ends at its first gap, so 2 of its 5 "
        "files were not read (give the folder or a glob instead, which read every image in "
        "natural order)")
    # the folder itself reads all five
    assert main(["calibrate", "capture", "--camera", str(tmp_path / "stream"), "--pattern",
                 "9x6", "--out", str(tmp_path / "all")]) == 0
    assert "from 5 frames" in capsys.readouterr().out


def test_capture_stops_at_count_and_a_rerun_adds_only_new_views(
    synthetic_views: SyntheticViews, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = _write_sequence(tmp_path / "stream", list(synthetic_views.images[:6]))
    shots = tmp_path / "new" / "shots"  # missing folders are created
    args = ["calibrate", "capture", "--camera", source, "--pattern", "9x6", "--out", str(shots),
            "--count", "2"]
    assert main(args) == 0
    first = sorted(shots.glob("*.jpg"))
    assert "kept 2 of 2 views from 2 frames" in capsys.readouterr().out
    # The rerun reads the same stream: its first two frames are the views already there.
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "kept 2 of 2 views from 4 frames" in out
    assert "2 too similar to kept views (including the 2 already there)" in out
    assert sorted(p.name for p in shots.glob("*.jpg")) == [
        "view_000.jpg", "view_001.jpg", "view_002.jpg", "view_003.jpg"]
    assert [p.read_bytes() for p in first] == [
        (shots / name).read_bytes() for name in ("view_000.jpg", "view_001.jpg")]


def test_capture_that_keeps_no_view_exits_2_and_says_why(
    synthetic_views: SyntheticViews, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = _write_sequence(tmp_path / "stream", list(synthetic_views.images[:3]))
    shots = tmp_path / "shots"
    args = ["calibrate", "capture", "--camera", source, "--pattern", "9x6", "--out", str(shots)]
    assert main(args) == 0
    kept = sorted(shots.glob("*.jpg"))
    capsys.readouterr()
    assert main(args) == 2  # every frame is a view already there: nothing usable was added
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"kept none of 3 frames in {shots} (0 without the whole board, 3 too similar to " \
           f"kept views (including the {len(kept)} already there)" in err
    assert sorted(shots.glob("*.jpg")) == kept


@pytest.mark.parametrize(
    ("camera", "expected", "code"),
    [
        ("9", "--camera '9': cannot open it as a camera or video", 1),
        ("missing.mp4", "--camera 'missing.mp4': no such file", 2),
    ],
)
def test_capture_cannot_open(tmp_path: Path, capsys: pytest.CaptureFixture[str], camera: str,
                             expected: str, code: int) -> None:
    assert main(["calibrate", "capture", "--camera", camera, "--pattern", "9x6",
                 "--out", str(tmp_path / "shots")]) == code
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and expected in err and "Traceback" not in err


def test_capture_refuses_a_too_small_pattern(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    real = sorted(shared_data("chessboard/opencv-left").glob("left*.jpg"))[1:3]
    source = _write_sequence(tmp_path / "stream", [cv2.imread(str(p)) for p in real])
    assert main(["calibrate", "capture", "--camera", source, "--pattern", "8x6",
                 "--out", str(tmp_path / "shots")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--pattern 8x6" in err and "use --pattern 9x6" in err
    assert not list((tmp_path / "shots").glob("*.jpg"))


def test_capture_with_a_board_counted_by_squares_gets_a_hint(
    synthetic_views: SyntheticViews, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = _write_sequence(tmp_path / "stream", list(synthetic_views.images[:2]))
    assert main(["calibrate", "capture", "--camera", source, "--pattern", "10x7",
                 "--out", str(tmp_path / "shots")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no frame showed the whole board" in err
    assert "use --pattern 9x6" in err


def _calibration_file(synthetic_views: SyntheticViews, path: Path) -> Path:
    cam = synthetic_views.camera
    save_calibration(CameraCalibration(cam.camera_matrix(), cam.distortion(), (640, 480),
                                       rms=0.1), path)
    return path


def test_undistort_writes_images_and_before_after(
    synthetic_views: SyntheticViews, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    calibration = _calibration_file(synthetic_views, tmp_path / "cam.yaml")
    image = synthetic_views.folder / "view_00.png"
    out = tmp_path / "undistorted"
    assert main(["undistort", str(image), "--calibration", str(calibration),
                 "--out", str(out)]) == 0
    undistorted = cv2.imread(str(out / "view_00_undistorted.png"), cv2.IMREAD_UNCHANGED)
    compare = cv2.imread(str(out / "view_00_compare.png"))
    assert undistorted.shape == (480, 640)
    assert compare.shape == (480, 640 * 2 + 8, 3)
    assert not np.array_equal(undistorted, synthetic_views.images[0])
    assert "wrote" in capsys.readouterr().out


def test_undistort_bad_inputs(synthetic_views: SyntheticViews, tmp_path: Path,
                              capsys: pytest.CaptureFixture[str]) -> None:
    calibration = _calibration_file(synthetic_views, tmp_path / "cam.yaml")
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((240, 320), np.uint8))
    junk = tmp_path / "junk.png"
    junk.write_text("junk")
    code = main(["undistort", str(small), str(junk), str(synthetic_views.folder / "view_01.png"),
                 "--calibration", str(calibration), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert "2 of 3 images not undistorted" in err
    assert "small.png: image is 320x240, the calibration" in err and "is for 640x480" in err
    assert "junk.png: not a readable image" in err
    assert (tmp_path / "out" / "view_01_compare.png").exists()  # the good one is still done
    code = main(["undistort", str(small), "--calibration", str(tmp_path / "none.yaml"),
                 "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and (f"Invalid value for '--calibration': Path '{tmp_path / 'none.yaml'}' "
                          "does not exist; expected a calibration file") in err


def test_side_by_side_draws_the_same_lines_on_both() -> None:
    before = np.zeros((60, 90), np.uint8)
    picture = side_by_side(before, before.copy())
    left, right = picture[:, :90], picture[:, 98:]
    assert picture.shape == (60, 188, 3)
    # Identical inputs -> identical halves below the labels, and the lines are drawn.
    np.testing.assert_array_equal(left[30:], right[30:])
    assert left[30:].max() > 0
    with pytest.raises(ValueError, match="sizes differ"):
        side_by_side(before, np.zeros((10, 10), np.uint8))
