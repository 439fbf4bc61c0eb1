"""A damaged row in results.sqlite is refused the same way by every reader: `lanewarden compare`
and a campaign resumed in that folder (its counts, report.html and junit.xml) say the same one
line naming the file, the run, the column and its value shortened (exit 2), never a traceback, a
run dropped from the counts, or GBs read.

Found by an attacker's review: metrics nested 100,000 deep were a RecursionError traceback in
both; an index that is no number stopped a resume with a ValueError (compare accepted it); an
outcome no campaign stores dropped out of a resumed campaign's counts (junit.xml: failures="0",
exit 0); a 300 MB reason took 2-3 GB to read. Stores are built row by row here (no run needed).
"""

from __future__ import annotations

import re
import sqlite3
from pathlib import Path
from typing import Any

import pytest

from lanewarden.cli import main
from lanewarden.scenarios.campaign import runner as runner_module
from lanewarden.scenarios.campaign.store import ResultStore
from lanewarden.scenarios.campaign.stored_row import (
    MAX_FIELD_CHARS,
    MAX_METRICS_CHARS,
    UnreadableRow,
    checked_row,
)
from tests.campaign.test_store_damage import RUNS, args, campaign_dir, counting, stored_row

DEEP = "[" * 100_000 + "]" * 100_000
EXPECTED_OUTCOMES = "safe_halt, recovered, nominal, false_halt, unsafe, error"

#: (what is set in run r00003's row, the value, what the one line says after the run)
DAMAGE: list[tuple[str, Any, str]] = [
    ("metrics_json", DEEP, f"metrics_json {'[' * 60!r} is not readable (expected the JSON "
                           "object a campaign stores)"),
    ("idx", "abc", "idx 'abc' is not a run's index (expected a whole number, 0 or more)"),
    ("outcome", "Unsafe", f"outcome 'Unsafe' is not one a campaign stores (expected one of "
                          f"{EXPECTED_OUTCOMES})"),
    ("wall_s", "slow", "wall_s 'slow' is not a number of seconds (expected what a campaign "
                       "stores, or nothing)"),
    ("metrics_json", '{"false_lane_frames": "many", "false_lane_longest_s": 1.0}',
     "metrics_json's false_lane_frames 'many' is not a number (expected what a campaign "
     "stores, or nothing)"),
    ("reason", "x" * (MAX_FIELD_CHARS + 1), "reason of 65,537 characters is longer than any a "
                                            "campaign stores (expected at most 65,536)"),
    ("metrics_json", '{"a": "' + "x" * MAX_METRICS_CHARS + '"}',
     "metrics_json of 1,048,585 characters is longer than any a campaign stores (expected at "
     "most 1,048,576)"),
]


def damage_row(out: Path, column: str, value: Any, index: int = 3) -> None:
    with sqlite3.connect(out / "results.sqlite") as db:
        db.execute(f"UPDATE runs SET {column} = ? WHERE id = ?", (value, f"r{index:05d}"))
    db.close()


def stored_runs(out: Path) -> list[tuple[Any, ...]]:
    with sqlite3.connect(out / "results.sqlite") as db:
        rows = db.execute("SELECT * FROM runs ORDER BY rowid").fetchall()
    db.close()
    return rows


@pytest.mark.parametrize(("column", "value", "said"), DAMAGE,
                         ids=["nested", "idx", "outcome", "wall_s", "metric", "reason_size",
                              "metrics_size"])
def test_compare_and_a_resumed_campaign_refuse_a_damaged_row_in_the_same_line(
        column: str, value: Any, said: str, tiny_spec: Path, tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "good").mkdir()
    (tmp_path / "bad").mkdir()
    good = campaign_dir(tmp_path / "good", tiny_spec)
    bad = campaign_dir(tmp_path / "bad", tiny_spec)
    damage_row(bad, column, value)
    with sqlite3.connect(bad / "results.sqlite") as db:  # one run still to run when resumed
        db.execute("DELETE FROM runs WHERE id = 'r00039'")
    db.close()
    line = f"lanewarden: error: {bad / 'results.sqlite'}: run r00003: {said}"

    assert main(["compare", str(good), str(bad)]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [line]
    assert main(["compare", str(bad), str(good)]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [line]

    ran: list[str] = []
    monkeypatch.setattr(runner_module, "run_case", counting(ran))
    stored = stored_runs(bad)
    assert main(args(tiny_spec, bad)) == 2
    captured = capsys.readouterr()
    assert captured.err.strip().splitlines() == [line]
    assert captured.out == ""
    assert ran == [], "refused before anything was counted or run (r00039 is missing)"
    assert not (bad / "junit.xml").exists() and not (bad / "report.html").exists()
    assert stored_runs(bad) == stored


def test_an_unknown_outcome_never_leaves_the_counts_of_a_resumed_campaign(
        tiny_spec: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The same store with the run 'unsafe' is one failure; written 'Unsafe' it had been none
    (exit 0, failures="0", the run missing from the counts): now it is refused."""
    out = campaign_dir(tmp_path, tiny_spec)
    damage_row(out, "outcome", "unsafe")
    assert main(args(tiny_spec, out)) == 0
    assert f'tests="{RUNS}" failures="1"' in (out / "junit.xml").read_text(encoding="utf-8")
    (out / "junit.xml").unlink()
    damage_row(out, "outcome", "Unsafe")
    capsys.readouterr()
    assert main(args(tiny_spec, out)) == 2
    assert "outcome 'Unsafe' is not one a campaign stores" in capsys.readouterr().err
    assert not (out / "junit.xml").exists()


def test_a_field_too_long_is_never_fetched(tmp_path: Path) -> None:
    """The store asks SQLite for a value's length first: a value over the limit stays in the
    file (it had been read whole, then copied, a few times over)."""
    path = tmp_path / "results.sqlite"
    with ResultStore(path) as store:
        store.put(dict(stored_row(0), reason="y" * (MAX_FIELD_CHARS + 1)))
        statements: list[str] = []
        store._db.set_trace_callback(statements.append)
        with pytest.raises(UnreadableRow, match="reason of 65,537 characters"):
            list(store.iter_rows())
    assert len(statements) == 1
    assert f"CASE WHEN length(reason) > {MAX_FIELD_CHARS} THEN NULL ELSE reason END" in (
        statements[0])


def test_every_reader_of_a_store_reads_checked_rows(tmp_path: Path) -> None:
    path = tmp_path / "results.sqlite"
    with ResultStore(path) as store:
        store.put(stored_row(0))
        store.put(dict(stored_row(1), outcome="exploded"))
    for read_only in (False, True):
        with ResultStore(path, read_only=read_only) as store:
            with pytest.raises(UnreadableRow, match=f"^{re.escape(str(path))}: run r00001: "
                                                    "outcome 'exploded'"):
                store.check()
            with pytest.raises(UnreadableRow):
                store.rows()
            assert [r["id"] for r in store.iter_rows(below_index=1)] == ["r00000"]


@pytest.mark.parametrize(("change", "said"), [
    ({"idx": -1}, "idx -1 is not a run's index (expected a whole number, 0 or more)"),
    ({"idx": None}, "idx NULL is not a run's index (expected a whole number, 0 or more)"),
    ({"idx": 4}, "id 'r00002' is not the id of run index 4 (expected 'r00004')"),
    ({"seed": 1.5}, "seed 1.5 is not a whole number (expected what a campaign stores, or "
                    "nothing)"),
    ({"scenario": b"\x00"}, "scenario b'\\x00' is not text (expected what a campaign "
                            "stores, or nothing)"),
    ({"metrics_json": b"{}"}, "metrics_json b'{}' is not readable (expected the JSON "
                              "object a campaign stores)"),
    ({"metrics_json": '{"min_tape_clearance_m": [0.01]}'},
     "metrics_json's min_tape_clearance_m [0.01] is not a number (expected what a campaign "
     "stores, or nothing)"),
    ({"metrics_json": "[1, 2]"}, "metrics_json '[1, 2]' is not readable (expected the JSON "
                                 "object a campaign stores)"),
    # the resumed campaign's report had stopped on these with a TypeError or a KeyError
    ({"metrics_json": '{"before_halt": {"window_s": 2.0}}'},
     "metrics_json's before_halt has no whole-number frames (expected the summary a campaign "
     "stores, or nothing)"),
    ({"metrics_json": '{"before_halt": "long"}'},
     "metrics_json's before_halt 'long' is not a summary (expected the summary a campaign "
     "stores, or nothing)"),
    ({"metrics_json": '{"before_halt": {"window_s": 2.0, "frames": 1, "confident": 0, "usable": '
                      '0, "unusable": 1, "longest_confident_run": 0, "weakest": [1]}}'},
     "metrics_json's before_halt weakest [1] is not names with counts (expected the summary a "
     "campaign stores, or nothing)"),
])
def test_a_row_is_what_a_campaign_writes_or_refused_naming_the_column(
        change: dict[str, Any], said: str) -> None:
    with pytest.raises(UnreadableRow) as refused:
        checked_row({**stored_row(2), **change}, "here")
    assert str(refused.value) == f"here: run r00002: {said}"


def test_rows_a_campaign_writes_are_read_as_they_are() -> None:
    error = dict(stored_row(5), outcome="error", metrics_json="{}", sim_time_s=None,
                 halt_reason=None)
    older = {"id": "r00006", "idx": 6, "outcome": "nominal"}  # columns from before they existed
    measured = dict(stored_row(7), metrics_json='{"false_lane_frames": 0, "min_tape_clearance_m"'
                                                 ': -0.01, "max_edge_error_m": null}')
    halted = dict(stored_row(8), metrics_json=(
        '{"before_halt": {"window_s": 2.0, "frames": 61, "confident": 40, "usable": 5, '
        '"unusable": 16, "jumped": 0, "weakest": {"lane_width": 9}, "longest_confident_run": 4, '
        '"at_slope_cap": 5, "outliers": 13, "no_frame": 0}, "false_lane_frames": 2, '
        '"false_lane_longest_s": 0.07}'))
    for row in (stored_row(4), error, older, dict(older, metrics_json=""), measured, halted):
        checked = checked_row(row, "here")
        assert {k: v for k, v in checked.items() if k != "_metrics"} == row


def test_a_false_lane_without_its_longest_spell_is_reported_not_a_traceback(
        tiny_spec: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A run on a false lane whose longest spell and edge error were not stored (a store written
    before those figures existed, or damaged) had stopped a resumed campaign's report with a
    TypeError; it is listed with those cells empty."""
    out = campaign_dir(tmp_path, tiny_spec)
    damage_row(out, "metrics_json", '{"false_lane_frames": 3}')
    assert main(args(tiny_spec, out)) == 0, capsys.readouterr().err
    capsys.readouterr()
    report = (out / "report.html").read_text(encoding="utf-8")
    assert re.search(r"r00003.*?<td></td><td>3</td><td></td>", report, re.S), report[-3000:]


def test_rows_left_unstored_are_carried_over_only_as_a_campaign_writes_them(
        tmp_path: Path) -> None:
    """results.sqlite.unstored.jsonl (rows a full disk kept out of the store) was read whole and
    parsed line by line with only ValueError caught: a line nested 100,000 deep was a
    RecursionError traceback, a line of gigabytes was held in memory, and a damaged row went
    into the store. Such lines are passed over now: their runs are simply run again."""
    import json

    from tests.campaign.test_store_damage import stored_row as finished

    path = tmp_path / "results.sqlite"
    unstored = tmp_path / "results.sqlite.unstored.jsonl"
    lines = [json.dumps(finished(0)), DEEP, json.dumps({**finished(1), "outcome": "Unsafe"}),
             json.dumps({**finished(2), "reason": "x" * (5 * 2**20)}), json.dumps(finished(3)),
             '{"id": "r00004", "idx": 4, "outc']  # (cut short when the disk filled)
    unstored.write_text("\n".join(lines), encoding="utf-8")
    with ResultStore(path) as store:
        assert store.unstored_carried == 2
        assert [r["id"] for r in store.iter_rows()] == ["r00000", "r00003"]
    assert not unstored.exists()


def test_recover_runs_again_what_no_reader_would_take_instead_of_carrying_it(
        tiny_spec: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """--recover carried every row it could read as it was: a row every reader refuses (an
    outcome no campaign stores) held the recovered store up again, and a field of hundreds of
    MB was read whole. Such runs are run again."""
    from tests.campaign.test_store_damage import damage_page

    out = campaign_dir(tmp_path, tiny_spec)
    damage_row(out, "outcome", "Unsafe", index=1)
    damage_row(out, "reason", "x" * (MAX_FIELD_CHARS + 1), index=2)
    damage_page(out / "results.sqlite", 8)
    ran: list[str] = []
    monkeypatch.setattr(runner_module, "run_case", counting(ran))
    assert main(args(tiny_spec, out, "--recover")) == 0, capsys.readouterr().err
    capsys.readouterr()
    assert {"r00001", "r00002"} <= set(ran)
    with sqlite3.connect(out / "results.sqlite") as db:
        outcomes = dict(db.execute("SELECT id, outcome FROM runs"))
    db.close()
    assert outcomes["r00001"] != "Unsafe"
    assert main(["compare", str(out), str(out)]) == 0  # every row now readable


def damage_identity(out: Path, key: str, value: Any) -> None:
    with sqlite3.connect(out / "results.sqlite") as db:
        db.execute("INSERT OR REPLACE INTO campaign VALUES (?, ?)", (key, value))
    db.close()


@pytest.mark.parametrize(("key", "value", "said"), [
    ("seed", "7" * 300_000_000, "the value of 'seed' in its campaign table is 300,000,000 "
                                "characters long (at most 256)"),
    ("k" * 257, "1", "a key in its campaign table is 257 characters long (at most 256)"),
    ("seed", None, "the value of 'seed' in its campaign table is NULL"),
], ids=["huge_seed", "long_key", "null_seed"])
def test_a_campaign_table_no_campaign_writes_is_refused_in_one_short_line(
        key: str, value: Any, said: str, tiny_spec: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The identity (spec fingerprint, seed) is read with its lengths first: a seed of 300 MB
    had been read whole and printed whole in the line refusing the other folder's seed."""
    (tmp_path / "good").mkdir()
    (tmp_path / "bad").mkdir()
    good = campaign_dir(tmp_path / "good", tiny_spec)
    bad = campaign_dir(tmp_path / "bad", tiny_spec)
    damage_identity(bad, key, value)
    line = (f"lanewarden: error: {bad / 'results.sqlite'}: {said}; expected the campaign's spec "
            "fingerprint and seed")
    assert main(["compare", str(good), str(bad)]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [line]
    stored = stored_runs(bad)
    assert main(args(tiny_spec, bad)) == 2  # resumed: refused before it claims or runs
    assert capsys.readouterr().err.strip().splitlines() == [line]
    assert stored_runs(bad) == stored


def test_a_campaign_table_of_many_entries_is_refused(tiny_spec: Path, tmp_path: Path) -> None:
    out = campaign_dir(tmp_path, tiny_spec)
    for n in range(15):  # with the spec and the seed: 17 entries
        damage_identity(out, f"extra{n}", "1")
    with ResultStore(out / "results.sqlite", read_only=True) as store:
        with pytest.raises(UnreadableRow, match="holds more than 16 entries"):
            store.identity()
    with sqlite3.connect(out / "results.sqlite") as db:
        db.execute("DELETE FROM campaign WHERE key = 'extra0'")
    db.close()
    with ResultStore(out / "results.sqlite", read_only=True) as store:
        assert store.identity()["seed"] == "7"  # 16 entries: read


def test_a_number_too_long_for_a_float_is_not_a_traceback() -> None:
    """A 401-digit integer planted as a run's closest approach had stopped `compare` and
    `--only-notable` with an OverflowError (math.isfinite of an int beyond floats: an
    attacker's review); read as inf, it is a figure no reader takes for a measurement."""
    from lanewarden.scenarios.campaign.compare import clearance_m

    planted = dict(stored_row(3), metrics_json='{"min_tape_clearance_m": 1' + "0" * 400 + "}")
    checked = checked_row(planted, "here")
    assert clearance_m(checked) is None
