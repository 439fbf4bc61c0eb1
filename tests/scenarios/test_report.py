"""The demo's comparison table, summary sentence and report page."""

from __future__ import annotations

from pathlib import Path

from lanewarden.scenarios.report import comparison_rows, demo_summary, format_table, write_report

LECTURE = {"halted": False, "halt_reason": None, "turns_completed": ["A"],
           "max_cross_track_error_m": 0.7, "distance_past_lane_end_m": 2.5, "crossed_tape": True,
           "states_visited": ["FOLLOW", "TURN_RIGHT", "TURN_LEFT"],
           "outputs": ["plot.png", "run.jsonl", "video.mp4"]}
SUPERVISED = {"halted": True, "halt_reason": "LANE_LOST: no usable lane for longer than x",
              "turns_completed": ["A", "B"], "max_cross_track_error_m": 0.05123,
              "distance_past_lane_end_m": -0.36, "crossed_tape": False,
              "outputs": ["plot.png", "run.jsonl"]}


def test_table_and_summary() -> None:
    rows = comparison_rows({"lecture": LECTURE, "supervised": SUPERVISED})
    assert rows[0] == ["", "lecture", "supervised"]
    table = dict((r[0], r[1:]) for r in rows[1:])
    assert table["halted"] == ["no", "yes"]
    assert table["halt reason"] == ["-", "LANE_LOST"]
    assert table["turns completed"] == ["A", "A, B"]
    assert table["states visited"] == ["FOLLOW, TURN_RIGHT, TURN_LEFT", "-"]
    assert table["max cross-track error (m)"] == ["0.7", "0.051"]
    text = format_table(rows)
    assert text.splitlines()[1].startswith("---")
    summary = demo_summary(LECTURE, SUPERVISED)
    assert summary.startswith("The lecture's controller completed turn A, crossed a tape and "
                              "never stopped, ending 2.50 m past the end of the tape")
    assert "the supervised controller completed turns A and B and halted (LANE_LOST) 0.36 m " \
           "before the end of the tape." in summary


def test_report_page_links_each_run(tmp_path: Path) -> None:
    write_report(tmp_path / "report.html", {"lecture": LECTURE, "supervised": SUPERVISED}, "Hi.")
    page = (tmp_path / "report.html").read_text()
    assert '<video src="lecture/video.mp4"' in page
    assert 'src="supervised/video.mp4"' not in page and "(no video recorded)" in page
    assert 'src="supervised/plot.png"' in page and "<p>Hi.</p>" in page
