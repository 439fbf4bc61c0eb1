"""The campaign report reads right: worst cases are the unsafe runs, the false halts and the
slowest halts (never a nominal run); each time-to-halt distribution is a plot of its own halts on
one shared, labelled axis; rerun commands are selectable and copyable; junit.xml counts right.
Rows are literal, as results.sqlite holds them."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import pytest

from lanewarden.scenarios.campaign.report import (
    LISTED_PER_OUTCOME,
    nice_axis,
    report_html,
    summarize,
    write_junit,
)


def row(index: int, outcome: str, reason: str, to_halt: float | None = None,
        kinds: str = "bumper", scenario: str = "straight") -> dict[str, Any]:
    return {"id": f"r{index:05d}", "idx": index, "scenario": scenario, "camera": "small",
            "seed": 0, "fault_kinds": kinds, "outcome": outcome, "reason": reason,
            "halt_reason": None, "time_to_halt_s": to_halt, "cpu_s": 3.0, "sim_time_s": 12.0,
            "wall_s": 3.5, "metrics_json": json.dumps({"max_cross_track_error_m": 0.02})}


ROWS = [
    row(0, "nominal", "followed the lane throughout", kinds="glare_sweep"),
    row(1, "safe_halt", "BUMPER answering bumper (fault 0)", 0.034),
    row(2, "safe_halt", "BUMPER answering bumper (fault 0)", 0.067),
    row(3, "safe_halt", "CLIFF answering cliff (fault 1)", 0.0, kinds="loop_stall,cliff"),
    row(4, "safe_halt", "LANE_LOST answering lens_smudge (fault 0)", 2.4, kinds="lens_smudge"),
    row(5, "recovered", "DEGRADED, then following again", kinds="glare_sweep"),
    row(6, "false_halt", "LANE_LOST at 7.500 s with no fault acting and the tape in place",
        kinds="glare_sweep"),
    row(7, "unsafe", "bumper (fault 0) took effect at 2.000 s: HALT due by 2.100 s, came at "
        "2.333 s", 0.333),
    row(8, "unsafe", "crossed a tape", kinds="occlusion"),
    row(9, "error", "fault never took effect: 0:floor_mark", kinds="floor_mark"),
]


def _section(page: str, heading: str) -> str:
    start = page.index(f"<h2>{heading}</h2>")
    end = page.find("<h2>", start + 1)
    return page[start:end if end > 0 else None]


def _run_ids(html_part: str) -> list[str]:
    return re.findall(r"<tr><td>(r\d{5})</td>", html_part)


def test_worst_cases_are_unsafe_false_halts_and_the_slowest_halts(tmp_path: Path) -> None:
    page = report_html("spec", summarize(ROWS), tmp_path, "text")
    worst = _section(page, "Worst cases")
    # unsafe: never halting (crossed a tape, no time) before the late one, then the false halt;
    # then the slowest safe halt of each kind, slowest first
    assert _run_ids(worst) == ["r00008", "r00007", "r00006", "r00004", "r00002", "r00003"]
    assert "r00000" not in worst and "r00005" not in worst, "no nominal or recovered run"
    assert _run_ids(_section(page, "Runs in error")) == ["r00009"]


def test_the_rerun_commands_can_be_selected_and_copied() -> None:
    """The command may wrap after each slash (<wbr>, no character: a selection copies the
    command as it is); the button copies it whole."""
    page = report_html("spec", summarize(ROWS), Path("/data/campaigns/c1"), "text")
    assert ('<code class="cmd">lanewarden sim --case /<wbr>data/<wbr>campaigns/<wbr>c1/<wbr>'
            'cases/<wbr>r00007.yaml</code> <button type="button" class="copy" '
            'data-copy="lanewarden sim --case /data/campaigns/c1/cases/r00007.yaml"') in page
    assert "user-select: all" in page and "navigator.clipboard.writeText" in page


def test_the_case_tables_scroll_in_their_own_box() -> None:
    """Wider than the window (many columns, long names), a case table scrolls inside its box,
    the scroll bar under it; the page itself does not (its rerun column was out of sight)."""
    page = report_html("spec", summarize(ROWS), Path("/data/c1"), "text")
    for heading in ("Worst cases", "Runs in error"):
        section = _section(page, heading)
        assert section.count('<div class="wide"><table>') == section.count("<table>") > 0
    assert "div.wide { overflow-x: auto;" in page


def test_a_relative_out_folder_still_gives_commands_that_work_from_anywhere(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`campaign --out rel/c1`: the report's rerun commands name the case by its absolute path
    (they named rel/c1/cases/..., which fails from any other folder, such as rel/c1 itself)."""
    monkeypatch.chdir(tmp_path)
    page = report_html("spec", summarize(ROWS), Path("rel/c1"), "text")
    assert f"data-copy=\"lanewarden sim --case {tmp_path.resolve()}/rel/c1/cases/r00007.yaml\"" \
        in page
    assert "--case rel/c1/" not in page


def test_time_to_halt_is_a_plot_per_kind_on_one_labelled_axis(tmp_path: Path) -> None:
    page = report_html("spec", summarize(ROWS), tmp_path, "text")
    table = _section(page, "Time to halt (safe halts)")
    plots = re.findall(r"<svg .*?</svg>", table)
    assert len(plots) == 3  # bumper, cliff, lens_smudge
    assert len(set(plots)) == 3, "each row draws its own halts"
    for plot in plots:  # the shared axis 0..2.5 s: the same tick labels on every row
        assert [t for t in re.findall(r">([-\d.]+)</text>", plot)] == [
            "0", "0.5", "1", "1.5", "2", "2.5"]
    bumper = next(p for p in plots if "2 halts" in p)
    # 0..2.5 s over x = 14..326 px: 0.034 s at 18.2 px, 0.067 s at 22.4 px, 1 s at 138.8 px
    assert re.findall(r'<circle cx="([\d.]+)"', bumper) == ["18.2", "22.4"]
    assert '<text x="138.8" y="41" font-size="10" text-anchor="middle" fill="#555">1</text>' \
        in bumper
    assert 'aria-label="2 halts from 0.034 s to 0.067 s, median 0.051 s"' in bumper


def test_many_halts_make_a_histogram_and_the_lists_stay_short(tmp_path: Path) -> None:
    rows = [row(i, "safe_halt", "BUMPER answering bumper (fault 0)", 0.001 * i)
            for i in range(200)]
    rows += [row(1000 + i, "unsafe", "crossed a tape", kinds="occlusion") for i in range(40)]
    summary = summarize(rows)
    page = report_html("spec", summary, tmp_path, "text")
    plot = re.findall(r"<svg .*?</svg>", _section(page, "Time to halt (safe halts)"))[0]
    assert "<circle" not in plot and plot.count("<rect") >= 10
    worst = _section(page, "Worst cases")
    assert len(_run_ids(worst)) == LISTED_PER_OUTCOME + 1  # + the slowest bumper halt
    assert f"... and {40 - LISTED_PER_OUTCOME} more unsafe runs" in worst


def test_one_of_a_kind_is_singular(tmp_path: Path) -> None:
    rows = [row(0, "safe_halt", "BUMPER answering bumper (fault 0)", 0.05)]
    rows += [row(1000 + i, "unsafe", "crossed a tape", kinds="occlusion")
             for i in range(LISTED_PER_OUTCOME + 1)]
    page = report_html("spec", summarize(rows), tmp_path, "text")
    plot = re.findall(r"<svg .*?</svg>", _section(page, "Time to halt (safe halts)"))[0]
    assert 'aria-label="1 halt from 0.050 s to 0.050 s, median 0.050 s"' in plot
    assert "... and 1 more unsafe run (results.sqlite" in _section(page, "Worst cases")


def test_nice_axes() -> None:
    assert nice_axis(0.034, 2.4) == (0.0, 2.5, [0.0, 0.5, 1.0, 1.5, 2.0, 2.5])
    assert nice_axis(0.0, 0.067) == (0.0, 0.08, [0.0, 0.02, 0.04, 0.06, 0.08])
    assert nice_axis(-0.1, 0.3) == (-0.1, 0.3, [-0.1, 0.0, 0.1, 0.2, 0.3])


def test_junit_counts_failures_and_errors(tmp_path: Path) -> None:
    summary = summarize(ROWS)
    write_junit(tmp_path / "junit.xml", "spec", ROWS, summary)
    suite = ElementTree.parse(tmp_path / "junit.xml").getroot()
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors"), suite.get("time")) == (
        "10", "3", "1", "35.000")
    cases = suite.findall("testcase")
    assert [c.get("name") for c in cases][:2] == ["r00000 glare_sweep", "r00001 bumper"]
    assert cases[8].find("failure").get("message") == "unsafe: crossed a tape"  # type: ignore
    # the rerun command works from anywhere, as the report's does; no "None" for no halt
    out = cases[0].findtext("system-out") or ""
    assert f"rerun: lanewarden sim --case {tmp_path.resolve()}/cases/r00000.yaml" in out
    assert "halt reason: None" not in "".join(c.findtext("system-out") or "" for c in cases)


def test_blind_halts_are_listed_apart_from_the_failures(tmp_path: Path) -> None:
    blind = row(10, "safe_halt", "LANE_LOST at 5.167 s: camera showed no lane contrast the "
                "detector could use in any of the last 6 frames (0.2 s)", kinds="loop_stall")
    page = report_html("spec", summarize([*ROWS, blind]), tmp_path, "text")
    section = _section(page, "Halts while the camera showed no lane")
    assert _run_ids(section) == ["r00010"]
    assert "camera showed no lane contrast" in section
    assert "r00010" not in _section(page, "Worst cases")
    assert "Halts while the camera showed no lane" not in report_html(
        "spec", summarize(ROWS), tmp_path, "text")


def test_a_false_halt_shows_what_perception_gave_the_supervisor_before_it(
        tmp_path: Path) -> None:
    """A listed run's `before_halt` summary (scenarios/before_halt.py) is one line in its row;
    a row stored before the summary existed shows an empty cell, not an error."""
    summary = {"window_s": 2.0, "frames": 60, "confident": 40, "usable": 5, "unusable": 15,
               "weakest": {"lane_width": 9, "parallel": 4}, "longest_confident_run": 4,
               "at_slope_cap": 5, "outliers": 13, "no_frame": 0}
    halted = row(6, "false_halt", "DEGRADED_BUDGET_EXHAUSTED at 8.100 s with no fault acting "
                 "and the tape in place", kinds="glare_sweep")
    halted["metrics_json"] = json.dumps({"max_cross_track_error_m": 0.02,
                                         "before_halt": summary})
    rows = [halted if r["id"] == "r00006" else r for r in ROWS]
    worst = _section(report_html("spec", summarize(rows), tmp_path, "text"), "Worst cases")
    assert "<th>perception before the halt</th>" in worst
    line = ("last 2 s: 60 frames, 40 confident (at most 4 in a row), 5 usable but not confident, "
            "15 unusable (lane_width 9, parallel 4); 5 at the slope cap; 13 outliers")
    assert f'<td class="before">{line}</td>' in worst
    old = _section(report_html("spec", summarize(ROWS), tmp_path, "text"), "Worst cases")
    assert old.count('<td class="before"></td>') == len(_run_ids(old))


def _on_a_false_lane(index: int, outcome: str, longest_s: float, frames: int) -> dict[str, Any]:
    driven = row(index, outcome, "LANE_DEPARTURE answering (no fault)", 0.1, scenario="lecture")
    return {**driven, "metrics_json": json.dumps({
        "max_cross_track_error_m": 0.05, "false_lane_frames": frames,
        "false_lane_longest_s": longest_s, "max_edge_error_m": 0.2795,
        "min_tape_clearance_m": 0.0429})}


def test_runs_on_a_false_lane_are_listed_whatever_their_outcome(tmp_path: Path) -> None:
    """A safe halt after 1.17 s on a lane of parquet slats (r00322's numbers) is listed, the
    longest stretch first, beside a recovered one; runs that never trusted a false lane (the
    other rows: no such metric, or 0 frames) are not."""
    rows = [*ROWS, _on_a_false_lane(10, "recovered", 0.0667, 2),
            _on_a_false_lane(11, "safe_halt", 1.1667, 72), _on_a_false_lane(12, "nominal", 0.0, 0)]
    part = _section(report_html("spec", summarize(rows), tmp_path, "text"),
                    "Driving on a false lane")
    assert _run_ids(part) == ["r00011", "r00010"]
    assert "2 runs of 3, 74 frames in all" in part  # of the 3 runs that measured it
    assert ("<td>1.17</td><td>72</td><td>0.280</td><td>42.9</td>") in part
    assert "more than 8 cm from every tape" in part
    measured_none = _on_a_false_lane(12, "nominal", 0.0, 0)
    assert "<p>None in 1 run.</p>" in _section(
        report_html("spec", summarize([*ROWS, measured_none]), tmp_path, "text"),
        "Driving on a false lane")
    # rows stored before the figures existed: not measured, not "none"
    assert "<p>Not measured: these runs were stored before" in _section(
        report_html("spec", summarize(ROWS), tmp_path, "text"), "Driving on a false lane")
