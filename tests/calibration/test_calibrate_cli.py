"""`lanewarden calibrate`: results, quality gates and bad inputs (one line, exit code, no crash)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from lanewarden.cli import main
from lanewarden.perception.calibration import load_calibration
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.chessboard import ChessboardRenderer
from tests.calibration.conftest import SyntheticViews


def _run(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(["calibrate", *args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def _one_error_line(err: str) -> str:
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("lanewarden: error: ")
    return lines[0]


def _copy_views(synthetic: SyntheticViews, folder: Path, count: int) -> None:
    folder.mkdir(exist_ok=True)
    for path in sorted(synthetic.folder.glob("view_*.png"))[:count]:
        shutil.copy(path, folder / path.name)


def test_synthetic_views_calibrate_and_write(
    synthetic_views: SyntheticViews, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "new" / "folder" / "cam.yaml"  # missing folders are created, as elsewhere
    code, stdout, err = _run(capsys, "--images", str(synthetic_views.folder / "*.png"),
                             "--pattern", "9x6", "--square", "0.025", "--out", str(out), "--ros")
    assert code == 0, err
    assert "Quality gates: passed" in stdout and f"Wrote {out}" in stdout
    saved = load_calibration(out)
    assert saved.fx == pytest.approx(synthetic_views.camera.focal_px, rel=0.01)
    assert saved.views_used == 15 and saved.pattern == "9x6 chessboard, 0.025 m squares"
    assert (out.parent / "cam.ros.yaml").exists()


def test_no_file_matches(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = _run(capsys, "--images", str(tmp_path / "*.jpg"), "--pattern", "9x6",
                        "--square", "0.025", "--out", str(tmp_path / "c.yaml"))
    assert code == 2
    line = _one_error_line(err)
    assert f"--images '{tmp_path / '*.jpg'}': no files match" in line


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--pattern", "9by6"], "Invalid value for '--pattern': '9by6' is not COLSxROWS"),
        (["--pattern", "1x6"], "expected at least 3x3 inner corners"),
        (["--square", "0"], "Invalid value for '--square': 0.0 m: expected a positive"),
        (["--square", "nan"], "Invalid value for '--square': nan m"),
        (["--square", "big"], "Invalid value for '--square'"),
    ],
)
def test_bad_flag_values(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                         args: list[str], expected: str) -> None:
    base = {"--images": str(tmp_path / "*.png"), "--pattern": "9x6", "--square": "0.025",
            "--out": str(tmp_path / "c.yaml")}
    base.update(dict(zip(args[::2], args[1::2], strict=True)))
    code, _, err = _run(capsys, *[item for pair in base.items() for item in pair])
    assert code == 2
    assert expected in _one_error_line(err)


def test_missing_flags_and_unquoted_glob(tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = _run(capsys, "--pattern", "9x6")
    assert code == 2
    assert "missing --images, --square, --out" in _one_error_line(err)
    code, _, err = _run(capsys, "--images", "a.png", "b.png", "--pattern", "9x6")
    assert code == 2
    assert "unexpected argument 'b.png': quote the --images glob" in _one_error_line(err)
    code, _, err = _run(capsys, "captur", "--pattern", "9x6")
    assert code == 2
    assert "No such command 'captur'; did you mean 'capture'?" in _one_error_line(err)


def test_unreadable_and_mixed_size_views_are_rejected_with_reasons(
    synthetic_views: SyntheticViews, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "shots"
    _copy_views(synthetic_views, folder, 15)
    (folder / "notes.png").write_text("not an image")
    (folder / "empty.png").write_bytes(b"")
    small = cv2.resize(synthetic_views.images[0], (320, 240))
    cv2.imwrite(str(folder / "small.png"), small)
    cv2.imwrite(str(folder / "wall.png"), np.full((480, 640), 90, np.uint8))
    code, stdout, err = _run(capsys, "--images", str(folder / "*.png"), "--pattern", "9x6",
                             "--square", "0.025", "--out", str(tmp_path / "c.yaml"), "--json")
    assert code == 0, err
    result = json.loads(stdout.strip().splitlines()[-1])
    reasons = {item["file"]: item["reason"] for item in result["views_rejected"]}
    assert reasons == {
        "notes.png": "not a readable image",
        "empty.png": "empty file, not an image",
        "small.png": "image size 320x240 differs from 640x480 (the size of most views)",
        "wall.png": "board not found (looked for 9x6 inner corners, whole board)",
    }
    assert result["views_used"] == 15


def test_no_board_anywhere_fails_the_gate(tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    for i in range(4):
        cv2.imwrite(str(tmp_path / f"wall_{i}.png"), np.full((120, 160), 60 + 40 * i, np.uint8))
    code, stdout, err = _run(capsys, "--images", str(tmp_path / "*.png"), "--pattern", "9x6",
                             "--square", "0.025", "--out", str(tmp_path / "c.yaml"), "--json")
    assert code == 2
    line = _one_error_line(err)
    assert "only 0 of 4 views are usable, need calibration.min_views 10" in line
    assert "4 x board not found (looked for 9x6 inner corners, whole board)" in line
    result = json.loads(stdout.strip().splitlines()[-1])
    assert result["rms"] is None and result["views_used"] == 0
    assert len(result["views_rejected"]) == 4
    assert not (tmp_path / "c.yaml").exists()


def test_board_counted_by_squares_gets_a_hint(
    synthetic_views: SyntheticViews, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    _copy_views(synthetic_views, tmp_path / "shots", 3)
    code, _, err = _run(capsys, "--images", str(tmp_path / "shots"), "--pattern", "10x7",
                        "--square", "0.025", "--out", str(tmp_path / "c.yaml"))
    assert code == 2
    line = _one_error_line(err)
    assert "board not found (looked for 10x7" in line and "try --pattern 9x6" in line


def test_failed_gates_print_json_then_exit_2(
    synthetic_views: SyntheticViews, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "strict.yaml"
    config.write_text("calibration:\n  max_rms_px: 0.01\n  min_views: 12\n")
    _copy_views(synthetic_views, tmp_path / "shots", 8)
    out = tmp_path / "c.yaml"
    code, stdout, err = _run(capsys, "--images", str(tmp_path / "shots" / "*.png"),
                             "--pattern", "9x6", "--square", "0.025", "--out", str(out),
                             "--json", "--config", str(config))
    assert code == 2
    line = _one_error_line(err)
    assert "calibration fails 2 quality gate(s): rms" in line
    assert "exceeds calibration.max_rms_px 0.01 px" in line
    assert "views_used 8 is below calibration.min_views 12" in line
    result = json.loads(stdout.strip().splitlines()[-1])
    assert result["quality_gates"]["passed"] is False
    assert len(result["per_view_error"]) == 8 and result["calibration_file"] is None
    assert not out.exists()
    # Without --json the report still shows why.
    code, stdout, _ = _run(capsys, "--images", str(tmp_path / "shots" / "*.png"),
                           "--pattern", "9x6", "--square", "0.025", "--out", str(out),
                           "--config", str(config))
    assert code == 2 and "Quality gates: FAILED" in stdout


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("calibration:\n  max_rms: 2\n", "unknown key 'calibration.max_rms'"),
        ("calibration:\n  min_views: 1\n",
         "calibration.min_views = 1: expected an integer with 3 <= value <= 1000"),
        ("calibration:\n  max_rms_px: -1\n", "calibration.max_rms_px = -1"),
    ],
)
def test_bad_config_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                text: str, expected: str) -> None:
    config = tmp_path / "bad.yaml"
    config.write_text(text)
    code, _, err = _run(capsys, "--images", "x", "--pattern", "9x6", "--square", "1",
                        "--out", str(tmp_path / "c.yaml"), "--config", str(config))
    assert code == 2
    assert expected in _one_error_line(err)


def test_outlier_view_flagged_then_dropped(
    synthetic_views: SyntheticViews, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "shots"
    _copy_views(synthetic_views, folder, 15)
    # view_01 seen through a different lens: it cannot agree with the other fourteen.
    odd_lens = ChessboardRenderer(CameraModel(dist_coeffs=(-0.3, 0.05, 0.0, 0.0, 0.0),
                                              hfov_deg=60.0))
    cv2.imwrite(str(folder / "view_01.png"), odd_lens.render(synthetic_views.poses[1]))
    args = ["--images", str(folder / "*.png"), "--pattern", "9x6", "--square", "0.025",
            "--out", str(tmp_path / "c.yaml")]
    code, stdout, err = _run(capsys, *args)
    assert code == 0, err
    flagged = [line for line in stdout.splitlines() if "<- outlier" in line]
    assert len(flagged) == 1 and "view_01.png" in flagged[0]
    assert "--drop-outliers re-calibrates without them" in stdout
    code, stdout, err = _run(capsys, *args, "--drop-outliers", "--json")
    assert code == 0, err
    result = json.loads(stdout.strip().splitlines()[-1])
    assert result["views_used"] == 14
    assert {"file": "view_01.png", "reason": "outlier, dropped by --drop-outliers"} in result[
        "views_rejected"]
    assert not any(item["outlier"] for item in result["per_view_error"])
    assert result["rms"] < result["rms_before_drop"] / 2
