"""A results.sqlite whose `runs` or `campaign` computes its rows (a view, a virtual table, a
generated column) is refused in one line (exit 2) before a row is read, by every command that
reads it: `compare`, a campaign resumed in its folder, `--only-notable`, `--recover`.

Read as it was, a recursive `runs` view kept `compare` sorting rows into /var/tmp at 64 MB/s
until the disk was full, deaf to Ctrl-C (an attacker's review). The check is ros_bag's
(`lanewarden.sqlite_tables`)."""

from __future__ import annotations

import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from lanewarden.cli import main
from lanewarden.scenarios.campaign.store import COLUMN_NAMES
from tests.campaign.test_compare import BEFORE, store
from tests.campaign.test_store_damage import args, campaign_dir, damage_page

ENDLESS_RUNS = [
    "ALTER TABLE runs RENAME TO stored",
    "CREATE VIEW runs AS WITH RECURSIVE c(x) AS (SELECT 1 UNION ALL SELECT x + 1 FROM c) SELECT "
    + ", ".join("printf('r%05d', x) AS id" if c == "id" else "x AS idx" if c == "idx"
                else "'nominal' AS outcome" if c == "outcome" else f"NULL AS {c}"
                for c in COLUMN_NAMES) + " FROM c"]

STORED = [c for c in COLUMN_NAMES if c != "metrics_json"]
#: (statements turning a stored results.sqlite into a crafted one, what the one line says)
CRAFTED = {
    "view": (["ALTER TABLE runs RENAME TO stored", "CREATE VIEW runs AS SELECT * FROM stored"],
             "'runs' is a view, not a table"),
    "virtual-table": (["ALTER TABLE runs RENAME TO stored",
                       f"CREATE VIRTUAL TABLE runs USING fts5({', '.join(COLUMN_NAMES)})",
                       "INSERT INTO runs SELECT * FROM stored"],
                      "'runs' is a virtual table, not a table"),
    "generated-column": (["ALTER TABLE runs RENAME TO stored",
                          "CREATE TABLE runs (" + ", ".join(
                              f"{c} AS (zeroblob(1000))" if c == "metrics_json" else c
                              for c in COLUMN_NAMES) + ")",
                          f"INSERT INTO runs ({', '.join(STORED)}) SELECT {', '.join(STORED)} "
                          "FROM stored"],
                         "'runs' has computed columns (metrics_json)"),
    "campaign-view": (["ALTER TABLE campaign RENAME TO stored_campaign",
                       "CREATE VIEW campaign AS SELECT * FROM stored_campaign"],
                      "'campaign' is a view, not a table"),
}


def craft(path: Path, statements: list[str]) -> bytes:
    with sqlite3.connect(path) as db:
        for statement in statements:
            db.execute(statement)
    db.close()
    return path.read_bytes()


def refusal(path: Path, found: str) -> str:
    return (f"{path}: {found}; expected the tables `lanewarden campaign` writes (their rows "
            "stored in the file); nothing was read or changed")


@pytest.mark.parametrize("kind", sorted(CRAFTED))
def test_compare_refuses_a_table_that_computes_its_rows(
        kind: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    good = store(tmp_path / "good", BEFORE)
    crafted = store(tmp_path / "crafted", BEFORE)
    statements, found = CRAFTED[kind]
    content = craft(crafted / "results.sqlite", statements)
    for pair in ((good, crafted), (crafted, good)):
        assert main(["compare", *map(str, pair)]) == 2
        assert capsys.readouterr().err == (
            f"lanewarden: error: {refusal(crafted / 'results.sqlite', found)}\n")
    assert (crafted / "results.sqlite").read_bytes() == content
    assert sorted(p.name for p in crafted.iterdir()) == ["results.sqlite"]


def test_a_campaign_never_reads_nor_writes_a_results_file_that_computes_its_rows(
        tiny_spec: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Resumed in its folder, screened with --only-notable, recovered: one line, nothing run,
    nothing changed."""
    out = campaign_dir(tmp_path, tiny_spec)
    content = craft(out / "results.sqlite", CRAFTED["view"][0])
    line = f"lanewarden: error: {refusal(out / 'results.sqlite', CRAFTED['view'][1])}\n"
    assert main(args(tiny_spec, out)) == 2
    assert capsys.readouterr().err == line
    screen = tmp_path / "screen"
    assert main(args(tiny_spec, screen, "--only-notable", str(out))) == 2
    assert capsys.readouterr().err == line.replace("error: ", f"error: --only-notable {out}: ")
    assert (out / "results.sqlite").read_bytes() == content
    assert sorted(p.name for p in out.iterdir()) == ["results.sqlite"]
    assert not screen.exists()


def test_recover_carries_no_row_a_table_computes(
        tiny_spec: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A damaged file's rows are not read through computed columns either (zeroblob(10**9)
    would be a gigabyte a row): it is kept aside, as any damaged file, and nothing of it is
    carried over. (A view has no rowid: the scans of a damaged file never read one.)"""
    out = campaign_dir(tmp_path, tiny_spec)
    craft(out / "results.sqlite", CRAFTED["generated-column"][0])
    damage_page(out / "results.sqlite", 8)
    assert main(args(tiny_spec, out, "--recover", "--runs", "1")) == 0
    assert "0 stored runs carried over" in capsys.readouterr().err
    assert (out / "results.sqlite.damaged").is_file()
    with sqlite3.connect(out / "results.sqlite") as db:
        workers = [r[0] for r in db.execute("SELECT worker FROM runs")]
    db.close()
    assert len(workers) == 1 and workers != ["made-by-the-test"], "run again, not carried over"


def test_compare_of_an_endless_view_ends_at_once_in_one_line(tmp_path: Path) -> None:
    """The review's file: `runs` a recursive view without end. A separate process, so that a
    regression fails this test (after a generous while) instead of filling the disk."""
    for name in ("a", "b"):
        store(tmp_path / name, BEFORE)
        craft(tmp_path / name / "results.sqlite", ENDLESS_RUNS)
    done = subprocess.run([sys.executable, "-m", "lanewarden", "compare", "a", "b"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert (done.returncode, done.stderr) == (
        2, f"lanewarden: error: {refusal(Path('a/results.sqlite'), CRAFTED['view'][1])}\n")
