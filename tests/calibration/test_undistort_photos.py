"""`undistort` sees a photo as `calibrate` and `detect` see it: upright as its EXIF orientation
says.

It had decoded photos with IMREAD_UNCHANGED, which ignores the EXIF orientation: a phone's photo
held upright (stored 640x480, EXIF "rotate 90") was 640x480 to `undistort`, the size its header
gives, and 480x640 to `calibrate` (and `detect`, `survey`). So the calibration `calibrate` made
from such photos, for 480x640, refused the very photos it was made from ("image is 640x480, the
calibration ... is for 480x640"), and a calibration for 640x480 undistorted them lying on
their side.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from PIL import Image

from lanewarden.cli import main
from lanewarden.image_files import read_image
from lanewarden.perception.calibration import CameraCalibration, save_calibration


def upright_photo(path: Path) -> Path:
    """A JPEG stored 640x480 whose EXIF orientation says 'rotate 90 degrees clockwise to show'."""
    stored = np.zeros((480, 640, 3), np.uint8)
    stored[:, :320] = 200  # the left half light: after turning, the top half
    exif = Image.Exif()
    exif[0x0112] = 6
    Image.fromarray(stored).save(path, exif=exif.tobytes())
    return path


def calibration_for(path: Path, width: int, height: int) -> Path:
    k = np.array([[500.0, 0.0, width / 2], [0.0, 500.0, height / 2], [0.0, 0.0, 1.0]])
    save_calibration(CameraCalibration(k, np.zeros(5), (width, height)), path)
    return path


def test_a_photo_turned_by_its_exif_orientation_is_undistorted_upright(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    photo = upright_photo(tmp_path / "phone.jpg")
    seen_by_calibrate, _ = read_image(photo, cv2.IMREAD_GRAYSCALE)
    assert seen_by_calibrate is not None and seen_by_calibrate.shape == (640, 480)
    portrait = calibration_for(tmp_path / "portrait.yaml", 480, 640)
    assert main(["undistort", str(photo), "--calibration", str(portrait), "--out",
                 str(tmp_path / "out")]) == 0, capsys.readouterr().err
    undistorted = cv2.imread(str(tmp_path / "out" / "phone_undistorted.jpg"))
    assert undistorted.shape == (640, 480, 3)
    assert undistorted[:100, 200:280].mean() > 150 > undistorted[-100:, 200:280].mean()


def test_the_size_refused_is_the_size_as_turned(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    photo = upright_photo(tmp_path / "phone.jpg")
    landscape = calibration_for(tmp_path / "landscape.yaml", 640, 480)
    assert main(["undistort", str(photo), "--calibration", str(landscape), "--out",
                 str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err == (
        f"lanewarden: error: 1 of 1 images not undistorted: {photo}: image is 480x640 (turned "
        f"upright by its EXIF orientation), the calibration {landscape} is for 640x480\n")


def test_a_gray_photo_stays_gray(tmp_path: Path) -> None:
    photo = tmp_path / "gray.png"
    cv2.imwrite(str(photo), np.full((480, 640), 90, np.uint8))
    landscape = calibration_for(tmp_path / "landscape.yaml", 640, 480)
    assert main(["undistort", str(photo), "--calibration", str(landscape), "--out",
                 str(tmp_path / "out")]) == 0
    written = cv2.imread(str(tmp_path / "out" / "gray_undistorted.png"), cv2.IMREAD_UNCHANGED)
    assert written.shape == (480, 640)
