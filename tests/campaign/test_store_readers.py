"""Another program reading results.sqlite while a campaign writes it (`sqlite3`, a viewer, a
script): each write waits for the reader (SQLite's busy timeout, `LOCK_WAIT_S`), and a reader
that keeps its lock longer than that makes the store keep the row beside the file and say, in
one line, that another program holds the lock; the next campaign stores the row. A campaign once
stopped after 5 s (Python's default wait) on a reader's loop that held its query open."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from lanewarden.scenarios.campaign.store import LOCK_WAIT_S, DamagedResults, ResultStore
from tests.campaign.test_store_damage import stored_row


def test_a_write_waits_minutes_for_another_programs_read() -> None:
    assert LOCK_WAIT_S >= 60.0  # a person looking at the table, not a blink


def test_the_store_asks_sqlite_to_wait_for_readers(tmp_path: Path) -> None:
    with ResultStore(tmp_path / "results.sqlite", lock_wait_s=42.0) as store:
        assert store._db.execute("PRAGMA busy_timeout").fetchone() == (42000,)


def test_a_reader_that_keeps_its_lock_longer_is_named_and_the_row_kept(tmp_path: Path) -> None:
    path = tmp_path / "results.sqlite"
    with ResultStore(path) as store:
        store.put(stored_row(0))
    reader = sqlite3.connect(f"file:{path}?mode=ro", uri=True, isolation_level=None)
    reader.execute("BEGIN")
    assert reader.execute("SELECT id FROM runs").fetchone() == ("r00000",)  # its lock held
    try:
        with ResultStore(path, lock_wait_s=0.05) as store, \
                pytest.raises(DamagedResults) as refused:
            store.put(stored_row(1))
    finally:
        reader.execute("COMMIT")
        reader.close()
    message = str(refused.value)
    assert message == (
        f"{path}: cannot store run r00001: another program kept the file locked for longer "
        f"than 0.05 s (a reader that holds its query open): its result is kept in "
        f"{path}.unstored.jsonl; close it and run the same command again")
    with ResultStore(path) as store:  # the reader is gone: the kept row is stored
        assert store.unstored_carried == 1
        assert store.done_ids() == {"r00000", "r00001"}
