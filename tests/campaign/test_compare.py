"""`lanewarden compare`: two campaigns of the same draws, run by run.

- a run that became unsafe or a false halt is `worse`, one that stopped being either `better`,
  a change to or from `error` says nothing either way, any other change is `changed`; worse
  first in what is printed;
- runs are matched by id, and only when everything drawn for them is the same: otherwise one
  line naming the run and what differs, exit 2;
- closest approaches, near misses and false lanes over the runs both hold; the false lanes only
  where both campaigns measured them;
- both folders are only read: nothing is created or changed in either, a folder without results
  or with a damaged file is one line, exit 2;
- a row no campaign writes (an unknown outcome, unreadable metrics) is refused, never read as
  "not measured" (a damaged row must not make a campaign look safer);
- `--fail-if-worse` is a gate: exit 3 naming the runs that got worse (2: not comparable);
- a screen (`campaign --only-notable DIR`) runs exactly DIR's notable runs, and is refused in one
  line naming the flag where DIR is of another seed or spec, unreadable, has none, or names runs
  beyond --runs.
Rows are literal, as results.sqlite holds them; expected figures are written out."""

from __future__ import annotations

import json
import re
import sqlite3
from pathlib import Path
from typing import Any

import pytest

from lanewarden.cli import main
from lanewarden.scenarios.campaign.compare import (
    CampaignsDiffer,
    compare_campaigns,
    describe,
    is_notable,
)
from lanewarden.scenarios.campaign.store import ResultStore
from lanewarden.scenarios.campaign.stored_row import UnreadableRow


def row(index: int, outcome: str, clearance_m: float | None = 0.1,
        false_lane_frames: int | None = 0, scenario: str = "lecture") -> dict[str, Any]:
    metrics: dict[str, Any] = {}
    if clearance_m is not None:
        metrics["min_tape_clearance_m"] = clearance_m
    if false_lane_frames is not None:
        metrics["false_lane_frames"] = false_lane_frames
    return {"id": f"r{index:05d}", "idx": index, "scenario": scenario, "camera": "320x240",
            "floor": "parquet", "tape": "white", "effect": "none", "seed": 100 + index,
            "fault_kinds": "tape_patch", "outcome": outcome, "reason": "r",
            "halt_reason": None, "metrics_json": json.dumps(metrics)}


BEFORE = [
    row(0, "safe_halt", 0.0107, 45),
    row(1, "false_halt", 0.09),
    row(2, "recovered", 0.06),
    row(3, "unsafe", -0.01, 3),
    row(4, "safe_halt", 0.05),
    row(5, "error", None, None),
    row(6, "nominal", 0.1),
    row(7, "false_halt", 0.08),
]
AFTER = [
    row(0, "unsafe", -0.0001, 59),       # worse
    row(1, "recovered", 0.098),          # better
    row(2, "false_halt", 0.07),          # worse
    row(3, "false_halt", 0.02),          # better (no longer unsafe)
    row(4, "recovered", 0.025, 2),       # changed (both good outcomes)
    row(5, "safe_halt", 0.09),           # error: says nothing
    row(6, "nominal", 0.1),
    row(7, "unsafe", 0.001),             # worse (a false halt that now crosses)
    row(8, "nominal", 0.1),              # only after
]


def test_each_changed_run_is_classed_from_the_safety_side_worse_first() -> None:
    comparison = compare_campaigns(BEFORE, AFTER)
    assert comparison.shared == 8
    assert (comparison.only_before, comparison.only_after) == (0, 1)
    assert [(c.run_id, c.change, c.before, c.after) for c in comparison.changes] == [
        ("r00000", "worse", "safe_halt", "unsafe"),
        ("r00002", "worse", "recovered", "false_halt"),
        ("r00007", "worse", "false_halt", "unsafe"),
        ("r00001", "better", "false_halt", "recovered"),
        ("r00003", "better", "unsafe", "false_halt"),
        ("r00005", "error", "error", "safe_halt"),
        ("r00004", "other", "safe_halt", "recovered"),
    ]
    first = comparison.changes[0]
    assert (first.before_clearance_m, first.after_clearance_m) == (0.0107, -0.0001)
    assert first.what == "lecture / 320x240 / parquet / white"


def test_figures_are_over_the_runs_both_hold() -> None:
    comparison = compare_campaigns(BEFORE, AFTER)
    before, after = comparison.before, comparison.after
    assert dict(before.counts) == {"safe_halt": 2, "recovered": 1, "nominal": 1,
                                   "false_halt": 2, "unsafe": 1, "error": 1}
    assert dict(after.counts) == {"safe_halt": 1, "recovered": 2, "nominal": 1,
                                  "false_halt": 2, "unsafe": 2, "error": 0}
    assert (before.closest_m, before.closest_id) == (-0.01, "r00003")
    assert (after.closest_m, after.closest_id) == (-0.0001, "r00000")
    # within 30 mm: before r00000 and r00003; after r00000, r00003, r00004 and r00007
    assert (before.near_tape, after.near_tape) == (2, 4)
    # r00005 was an error before, with no metrics: 7 of the 8 measured before, all 8 after
    assert (before.false_lane_measured, after.false_lane_measured) == (7, 8)
    assert (before.false_lane_runs, before.false_lane_frames) == (2, 48)
    assert (after.false_lane_runs, after.false_lane_frames) == (2, 61)


def test_false_lanes_are_compared_only_where_both_measured_them() -> None:
    lines = describe(compare_campaigns(BEFORE, AFTER), "before", "after")
    assert ("  trusted a false lane: measured in 7 runs before and 8 after, of 8 (the others "
            "were stored before the metric existed): not compared") in lines
    both = describe(compare_campaigns(BEFORE[:5], AFTER[:5]), "before", "after")
    assert "  trusted a false lane: 2 runs (48 frames) before, 2 runs (61 frames) after" in both


def test_the_printed_table_marks_what_moved() -> None:
    lines = describe(compare_campaigns(BEFORE, AFTER), "b", "a")
    assert lines[0] == "8 runs in both (before: b; after: a); left out: 0 only before, 1 only after"
    assert "  unsafe           1       2  (+1)" in lines
    assert "  nominal          1       1" in lines
    assert ("  closest approach to a tape: -10.0 mm (r00003) before, -0.1 mm (r00000) after; "
            "within 30 mm: 2 before, 4 after") in lines
    worse = lines.index("worse (became unsafe or a false halt): 3")
    assert lines[worse + 1] == ("  r00000  safe_halt -> unsafe  (closest 10.7 mm -> -0.1 mm)  "
                                "lecture / 320x240 / parquet / white")
    assert lines.index("better (was unsafe and no longer is, or was a false halt and now ends "
                       "well): 2") > worse


def test_a_run_drawn_differently_is_refused_naming_it() -> None:
    after = [dict(r) for r in AFTER]
    after[2]["scenario"] = "s-curve"
    with pytest.raises(CampaignsDiffer, match=r"r00002 is not the same run in both "
                       r"\(scenario: 'lecture' before, 's-curve' after\)"):
        compare_campaigns(BEFORE, after)
    with pytest.raises(CampaignsDiffer, match="share no run"):
        compare_campaigns(BEFORE[:2], [row(9, "nominal")])


def test_a_row_no_campaign_writes_is_refused_naming_it() -> None:
    good = [row(0, "nominal"), row(1, "nominal")]
    for bad, said in ((dict(good[1], metrics_json="{not json"), "metrics_json '{not json'"),
                      (dict(good[1], metrics_json="[1, 2]"), "metrics_json '[1, 2]'"),
                      (dict(good[1], outcome="exploded"), "outcome 'exploded'")):
        with pytest.raises(UnreadableRow, match=f"^after: run r00001: {re.escape(said)} is "):
            compare_campaigns(good, [good[0], bad])
        with pytest.raises(UnreadableRow, match=f"^run r00001: {re.escape(said)} is "):
            is_notable(bad)
    # a run in error stores no metrics ('{}' or nothing): not measured, not refused
    quiet = [dict(good[0], outcome="error", metrics_json=None), dict(good[1], metrics_json="")]
    comparison = compare_campaigns(quiet, good)
    assert comparison.before.closest_id is None and comparison.before.false_lane_measured == 0
    assert comparison.after.closest_m == 0.1


def store(folder: Path, rows: list[dict[str, Any]], seed: int = 4) -> Path:
    folder.mkdir()
    with ResultStore(folder / "results.sqlite") as results:
        results.claim({"spec": "x", "seed": str(seed)})
        for r in rows:
            results.put(r)
    return folder


def test_cli_reads_both_folders_and_writes_nothing(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    before = store(tmp_path / "before", BEFORE)
    after = store(tmp_path / "after", AFTER)
    listing = {p: p.stat().st_mtime_ns for p in tmp_path.rglob("*")}
    assert main(["compare", str(before), str(after)]) == 0
    out = capsys.readouterr().out
    assert "worse (became unsafe or a false halt): 3" in out
    assert {p: p.stat().st_mtime_ns for p in tmp_path.rglob("*")} == listing

    assert main(["compare", str(before), str(after / "results.sqlite"), "--json"]) == 0
    document = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert [c["id"] for c in document["changes"] if c["change"] == "worse"] == [
        "r00000", "r00002", "r00007"]
    assert document["after"]["counts"]["unsafe"] == 2
    assert (document["before_name"], document["after_name"]) == (
        str(before), str(after / "results.sqlite"))


def test_cli_fail_if_worse_is_a_gate(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = store(tmp_path / "before", BEFORE)
    after = store(tmp_path / "after", AFTER)
    assert main(["compare", str(before), str(after), "--fail-if-worse"]) == 3
    captured = capsys.readouterr()
    assert "worse (became unsafe or a false halt): 3" in captured.out  # the table still printed
    assert captured.err.strip().splitlines() == [
        f"lanewarden: worse: 3 runs got worse in {after}: r00000 (safe_halt -> unsafe), r00002 "
        "(recovered -> false_halt), r00007 (false_halt -> unsafe)"]
    same = store(tmp_path / "same", BEFORE)
    assert main(["compare", str(before), str(same), "--fail-if-worse"]) == 0
    assert "no run changed outcome" in capsys.readouterr().out


def test_cli_bad_folders_are_one_line_and_left_alone(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    before = store(tmp_path / "before", BEFORE)
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["compare", str(before), str(empty)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"lanewarden: error: {empty / 'results.sqlite'}: no campaign results here (expected the "
        "results.sqlite a `lanewarden campaign --out` folder holds)")
    assert list(empty.iterdir()) == []

    garbage = tmp_path / "garbage"
    garbage.mkdir()
    (garbage / "results.sqlite").write_bytes(b"not a database at all" * 100)
    assert main(["compare", str(before), str(garbage)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"lanewarden: error: {garbage / 'results.sqlite'}: not a results database (expected the "
        "results.sqlite a `lanewarden campaign --out` folder holds)")
    assert (garbage / "results.sqlite").read_bytes() == b"not a database at all" * 100
    assert sorted(p.name for p in garbage.iterdir()) == ["results.sqlite"]

    damaged = tmp_path / "damaged"
    damaged.mkdir()
    data = bytearray((before / "results.sqlite").read_bytes())
    data[-4096:] = b"\xff" * 4096  # the last page overwritten, the header intact
    (damaged / "results.sqlite").write_bytes(bytes(data))
    assert main(["compare", str(before), str(damaged)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the results database is damaged" in err[0], err
    assert (damaged / "results.sqlite").read_bytes() == bytes(data)

    other = store(tmp_path / "other", [dict(r, seed=7) for r in AFTER])
    assert main(["compare", str(before), str(other)]) == 2
    assert "r00000 is not the same run in both (seed: 100 before, 7 after)" in (
        capsys.readouterr().err)
    seed5 = store(tmp_path / "seed5", AFTER, seed=5)
    assert main(["compare", str(before), str(seed5)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"lanewarden: error: {before} holds a campaign of seed 4, {seed5} one of seed 5: runs "
        "are compared by id, so both must come from the same spec and seed (only --config may "
        "differ)")
    (before / "junit.xml").write_text("<testsuite/>", encoding="utf-8")
    assert main(["compare", str(before / "junit.xml"), str(seed5)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"lanewarden: error: {before / 'junit.xml'}: not a results database (expected the "
        "results.sqlite a `lanewarden campaign --out` folder holds)")


def test_the_notable_runs_are_those_worth_screening_a_change_on() -> None:
    rows = [row(0, "nominal"), row(1, "false_halt"), row(2, "unsafe", -0.002),
            row(3, "safe_halt", 0.0299), row(4, "safe_halt", 0.03), row(5, "recovered", 0.2, 1),
            row(6, "error", None, None), row(7, "nominal", None, None)]
    assert [str(r["id"]) for r in rows if is_notable(r)] == ["r00001", "r00002", "r00003",
                                                             "r00005"]


def test_a_screen_runs_only_the_notable_runs_and_compares_with_them(
        tiny_spec: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = tmp_path / "before"
    common = ["--spec", str(tiny_spec), "--seed", "7", "--scheduler", "in-process", "--quiet"]
    assert main(["campaign", *common, "--out", str(before), "--runs", "3"]) == 0
    with sqlite3.connect(before / "results.sqlite") as db:  # say r00001 had halted falsely
        db.execute("UPDATE runs SET outcome = 'false_halt' WHERE id = 'r00001'")
        db.execute("UPDATE runs SET metrics_json = '{}' WHERE id != 'r00001'")
    capsys.readouterr()
    screen = tmp_path / "screen"
    assert main(["campaign", *common, "--out", str(screen), "--only-notable", str(before)]) == 0
    err = capsys.readouterr().err
    assert f"campaign tiny: only the notable runs of {before} (unsafe, false halts" in err
    assert "campaign tiny: 1 run (seed 7), 0 already stored" in err
    with sqlite3.connect(screen / "results.sqlite") as db:
        assert db.execute("SELECT id FROM runs").fetchall() == [("r00001",)]
    said = f"a screen: only the notable runs of {before}, not a sample"
    assert said in (screen / "report.html").read_text(encoding="utf-8")
    assert main(["compare", str(before), str(screen)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"1 run in both (before: {before}; after: {screen}); left out: 2 only "
                          "before, 0 only after")


def test_a_screen_is_refused_in_one_line_where_it_cannot_be_one(
        tiny_spec: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    nothing = store(tmp_path / "nothing", [row(0, "nominal"), row(1, "recovered")])
    common = ["campaign", "--spec", str(tiny_spec), "--scheduler", "in-process", "--quiet",
              "--seed", "4"]
    assert main([*common, "--out", str(tmp_path / "s1"), "--only-notable", str(nothing)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"lanewarden: error: --only-notable {nothing}: no run there is unsafe, a false halt, on "
        "a false lane or within 30 mm of a tape: nothing to screen")
    late = store(tmp_path / "late", [row(0, "nominal"), row(7, "false_halt")])
    assert main([*common, "--out", str(tmp_path / "s2"), "--runs", "5",
                 "--only-notable", str(late)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"lanewarden: error: --runs 5: --only-notable {late} names runs up to r00007; expected "
        "--runs 8 or more (or no --runs)")
    assert main([*common, "--out", str(late), "--only-notable", str(late)]) == 2
    assert "the same folder as --out" in capsys.readouterr().err
    # the rows say 'lecture': not what the tiny spec draws under these ids
    assert main([*common, "--out", str(tmp_path / "s3"), "--only-notable", str(late)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"lanewarden: error: --only-notable {late}: r00007 there is not the run this spec draws "
        "(scenario: 'lecture' there, 'short-straight' here); expected a campaign of the same "
        "spec and seed")
    assert main([*common[:-1], "5", "--out", str(tmp_path / "s4"),
                 "--only-notable", str(late)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"lanewarden: error: --only-notable {late}: a campaign of seed 4, this one --seed 5; "
        "expected --seed 4 (the same spec and seed draw the same runs)")
    damaged = store(tmp_path / "damaged", [dict(row(3, "unsafe"), metrics_json="{oops")])
    assert main([*common, "--out", str(tmp_path / "s5"), "--only-notable", str(damaged)]) == 2
    assert capsys.readouterr().err.strip() == (
        f"lanewarden: error: --only-notable {damaged}: {damaged / 'results.sqlite'}: run r00003: "
        "metrics_json '{oops' is not readable (expected the JSON object a campaign stores)")
    assert not any((tmp_path / f"s{i}").exists() for i in range(1, 6))
