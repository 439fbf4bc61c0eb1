"""A campaign's results: one SQLite file, one row per run, written as each run finishes.

Each row is committed on its own, so an interrupted campaign (Ctrl-C, a killed process, a lost
machine) keeps every run that finished, and running the same campaign again runs only what is
missing or ended in `error`. The `campaign` table holds what the directory is for (the spec's
fingerprint and the seed): a different campaign is refused rather than mixed in.

Never runs anything; only the campaign shell writes here.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from lanewarden.scenarios.errors import ScenarioError

COLUMNS: tuple[tuple[str, str], ...] = (
    ("id", "TEXT PRIMARY KEY"), ("idx", "INTEGER"), ("scenario", "TEXT"), ("camera", "TEXT"),
    ("floor", "TEXT"), ("tape", "TEXT"), ("effect", "TEXT"),
    ("seed", "INTEGER"), ("fault_kinds", "TEXT"), ("outcome", "TEXT"), ("reason", "TEXT"),
    ("halt_reason", "TEXT"), ("halt_time_s", "REAL"), ("time_to_halt_s", "REAL"),
    ("sim_time_s", "REAL"), ("frames", "INTEGER"), ("cpu_s", "REAL"), ("wall_s", "REAL"),
    ("worker", "TEXT"), ("metrics_json", "TEXT"), ("effects_json", "TEXT"),
)
COLUMN_NAMES = tuple(name for name, _ in COLUMNS)


class CampaignMismatch(ScenarioError):
    """The output directory already holds another campaign (a bad --out: exit 2)."""


class ResultStore:
    """DIR/results.sqlite. Use as a context manager."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self._db = sqlite3.connect(path)
            self._db.execute(f"CREATE TABLE IF NOT EXISTS runs "
                             f"({', '.join(f'{n} {t}' for n, t in COLUMNS)})")
            # A results file from before a column existed gets it (empty for its old rows).
            have = {row[1] for row in self._db.execute("PRAGMA table_info(runs)")}
            for name, kind in COLUMNS:
                if name not in have:
                    self._db.execute(f"ALTER TABLE runs ADD COLUMN {name} {kind}")
            self._db.execute("CREATE TABLE IF NOT EXISTS campaign (key TEXT PRIMARY KEY, "
                             "value TEXT)")
            self._db.commit()
        except sqlite3.Error as exc:
            raise ScenarioError(f"{path}: cannot open the results database ({exc})") from None

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._db.close()

    def claim(self, identity: Mapping[str, str]) -> None:
        """Mark the directory as holding this campaign, or refuse another one."""
        stored = dict(self._db.execute("SELECT key, value FROM campaign").fetchall())
        for key, value in identity.items():
            if key in stored and stored[key] != value:
                raise CampaignMismatch(
                    f"{self.path}: holds another campaign ({key} {stored[key]!r}, this one "
                    f"{value!r}): use another --out directory")
        self._db.executemany("INSERT OR REPLACE INTO campaign VALUES (?, ?)",
                             list(identity.items()))
        self._db.commit()

    def put(self, row: Mapping[str, Any]) -> None:
        """Store one run's row (replacing an earlier attempt of the same case) and commit."""
        values = [row.get(name) for name in COLUMN_NAMES]
        self._db.execute(f"INSERT OR REPLACE INTO runs ({', '.join(COLUMN_NAMES)}) VALUES "
                         f"({', '.join('?' for _ in COLUMN_NAMES)})", values)
        self._db.commit()

    def done_ids(self) -> set[str]:
        """Cases with a stored result that is not an error (those are not run again)."""
        return {r[0] for r in self._db.execute("SELECT id FROM runs WHERE outcome != 'error'")}

    def rows(self, ids: Iterable[str] | None = None) -> list[dict[str, Any]]:
        cursor = self._db.execute(f"SELECT {', '.join(COLUMN_NAMES)} FROM runs ORDER BY idx")
        wanted = None if ids is None else set(ids)
        return [dict(zip(COLUMN_NAMES, r, strict=True)) for r in cursor
                if wanted is None or r[0] in wanted]
