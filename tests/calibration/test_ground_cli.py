"""`lanewarden calibrate ground`: from the mount and from a floor chessboard photo, what it
writes, what it prints, and what it refuses (one line, exit 2, nothing written)."""

from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from lanewarden.perception.calibration import load_calibration, save_calibration
from lanewarden.perception.ground import CameraPose
from lanewarden.scenarios.camera import CameraModel
from tests.calibration.floor_board import FloorPhoto, floor_photo
from tests.calibration.test_calibrate_cli import _one_error_line
from tests.calibration.test_calibrate_cli import _run as run_calibrate
from tests.conftest import shared_data

JSON_KEYS = {"height_m", "pitch_deg", "roll_deg", "reprojection_error_m", "horizon_y_px",
             "mm_per_px_at_look_ahead", "bend_slope_sums", "calibration_file", "check_image"}
#: The lecture's camera (low and steep), as in the `lecture` scenario.
CAMERA = CameraModel(height_m=0.22, pitch_down_deg=50.0, hfov_deg=62.0, forward_offset_m=0.12)


def _run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    return run_calibrate(capsys, "ground", *args)


@pytest.fixture()
def intrinsics(tmp_path: Path) -> Path:
    path = tmp_path / "camera.yaml"
    save_calibration(replace(CAMERA.calibration(), ground=None), path)
    return path


@pytest.fixture(scope="module")
def photo(tmp_path_factory: pytest.TempPathFactory) -> tuple[FloorPhoto, Path]:
    shot = floor_photo(CAMERA, np.random.default_rng(3))
    path = tmp_path_factory.mktemp("floor") / "floor.png"
    assert cv2.imwrite(str(path), shot.image)
    return shot, path


def test_from_the_mount_round_trips_through_the_file(
        intrinsics: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "grounded.yaml"
    code, stdout, err = _run(capsys, "--calibration", str(intrinsics), "--height-m", "0.26",
                             "--pitch-deg", "40", "--roll-deg", "1.5", "--forward-m", "0.12",
                             "--out", str(out), "--json")
    assert code == 0, err
    payload = json.loads(stdout.strip().splitlines()[-1])
    assert JSON_KEYS <= set(payload)
    assert (payload["height_m"], payload["pitch_deg"], payload["roll_deg"]) == (0.26, 40.0, 1.5)
    assert payload["reprojection_error_m"] is None  # nothing was measured
    assert [b["radius_m"] for b in payload["bend_slope_sums"]] == [0.5, 1.0]
    ground = load_calibration(out).ground
    assert ground is not None
    assert ground.pose == CameraPose(height_m=0.26, pitch_deg=40.0, roll_deg=1.5, forward_m=0.12)
    assert ground.method == "from the mount (measured)"
    picture = cv2.imread(str(tmp_path / "grounded.ground-check.png"))
    assert picture is not None and picture.shape == (480, 640, 3)
    assert payload["check_image"] == str(tmp_path / "grounded.ground-check.png")


def test_a_missing_output_folder_is_created_as_for_every_out(
        intrinsics: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`--out` in a folder that does not exist yet: created with its parents, as `calibrate`
    and every other --out does (it had been refused: "folder ... does not exist")."""
    out = tmp_path / "robot" / "camera" / "grounded.yaml"
    code, _, err = _run(capsys, "--calibration", str(intrinsics), "--height-m", "0.26",
                        "--pitch-deg", "40", "--out", str(out))
    assert code == 0, err
    assert load_calibration(out).ground is not None
    assert (out.parent / "grounded.ground-check.png").is_file()
    # a refused pose still writes nothing, and creates no folder
    refused = tmp_path / "other" / "grounded.yaml"
    code, _, err = _run(capsys, "--calibration", str(intrinsics), "--height-m", "0.3",
                        "--pitch-deg", "-40", "--out", str(refused))
    assert code == 2 and not refused.parent.exists()


def test_a_check_picture_that_cannot_be_written_leaves_the_calibration_as_it_was(
        intrinsics: Path, small_disk: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """On a full disk the calibration had been rewritten, then the picture failed (exit 2):
    the picture now goes first, and a file that cannot be written is a runtime failure (1).
    A real full disk: a 400 KiB file system, filled but for a few kilobytes."""
    before = intrinsics.read_bytes()
    disk = os.statvfs(small_disk)
    (small_disk / "filler").write_bytes(b"\0" * (disk.f_bavail * disk.f_frsize - 8192))
    code, _, err = _run(capsys, "--calibration", str(intrinsics), "--height-m", "0.26",
                        "--pitch-deg", "40", "--out", str(intrinsics), "--check-image",
                        str(small_disk / "check.png"))
    assert code == 1, err
    assert ("cannot write the picture (No space left on device); nothing written to "
            f"{intrinsics}") in err
    assert intrinsics.read_bytes() == before
    assert sorted(p.name for p in small_disk.iterdir()) == ["filler"]  # nothing half-written


def test_from_the_mount_prints_what_it_means(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # the simulator's default camera (70 deg HFOV: f = 457.0 px), mounted as by default
    intrinsics = tmp_path / "default.yaml"
    save_calibration(replace(CameraModel().calibration(), ground=None), intrinsics)
    out = tmp_path / "grounded.yaml"
    code, stdout, err = _run(capsys, "--calibration", str(intrinsics), "--height-m", "0.4",
                             "--pitch-deg", "35", "--forward-m", "0.15", "--out", str(out),
                             "--ros", "--check-image", str(tmp_path / "check.png"))
    assert code == 0, err
    assert "camera: h 0.400 m, pitch 35.0°, 0.150 m ahead of the robot's centre" in stdout
    assert "horizon: row -80 at the image centre (above the image)" in stdout
    assert "look-ahead: row 192 sees the floor 0.87 m ahead" in stdout
    assert "strongest slope sum driving through a 90° bend" in stdout
    assert "R 0.5 m: right -11.0, left +11.0; R 1 m: right -10.9, left +10.9" in stdout
    assert (tmp_path / "check.png").is_file() and (tmp_path / "grounded.ros.yaml").is_file()
    assert load_calibration(tmp_path / "grounded.ros.yaml").ground is not None
    assert "warning" not in stdout  # perception works with this camera as configured


def test_a_pose_perception_cannot_use_with_the_config_is_written_with_a_warning(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Pitched 75° down the camera sees only the floor near the robot, not a 0.87 m
    look-ahead set in the config: the pose may well be right, so it is written, and the output
    says what detect and run will say about it. (With no look-ahead set, `auto`, the detector
    picks one this camera sees.)"""
    intrinsics = tmp_path / "default.yaml"
    save_calibration(replace(CameraModel().calibration(), ground=None), intrinsics)
    out = tmp_path / "grounded.yaml"
    config = tmp_path / "far.yaml"
    config.write_text("perception:\n  edges: {look_ahead_m: 0.87}\n")
    code, stdout, err = _run(capsys, "--calibration", str(intrinsics), "--height-m", "0.26",
                             "--pitch-deg", "75", "--out", str(out), "--config", str(config))
    assert code == 0, err
    warning = next(line for line in stdout.splitlines() if "warning" in line)
    assert warning.startswith("  warning: with this config `detect` and `run` will refuse this "
                              "camera: perception.edges.look_ahead_m = 0.87: outside the "
                              "camera's view at 640x480")
    assert load_calibration(out).ground is not None


def test_a_mount_that_sees_no_floor_is_refused(
        intrinsics: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "grounded.yaml"
    code, _, err = _run(capsys, "--calibration", str(intrinsics), "--height-m", "0.3",
                        "--pitch-deg", "-40", "--out", str(out))
    assert code == 2
    assert "the horizon is below the image: this camera sees no floor" in _one_error_line(err)
    assert not out.exists() and not (tmp_path / "grounded.ground-check.png").exists()


def test_from_a_floor_chessboard(photo: tuple[FloorPhoto, Path], intrinsics: Path,
                                 tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    shot, image = photo
    out = tmp_path / "grounded.yaml"
    code, stdout, err = _run(
        capsys, "--calibration", str(intrinsics), "--image", str(image), "--pattern", "7x5",
        "--square", f"{shot.square_m}", "--board-center-m",
        f"{shot.centre_xy[0]},{shot.centre_xy[1]}", "--out", str(out), "--json")
    assert code == 0, err
    payload = json.loads(stdout.strip().splitlines()[-1])
    assert JSON_KEYS <= set(payload) and payload["problems"] == []
    assert payload["height_m"] == pytest.approx(0.22, abs=0.005)
    assert payload["pitch_deg"] == pytest.approx(50.0, abs=0.5)
    assert 0 < payload["reprojection_error_m"] < 0.002
    ground = load_calibration(out).ground
    assert ground is not None and ground.reprojection_error_m == pytest.approx(
        payload["reprojection_error_m"], abs=1e-5)
    assert ground.method is not None and ground.method.startswith("from a floor chessboard (7x5")
    assert cv2.imread(str(tmp_path / "grounded.ground-check.png")) is not None


def test_an_error_above_the_gate_exits_2_and_writes_nothing(
        photo: tuple[FloorPhoto, Path], intrinsics: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    shot, image = photo
    strict = tmp_path / "strict.yaml"
    strict.write_text("calibration:\n  max_ground_error_m: 0.00001\n")
    out = tmp_path / "grounded.yaml"
    code, stdout, err = _run(
        capsys, "--calibration", str(intrinsics), "--image", str(image), "--pattern", "7x5",
        "--square", f"{shot.square_m}", "--board-center-m",
        f"{shot.centre_xy[0]},{shot.centre_xy[1]}", "--out", str(out), "--config", str(strict),
        "--json")
    assert code == 2
    line = _one_error_line(err)
    assert "implausible result: reprojection error on the floor" in line
    assert f"nothing written to {out}" in line
    assert json.loads(stdout.strip().splitlines()[-1])["calibration_file"] is None
    assert sorted(p.name for p in tmp_path.iterdir()) == ["camera.yaml", "strict.yaml"]


def test_a_pattern_one_column_short_is_refused(
        intrinsics: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """OpenCV's left05.jpg shows a 9x6 inner-corner board, and OpenCV also finds an 8x6 grid
    inside it: the pose solved from that part of a board put the camera half a square off
    (a new user measured 0.164 m for a mount 0.150 m ahead, with no warning). Refused, as
    `calibrate` refuses it."""
    image = shared_data("chessboard/opencv-left/left05.jpg")
    pattern = "8x6"
    out = tmp_path / "grounded.yaml"
    code, _, err = _run(
        capsys, "--calibration", str(intrinsics), "--image", str(image), "--pattern", pattern,
        "--square", "0.025", "--board-center-m", "0.6,0", "--out", str(out))
    assert code == 2
    assert _one_error_line(err) == (
        f"lanewarden: error: --pattern {pattern}: '{image}' shows a board with 9x6 inner corners; "
        "use --pattern 9x6 (count ALL inner corners: squares minus one per side); nothing "
        "written")
    assert not out.exists()


def test_an_upside_down_photo_exits_2(photo: tuple[FloorPhoto, Path], intrinsics: Path,
                                      tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # a camera mounted upside down, its photo not turned: the floor would lie above the horizon
    shot, _ = photo
    image = tmp_path / "upside-down.png"
    assert cv2.imwrite(str(image), cv2.flip(shot.image, -1))
    out = tmp_path / "grounded.yaml"
    code, _, err = _run(capsys, "--calibration", str(intrinsics), "--image", str(image),
                        "--pattern", "7x5", "--square", f"{shot.square_m}", "--board-center-m",
                        f"{shot.centre_xy[0]},{shot.centre_xy[1]}", "--out", str(out))
    assert code == 2
    line = _one_error_line(err)
    assert "implausible result: the solved horizon (row" in line
    assert "lies below the board" in line and "is the photo upside down" in line
    assert not out.exists() and not (tmp_path / "grounded.ground-check.png").exists()


@pytest.mark.parametrize(("args", "expected"), [
    ([], "calibrate ground: say how: usage: lanewarden calibrate ground"),
    (["--height-m", "0.3"], "missing --pitch-deg"),
    (["--height-m", "0.3", "--pitch-deg", "30", "--pattern", "7x5"],
     "--height-m, --pitch-deg (mount) and --pattern (chessboard) are two different ways"),
    (["--pattern", "7x5", "--square", "0.02"], "missing --image, --board-center-m"),
    (["--height-m", "-0.3", "--pitch-deg", "30"], "--height-m -0.3: expected a height above"),
    (["--height-m", "nan", "--pitch-deg", "30"], "Invalid value for '--height-m'"),
    (["--board-center-m", "0.5"], "Invalid value for '--board-center-m': '0.5': expected X,Y"),
    (["--square", "0"], "Invalid value for '--square'"),
    # a photo not taken yet: what it is and how to take one (an instructor's review)
    (["--pattern", "9x6", "--square", "0.03", "--board-center-m", "0.55,0", "--image",
      "floor.jpg"], "--image 'floor.jpg': no such file; expected a photo from the robot's "
     "camera of the chessboard lying flat on the floor (lanewarden calibrate capture --camera 0 "
     "--pattern COLSxROWS --count 1 --out DIR takes one)"),
])
def test_bad_invocations_are_one_line_and_exit_2(
        intrinsics: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str],
        expected: str) -> None:
    code, _, err = _run(capsys, "--calibration", str(intrinsics), "--out",
                        str(tmp_path / "o.yaml"), *args)
    assert code == 2
    assert expected in _one_error_line(err)
    assert not (tmp_path / "o.yaml").exists()


def test_a_photo_of_another_size_or_without_the_board(
        intrinsics: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    small = tmp_path / "small.png"
    assert cv2.imwrite(str(small), np.full((240, 320), 128, np.uint8))
    flags = ["--calibration", str(intrinsics), "--pattern", "7x5", "--square", "0.02",
             "--board-center-m", "0.4,0", "--out", str(tmp_path / "o.yaml")]
    code, _, err = _run(capsys, *flags, "--image", str(small))
    assert code == 2
    assert "image is 320x240, the calibration is for 640x480" in _one_error_line(err)
    blank = tmp_path / "blank.png"
    assert cv2.imwrite(str(blank), np.full((480, 640), 128, np.uint8))
    code, _, err = _run(capsys, *flags, "--image", str(blank))
    assert code == 2
    assert "board not found" in _one_error_line(err)


def test_the_summary_says_what_a_pose_that_sees_no_floor_shows() -> None:
    """A horizon below the image is not 'inside the image', a look-ahead with no row is not
    'row nan', and bends where neither tape is seen do not end with the lecture's turn rule
    (OpenCV's left01/left02.jpg held up in a room printed all three)."""
    from lanewarden.commands.calibrate_ground import _summary_lines
    from lanewarden.perception.ground_report import BendSlopeSums, GroundSummary

    nan = float("nan")
    summary = GroundSummary(
        horizon_y_px=868.0, look_ahead_y_px=nan, look_ahead_m=nan,
        mm_per_px_across_at_look_ahead=nan, mm_per_px_along_at_look_ahead=nan,
        bends=(BendSlopeSums(0.5, None, None), BendSlopeSums(1.0, None, None)),
        lane_width_m=0.6, tape_width_m=0.048)
    lines = _summary_lines(CameraPose(height_m=0.2, pitch_deg=48.9), "from the mount", summary,
                           None, 0.01, 480)
    assert lines[2:] == [
        "  horizon: row 868 at the image centre (below the image)",
        "  look-ahead: no row of the image sees the floor at a distance perception can use",
        "  strongest slope sum driving through a 90° bend (lane 0.6 m, tape 48 mm): R 0.5 m: "
        "right not seen, left not seen; R 1 m: right not seen, left not seen: this camera sees "
        "neither tape through these bends"]
