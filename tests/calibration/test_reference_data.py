"""OpenCV's own calibration views (left01..left14): we match OpenCV's reference result."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from lanewarden.cli import main
from lanewarden.perception.calibration import load_calibration
from lanewarden.perception.calibration_config import CalibrationConfig
from lanewarden.perception.chessboard import ChessboardPattern, detect_view
from lanewarden.perception.chessboard_calibration import calibrate_views, gate_failures
from tests.conftest import shared_data

# From OpenCV's modules/python/test/test_calibration.py (see ../shared/data/README.md).
REF_RMS = 0.196334638034
REF_K = np.array([[532.80992189, 0.0, 342.4952186], [0.0, 532.93346422, 233.8879292],
                  [0.0, 0.0, 1.0]])
REF_D = np.array([-0.281325576, 0.0291130406, 0.00121234330, -0.000140825372, 0.154865844])


def _within_opencv_tolerances(rms: float, k: np.ndarray, d: np.ndarray) -> None:
    assert abs(rms - REF_RMS) < 0.01
    assert float(np.abs(k - REF_K).sum()) < 10.0
    assert float(np.abs(np.asarray(d).ravel() - REF_D).sum()) < 0.05


def test_reference_procedure_matches_opencv() -> None:
    """OpenCV's path: findChessboardCorners, cornerSubPix((5, 5), eps 0.1, 30), flags=0."""
    folder = shared_data("chessboard/opencv-left")
    files = sorted(folder.glob("left*.jpg"))
    assert len(files) == 13
    config = CalibrationConfig(subpix_window_px=5, subpix_epsilon_px=0.1, subpix_max_iterations=30)
    pattern = ChessboardPattern(9, 6)
    views = [detect_view(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE), pattern, config, name=f.name)
             for f in files]
    assert all(v.accepted for v in views), [v.rejection for v in views if not v.accepted]
    run = calibrate_views(views, pattern, 1.0, (640, 480), config, flags=0)
    _within_opencv_tolerances(run.rms, run.calibration.camera_matrix, run.calibration.dist_coeffs)
    assert run.calibration.views_used == 13
    assert len(run.per_view) == 13 and not run.outliers
    # Standard deviations are small and positive for every estimated intrinsic.
    assert 0 < run.std_deviations["fx"] < 2.0 and 0 < run.std_deviations["k1"] < 0.05
    assert gate_failures(run, config) == []


def test_cli_json_on_reference_data(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = shared_data("chessboard/opencv-left")
    out = tmp_path / "left.yaml"
    code = main(["calibrate", "--images", str(folder / "*.jpg"), "--pattern", "9x6",
                 "--square", "1.0", "--out", str(out), "--json", "--ros"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    result = json.loads(captured.out.strip().splitlines()[-1])
    for key in ("rms", "camera_matrix", "dist_coeffs", "image_size", "views_used",
                "views_rejected", "per_view_error"):
        assert key in result
    assert result["image_size"] == [640, 480]
    assert result["views_used"] == 13 and result["views_rejected"] == []
    assert {e["file"] for e in result["per_view_error"]} == {f.name for f in
                                                             folder.glob("left*.jpg")}
    _within_opencv_tolerances(result["rms"], np.array(result["camera_matrix"]),
                              np.array(result["dist_coeffs"]))
    saved = load_calibration(out)
    np.testing.assert_allclose(saved.camera_matrix, result["camera_matrix"], rtol=1e-9)
    assert saved.rms == pytest.approx(result["rms"])
    assert saved.pattern == "9x6 chessboard, 1 m squares" and saved.views_used == 13
    assert saved.date is not None and saved.date.startswith("20")
    ros = load_calibration(tmp_path / "left.ros.yaml")
    np.testing.assert_allclose(ros.camera_matrix, saved.camera_matrix, rtol=1e-12)
    text = (tmp_path / "left.ros.yaml").read_text()
    for key in ("camera_name: left", "distortion_model: plumb_bob", "rectification_matrix:",
                "projection_matrix:"):
        assert key in text


def test_human_report_on_reference_data(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    folder = shared_data("chessboard/opencv-left")
    code = main(["calibrate", "--images", str(folder), "--pattern", "9x6", "--square", "0.025",
                 "--out", str(tmp_path / "c.yaml")])
    out = capsys.readouterr().out
    assert code == 0
    assert "RMS reprojection error: 0.19" in out
    assert "left08.jpg" in out and "Coverage: corners in 78% of the image" in out
    assert "few corners in the top-left region" in out
    assert "fx =" in out and "+-" in out and "k1 =" in out
    assert "Quality gates: passed" in out


def test_too_small_pattern_is_caught(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """OpenCV finds an 8x6 grid inside the 9x6 board; we must not calibrate on it silently."""
    folder = shared_data("chessboard/opencv-left")
    code = main(["calibrate", "--images", str(folder / "*.jpg"), "--pattern", "8x6",
                 "--square", "1", "--out", str(tmp_path / "c.yaml")])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "--pattern 8x6" in err and "use --pattern 9x6" in err
    assert not (tmp_path / "c.yaml").exists()
