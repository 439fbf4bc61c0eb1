"""`lanewarden demo`: the README's first command, run once exactly as a user runs it (640x480,
videos included), and the issue's acceptance asserted on what it wrote."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from lanewarden.cli import main


@pytest.fixture(scope="module")
def demo_out(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("demo") / "lanewarden-out"
    assert main(["demo", "--out", str(out), "--quiet"]) == 0
    return out


def metrics(out: Path, name: str) -> dict[str, object]:
    return dict(json.loads((out / name / "metrics.json").read_text()))


def test_supervised_run_follows_the_course_and_stops_at_the_end(demo_out: Path) -> None:
    m = metrics(demo_out, "supervised")
    assert m["scenario"] == "lecture" and m["controller"] == "supervised"
    assert m["resolution"] == [640, 480]
    assert m["turns_completed"] == ["A", "B"]
    # the lecture's sharp corners: TURN_RIGHT (at A) before TURN_LEFT (at B); where exactly is
    # tests/scenarios/test_lecture_turns.py
    visited = m["states_visited"]
    assert isinstance(visited, list) and "TURN_RIGHT" in visited and "TURN_LEFT" in visited
    assert visited.index("TURN_RIGHT") < visited.index("TURN_LEFT")
    assert isinstance(m["max_cross_track_error_m"], float)
    assert m["max_cross_track_error_m"] <= 0.10
    assert m["halted"] is True
    assert str(m["halt_reason"]).startswith(("LANE_LOST", "DEGRADED_BUDGET_EXHAUSTED"))
    assert isinstance(m["distance_past_lane_end_m"], float)
    assert m["distance_past_lane_end_m"] <= 0.10
    assert m["crossed_tape"] is False


def test_lecture_run_never_stops_and_wanders_past_the_end(demo_out: Path) -> None:
    m = metrics(demo_out, "lecture")
    assert m["controller"] == "lecture"
    visited = m["states_visited"]
    assert isinstance(visited, list) and {"TURN_RIGHT", "TURN_LEFT"} <= set(visited)
    assert m["halted"] is False
    assert isinstance(m["distance_past_lane_end_m"], float)
    assert m["distance_past_lane_end_m"] >= 1.0


def test_report_shows_both_runs(demo_out: Path) -> None:
    page = (demo_out / "report.html").read_text()
    for name in ("lecture", "supervised"):
        assert f'data-video="{name}/video.mp4"><img src="{name}/poster.jpg"' in page
        assert f'src="{name}/plot.png"' in page
        for output in ("metrics.json", "run.jsonl", "video.mp4", "poster.jpg", "plot.png",
                       "report.html"):
            assert (demo_out / name / output).stat().st_size > 0
        assert not (demo_out / name / "PARTIAL").exists()
    assert not (demo_out / "PARTIAL").exists()
    assert "<table>" in page and "distance past lane end" in page
    assert "<th>states visited</th>" in page and "<th>halt position</th>" in page
    assert "<h2>Reading the videos</h2>" in page


def test_posters_show_the_outcome(demo_out: Path) -> None:
    supervised, lecture = metrics(demo_out, "supervised"), metrics(demo_out, "lecture")
    poster = supervised["video_poster"]
    assert isinstance(poster, dict) and poster["shows"] == "the halt"
    halt_time = supervised["halt_time_s"]
    assert isinstance(halt_time, float)
    # metrics' times are rounded to 0.1 ms, the poster's is not
    assert -1e-4 <= poster["time_s"] - halt_time <= 1 / 15 + 1e-4  # the first video frame in HALT
    last = lecture["video_poster"]
    assert isinstance(last, dict) and last["shows"] == "the last frame"
    assert -1e-4 <= lecture["sim_time_s"] - last["time_s"] < 1 / 15  # type: ignore[operator]
