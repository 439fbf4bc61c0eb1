"""`lanewarden sim` and `lanewarden demo` as a user runs them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lanewarden.cli import main

SHORT = """\
name: short
lane:
  segments:
    - straight_m: 3.0
run:
  max_time_s: 3
config:
  simulation: {width_px: 320, height_px: 240, texture_mm_per_px: 5.0}
expect:
  supervised:
    halted: false
"""


def video_info(path: Path) -> dict[str, object]:
    import imageio_ffmpeg

    frames = imageio_ffmpeg.read_frames(str(path))
    info = dict(next(frames))
    frames.close()
    return info


def test_unknown_scenario_is_one_line_listing_the_names(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "--scenario", "nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("lanewarden: error: --scenario: unknown scenario 'nope'")
    assert "lecture" in err[0] and "fault-bumper" in err[0]


def test_bad_scenario_file_names_file_and_key(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(SHORT.replace("max_time_s: 3", "max_time_s: -3"), encoding="utf-8")
    assert main(["sim", "--scenario", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"lanewarden: error: {bad}: run.max_time_s = -3: expected a finite number "
                   "with 0 < value <= 600"]


def test_sim_writes_every_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = tmp_path / "short.yaml"
    scenario.write_text(SHORT, encoding="utf-8")
    out = tmp_path / "run"
    code = main(["sim", "--scenario", str(scenario), "--seed", "3", "--out", str(out),
                 "--quiet", "--check"])
    assert code == 0, capsys.readouterr().err
    metrics = json.loads((out / "metrics.json").read_text())
    for key in ("scenario", "controller", "seed", "frames", "sim_time_s", "wall_time_s", "halted",
                "halt_reason", "final_state", "states_visited", "max_cross_track_error_m",
                "mean_cross_track_error_m", "distance_travelled_m", "distance_past_lane_end_m",
                "crossed_tape", "lane_loss_to_halt_s", "turns_completed"):
        assert key in metrics
    assert metrics["scenario"] == "short" and metrics["seed"] == 3
    assert metrics["controller"] == "supervised" and metrics["expectation_met"] is True
    assert metrics["frames"] == 91 and metrics["sim_time_s"] == pytest.approx(3.0)
    lines = (out / "run.jsonl").read_text().splitlines()
    assert len(lines) == metrics["frames"]
    first = json.loads(lines[0])
    assert first["state"] == "HALT" and "observation" in first and "command" in first
    assert (out / "plot.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    info = video_info(out / "video.mp4")
    assert info["codec"] == "h264" and str(info["pix_fmt"]).startswith("yuv420p")
    assert info["size"] == (640 + 480, 480)  # camera panel beside the map
    stdout = capsys.readouterr().out
    assert "expected outcome: met" in stdout and str(out) in stdout


def test_check_flag_fails_an_unmet_expectation(tmp_path: Path) -> None:
    scenario = tmp_path / "short.yaml"
    scenario.write_text(SHORT.replace("halted: false", "halted: true"), encoding="utf-8")
    code = main(["sim", "--scenario", str(scenario), "--out", str(tmp_path / "o"), "--quiet",
                 "--no-video", "--check"])
    assert code == 2
    assert not (tmp_path / "o" / "video.mp4").exists()
