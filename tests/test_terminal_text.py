"""Text from input files reaches the terminal as one printable line: a name or key holding ESC,
BEL or a newline is shown with escapes (an attacker's review: a config key set the terminal's
title and forged a second 'lanewarden: error:' line; so did a calibration's ground_method in the
ground model's line and an image's file name in `detect`)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from lanewarden.cli import main
from lanewarden.perception.calibration import load_calibration, save_calibration
from lanewarden.scenarios.camera import CameraModel

FORGED = "\x1b]0;PWNED\x07\nlanewarden: error: forged"
SHOWN = "\\x1b]0;PWNED\\x07\\nlanewarden: error: forged"


def test_a_config_key_of_control_characters_is_shown_escaped_and_cut(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    config = tmp_path / "c.yaml"
    config.write_text('perception:\n  "\\e]0;PWNED\\a\\nlanewarden: error: forged": 1\n')
    assert main(["config", "show", "--config", str(config)]) == 2
    assert capsys.readouterr().err == (
        f"lanewarden: error: {config}: unknown key 'perception.{SHOWN}' (check the spelling; "
        "`lanewarden config show` lists every key)\n")
    config.write_text("perception:\n  ? " + "k" * 900_000 + "\n  : 1\n")
    assert main(["config", "show", "--config", str(config)]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert len(line) < 400 and "kkk…'" in line


def test_a_calibrations_ground_method_is_read_as_one_printable_line(tmp_path: Path) -> None:
    calibration = CameraModel().calibration()
    assert calibration.ground is not None
    path = tmp_path / "cal.yaml"
    save_calibration(replace(calibration, ground=replace(calibration.ground, method=FORGED)),
                     path)
    ground = load_calibration(path).ground
    # (OpenCV's writer keeps some of the control characters and mangles others: what is read
    # back holds control characters all the same, and is shown escaped)
    assert ground is not None and ground.method is not None
    assert ground.method.isprintable() and "PWNED" in ground.method, ground.method


def test_detect_names_an_image_file_in_one_printable_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import cv2

    good = tmp_path / "a\nlanewarden: error: forged.png"
    cv2.imwrite(str(good), np.full((240, 320, 3), 120, np.uint8))
    bad = tmp_path / "b\nlanewarden: error: forged.png"
    bad.write_bytes(b"x")
    assert main(["detect", str(good), str(bad)]) == 2
    captured = capsys.readouterr()
    [result] = [line for line in captured.out.splitlines() if "forged" in line]
    assert result.startswith(f"{tmp_path}/a\\nlanewarden: error: forged.png: none")
    assert captured.err.splitlines()[-1] == (
        f"lanewarden: error: 1 of 2 images not analysed: {tmp_path}/b\\nlanewarden: error: "
        "forged.png: not a readable image")
