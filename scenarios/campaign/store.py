"""A campaign's results: one SQLite file, one row per run, written as each run finishes.

Each row is committed on its own, so an interrupted campaign (Ctrl-C, a killed process, a lost
machine) keeps every run that finished, and running the same campaign again runs only what is
missing or ended in `error`. The `campaign` table holds what the directory is for (the spec's
fingerprint and the seed): a different campaign is refused rather than mixed in.

Nothing stored is lost to damage (a bad disk, a copy cut short, a page overwritten):
- the file is checked when opened (`PRAGMA quick_check`, bounded by the file's size): a damaged
  one is refused in one line (`DamagedResults`, exit 2) and left exactly as it is;
- `recover=True` keeps it as `results.sqlite.damaged` (`-2`, `-3`, ... if taken) and copies every
  row that can still be read into a new file (scanning the table from both ends and looking up
  every id its index still knows), so the campaign reruns only what was lost;
- a row that cannot be written (the file went bad or the disk filled during the campaign) goes
  to `results.unstored.jsonl` beside it instead, and the campaign stops with one line; the next
  campaign in that directory stores those rows first.

Every row a reader gets (`iter_rows`: compare, --only-notable, a resumed campaign's counts and
its report) is checked in one place, `stored_row.checked_row`, and a field longer than any run
writes is measured in SQL and never fetched: a row no campaign writes is refused in one line
naming this file and the run (`UnreadableRow`, exit 2), the same for every command.

Another program may read the file while a campaign writes it (`sqlite3`, a database viewer, a
script): a reader holds SQLite's shared lock while it reads, and each write waits for it, up to
`LOCK_WAIT_S` (SQLite's busy timeout; Python's default is 5 s, and a campaign once stopped on a
reader's loop). A reader that keeps its lock longer still makes the write fail: the row is kept
as above, and the one line says the file is locked by another program.

Never runs anything; only the campaign shell writes here.
"""

from __future__ import annotations

import json
import sqlite3
from collections import Counter
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any, TextIO

from lanewarden.documents import read_json
from lanewarden.scenarios.campaign.stored_row import (
    MAX_METRICS_CHARS,
    Oversized,
    UnreadableRow,
    checked_row,
    field_limit,
)
from lanewarden.scenarios.errors import ScenarioError
from lanewarden.sqlite_tables import computed_table

COLUMNS: tuple[tuple[str, str], ...] = (
    ("id", "TEXT PRIMARY KEY"), ("idx", "INTEGER"), ("scenario", "TEXT"), ("camera", "TEXT"),
    ("floor", "TEXT"), ("tape", "TEXT"), ("effect", "TEXT"),
    ("seed", "INTEGER"), ("fault_kinds", "TEXT"), ("outcome", "TEXT"), ("reason", "TEXT"),
    ("halt_reason", "TEXT"), ("halt_time_s", "REAL"), ("time_to_halt_s", "REAL"),
    ("sim_time_s", "REAL"), ("frames", "INTEGER"), ("cpu_s", "REAL"), ("wall_s", "REAL"),
    ("worker", "TEXT"), ("metrics_json", "TEXT"), ("effects_json", "TEXT"),
)
COLUMN_NAMES = tuple(name for name, _ in COLUMNS)
#: How long a write waits for another program's read of the file to end, seconds.
LOCK_WAIT_S = 600.0
#: Rows that could not be written, beside the database (a name of its own, never overwritten).
UNSTORED_SUFFIX = ".unstored.jsonl"
DAMAGED_SUFFIX = ".damaged"


def _bounded_select(have: Iterable[str] = COLUMN_NAMES) -> str:
    """The query a reader reads runs with: each column's value only when it is no longer than
    `stored_row.field_limit` (else NULL), then every column's length, so a damaged field of
    hundreds of MB never reaches Python (a 300 MB reason had taken 3 GB to read). SQLite 3.40's
    length() still reads a text once to count its characters (a blob's comes from the record
    header), bounded by SQLite's own limit on a value (1 GB). A column the file lacks (a file
    from before it existed) reads as empty."""
    present = set(have)
    names = [n if n in present else "NULL" for n in COLUMN_NAMES]
    values = [f"CASE WHEN length({n}) > {field_limit(c)} THEN NULL ELSE {n} END"
              for n, c in zip(names, COLUMN_NAMES, strict=True)]
    return f"SELECT {', '.join(values)}, {', '.join(f'length({n})' for n in names)} FROM runs"


class CampaignMismatch(ScenarioError):
    """The output directory already holds another campaign (a bad --out: exit 2)."""


class DamagedResults(ScenarioError):
    """results.sqlite cannot be read or written as it is (exit 2): nothing is changed."""


def _problem(exc: sqlite3.Error) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def _locked(exc: sqlite3.Error) -> bool:
    """Whether a write failed only because another connection held the file's lock (SQLite's
    SQLITE_BUSY or SQLITE_LOCKED, extended codes included)."""
    code = getattr(exc, "sqlite_errorcode", None)
    return code is not None and code & 0xFF in (sqlite3.SQLITE_BUSY, sqlite3.SQLITE_LOCKED)


class ResultStore:
    """DIR/results.sqlite. Use as a context manager. `recover`: see the module docstring."""

    def __init__(self, path: Path, *, recover: bool = False,
                 lock_wait_s: float = LOCK_WAIT_S, read_only: bool = False) -> None:
        self.path = path
        self._lock_wait_s = lock_wait_s
        self.recovered: Recovery | None = None
        self.unstored_path = path.with_name(path.name + UNSTORED_SUFFIX)
        self.unstored_carried = 0
        self._select = _bounded_select()
        if read_only:
            self._db = _open_read_only(path)  # its tables checked: only stored rows are read
            have = self._read(lambda db: {row[1] for row in db.execute("PRAGMA table_info(runs)")})
            if "id" not in have or "outcome" not in have:
                self._db.close()
                raise ScenarioError(f"{path}: not a campaign's results (no table of runs)")
            self._select = _bounded_select(have)
            return
        problem = _damage(path) if path.exists() else None
        if problem is None and path.exists():
            _refuse_computed_tables(path)  # before a row is read or written (damaged: below)
        if problem is not None:
            if not recover:
                raise DamagedResults(
                    f"{path}: the results database is damaged ({problem}); nothing was changed: "
                    "run the same command with --recover to keep it as "
                    f"{path.name}{DAMAGED_SUFFIX}, carry over every run that can still be "
                    "read and rerun the rest")
            self.recovered = _recover(path)
        try:
            self._db = sqlite3.connect(path, timeout=lock_wait_s)
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
            raise ScenarioError(f"{path}: cannot open the results database "
                                f"({_problem(exc)})") from None
        if self.recovered is not None:
            recovered = self.recovered
            self._write(lambda db: (self._insert(db, recovered.rows), db.executemany(
                "INSERT OR REPLACE INTO campaign VALUES (?, ?)",
                list(recovered.identity.items()))))
            recovered.rows = []  # stored now (one transaction); the count stays
        self.unstored_carried = self._store_unstored()

    def __enter__(self) -> ResultStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._db.close()

    def identity(self) -> dict[str, str]:
        """What the directory holds (`claim`: the spec's fingerprint, the seed); {} for a file
        from before it was kept. UnreadableRow when the `campaign` table holds what no campaign
        writes (`identity_read`)."""
        have = self._read(lambda db: db.execute(
            "SELECT name FROM sqlite_master WHERE type = 'table' AND name = 'campaign'").fetchall())
        if not have:
            return {}
        return identity_read(self._read(lambda db: db.execute(_IDENTITY_SELECT).fetchall()),
                             self.path)

    def claim(self, identity: Mapping[str, str]) -> None:
        """Mark the directory as holding this campaign, or refuse another one."""
        stored = self.identity()
        for key, value in identity.items():
            if key in stored and stored[key] != value:
                what = (f"its spec or --config differ (fingerprint {stored[key]!r}, this one "
                        f"{value!r})" if key == "spec" else
                        f"{key} {stored[key]!r}, this one {value!r}")
                raise CampaignMismatch(
                    f"{self.path}: holds another campaign ({what}): use another --out "
                    "directory, or the same spec, --config and --seed to resume it")
        self._write(lambda db: db.executemany("INSERT OR REPLACE INTO campaign VALUES (?, ?)",
                                              list(identity.items())))

    @staticmethod
    def _insert(db: sqlite3.Connection, rows: Iterable[Mapping[str, Any]]) -> None:
        db.executemany(f"INSERT OR REPLACE INTO runs ({', '.join(COLUMN_NAMES)}) VALUES "
                       f"({', '.join('?' for _ in COLUMN_NAMES)})",
                       ([row.get(name) for name in COLUMN_NAMES] for row in rows))

    def put(self, row: Mapping[str, Any]) -> None:
        """Store one run's row (replacing an earlier attempt of the same case) and commit; a row
        that cannot be written goes to results.unstored.jsonl, and DamagedResults says so."""
        try:
            self._insert(self._db, [row])
            self._db.commit()
        except sqlite3.Error as exc:
            kept = self._keep_unstored(row)
            if _locked(exc):
                raise DamagedResults(
                    f"{self.path}: cannot store run {row.get('id')}: another program kept the "
                    f"file locked for longer than {self._lock_wait_s:g} s (a reader that holds "
                    f"its query open): {kept}; close it and run the same command again"
                ) from None
            raise DamagedResults(
                f"{self.path}: cannot store run {row.get('id')} ({_problem(exc)}): {kept}; run "
                "the same command again (with --recover if the database is damaged)") from None

    def done_ids(self, below_index: int | None = None) -> set[str]:
        """Cases with a stored result that is not an error (those are not run again)."""
        query = "SELECT id FROM runs WHERE outcome != 'error'"
        args: tuple[int, ...] = ()
        if below_index is not None:
            query, args = query + " AND idx < ?", (below_index,)
        return self._read(lambda db: {r[0] for r in db.execute(query, args)})

    def extent(self) -> tuple[int, int]:
        """How many runs are stored (in error or not), and the --runs that covers them all (the
        highest stored index + 1; 0 when none is stored)."""
        count, last = self._read(lambda db: db.execute(
            "SELECT count(*), max(idx) FROM runs").fetchone())
        return int(count), 0 if last is None else int(last) + 1

    def outcome_counts(self, below_index: int) -> Counter[str]:
        """How many stored runs (not in error) of the first `below_index` have each outcome."""
        return self._read(lambda db: Counter(dict(db.execute(
            "SELECT outcome, count(*) FROM runs WHERE outcome != 'error' AND idx < ? GROUP BY "
            "outcome", (below_index,)))))

    def iter_rows(self, below_index: int | None = None) -> Iterator[dict[str, Any]]:
        """Every row (of the runs with an index below `below_index`), by index, one at a time,
        each checked as every reader checks it (`stored_row.checked_row`: UnreadableRow naming
        this file and the run, for a row no campaign writes)."""
        query: str = f"{self._select} ORDER BY idx"
        args: tuple[int, ...] = ()
        if below_index is not None:
            query, args = f"{self._select} WHERE idx < ? ORDER BY idx", (below_index,)
        try:
            for values in self._db.execute(query, args):
                yield checked_row(_row_read(values), str(self.path))
        except sqlite3.Error as exc:
            raise DamagedResults(f"{self.path}: cannot read the results ({_problem(exc)}); run "
                                 "the same command with --recover") from None

    def check(self) -> None:
        """UnreadableRow for the first stored row no campaign writes (`iter_rows`), before a
        resumed campaign counts what it holds or runs what is missing: a damaged row must not
        stop it with a traceback, drop out of its counts, or make it look safer."""
        for _ in self.iter_rows():
            pass

    def rows(self, ids: Iterable[str] | None = None) -> list[dict[str, Any]]:
        wanted = None if ids is None else set(ids)
        return [r for r in self.iter_rows() if wanted is None or r["id"] in wanted]

    # ---- damage ------------------------------------------------------------------------------
    def _read(self, query: Any) -> Any:
        try:
            return query(self._db)
        except sqlite3.Error as exc:
            raise DamagedResults(f"{self.path}: cannot read the results ({_problem(exc)}); run "
                                 "the same command with --recover") from None

    def _write(self, change: Any) -> None:
        try:
            change(self._db)
            self._db.commit()
        except sqlite3.Error as exc:
            raise DamagedResults(f"{self.path}: cannot write ({_problem(exc)}); run the same "
                                 "command with --recover") from None

    def _keep_unstored(self, row: Mapping[str, Any]) -> str:
        try:
            with self.unstored_path.open("a", encoding="utf-8") as out:
                out.write(json.dumps(dict(row), default=str) + "\n")
        except OSError as exc:
            return f"it could not be kept in {self.unstored_path} either ({exc.strerror})"
        return f"its result is kept in {self.unstored_path}"

    def _store_unstored(self) -> int:
        """Rows an earlier campaign could not store: into the database, then the file goes."""
        if not self.unstored_path.exists():
            return 0
        rows = []
        with self.unstored_path.open(encoding="utf-8", errors="replace") as stream:
            for line in _bounded_lines(stream, MAX_UNSTORED_LINE_CHARS):
                try:
                    row = read_json(line)
                    checked_row(row, "")  # (the row as every reader would check it)
                except (ValueError, RecursionError, TypeError, AttributeError, UnreadableRow):
                    continue  # a line cut short when the disk filled, or damaged: rerun it
                rows.append(row)
        self._write(lambda db: self._insert(db, rows))  # one transaction; the file stays if not
        self.unstored_path.unlink()
        return len(rows)


#: The longest line of results.unstored.jsonl read, characters: a row's fields at their limits
#: (`stored_row.field_limit`) and more; a longer line is damage, its run is rerun.
MAX_UNSTORED_LINE_CHARS = 4 * MAX_METRICS_CHARS


def _bounded_lines(stream: TextIO, limit: int) -> Iterator[str]:
    """The lines of `stream` no longer than `limit` characters; a longer one is skipped without
    holding it (a damaged or hostile file's line of gigabytes)."""
    while line := stream.readline(limit + 1):
        if len(line) <= limit or line.endswith("\n"):  # (a whole line of at most `limit`)
            yield line
            continue
        while (rest := stream.readline(limit)) and not rest.endswith("\n"):
            pass  # (the rest of the long line, a piece at a time)


#: The `campaign` table holds a campaign's identity: two keys (the spec's fingerprint, the seed)
#: of a few characters each. More entries than this, or a key or value longer than this, are no
#: campaign's: such a value is never fetched (a seed of 300 MB had been read whole and printed in
#: the line refusing another seed).
MAX_IDENTITY_ENTRIES = 16
MAX_IDENTITY_CHARS = 256
_IDENTITY_SELECT = (
    f"SELECT CASE WHEN length(key) > {MAX_IDENTITY_CHARS} THEN NULL ELSE key END, "
    f"CASE WHEN length(value) > {MAX_IDENTITY_CHARS} THEN NULL ELSE value END, length(key), "
    f"length(value) FROM campaign LIMIT {MAX_IDENTITY_ENTRIES + 1}")


def identity_read(rows: list[tuple[Any, ...]], path: Path) -> dict[str, str]:
    """The identity `_IDENTITY_SELECT`'s `rows` hold, or UnreadableRow (one line naming the file
    at `path`) for more entries than MAX_IDENTITY_ENTRIES or an entry longer than
    MAX_IDENTITY_CHARS."""
    expected = "expected the campaign's spec fingerprint and seed"
    if len(rows) > MAX_IDENTITY_ENTRIES:
        raise UnreadableRow(f"{path}: its campaign table holds more than {MAX_IDENTITY_ENTRIES} "
                            f"entries; {expected}")
    for key, value, key_length, value_length in rows:
        if key is None or value is None:
            name = "a key" if key is None else f"the value of {str(key)!r}"
            length = key_length if key is None else value_length
            what = "is NULL" if length is None else (
                f"is {length:,} characters long (at most {MAX_IDENTITY_CHARS})")
            raise UnreadableRow(f"{path}: {name} in its campaign table {what}; {expected}")
    return {str(key): str(value) for key, value, _, _ in rows}


# ---- checking and recovering a damaged file ---------------------------------------------------
class Recovery:
    """What `recover` carried over: `rows` (before they are stored), `count`, the campaign's
    `identity` when it could be read, `kept_as`: where the damaged file went."""

    def __init__(self, rows: list[dict[str, Any]], identity: dict[str, str], kept_as: Path,
                 lost_ids: int) -> None:
        self.rows = rows
        self.count = len(rows)
        self.identity = identity
        self.kept_as = kept_as
        self.lost_ids = lost_ids


#: The first bytes of every SQLite database file.
_SQLITE_HEADER = b"SQLite format 3\x00"


def results_in(folder: Path) -> Path:
    """A campaign folder's results.sqlite (the file itself may be given instead)."""
    return folder if folder.is_file() else folder / "results.sqlite"


def _read_only_uri(path: Path) -> str:
    """SQLite's URI of `path` for reading only (a '?' or '#' in a folder's name is quoted)."""
    return f"{path.resolve().as_uri()}?mode=ro"


def _open_read_only(path: Path) -> sqlite3.Connection:
    """The results file opened for reading only (nothing is created or changed): a missing or
    damaged file is refused in one line."""
    if not path.is_file():
        raise ScenarioError(f"{path}: no campaign results here (expected the results.sqlite a "
                            "`lanewarden campaign --out` folder holds)")
    try:
        with path.open("rb") as file:
            header = file.read(len(_SQLITE_HEADER))
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read ({exc.strerror})") from None
    if header != _SQLITE_HEADER and header:
        raise ScenarioError(f"{path}: not a results database (expected the results.sqlite a "
                            "`lanewarden campaign --out` folder holds)")
    problem = _damage(path)
    if problem is not None:
        raise DamagedResults(f"{path}: the results database is damaged ({problem}); run the "
                             "campaign that wrote it again with --recover first")
    _refuse_computed_tables(path)
    try:
        return sqlite3.connect(_read_only_uri(path), uri=True)
    except sqlite3.Error as exc:
        raise ScenarioError(f"{path}: cannot open the results database "
                            f"({_problem(exc)})") from None


#: The tables a campaign writes; each must hold its rows (`computed_table`) when present.
_TABLES = ("runs", "campaign")


def _refuse_computed_tables(path: Path) -> None:
    """DamagedResults (one line, exit 2; nothing read or changed) when `runs` or `campaign` in
    the (undamaged) file at `path` is a view, a virtual table or has generated columns: their
    rows would be computed on every read, without bound (a recursive view never ends). A file
    without them is left to its reader (a new store creates them; a reader refuses a file
    without `runs`)."""
    try:
        db = sqlite3.connect(_read_only_uri(path), uri=True)
    except sqlite3.Error as exc:
        raise ScenarioError(f"{path}: cannot open the results database "
                            f"({_problem(exc)})") from None
    try:
        found = _computed(db)
    except sqlite3.Error as exc:
        found = f"its tables cannot be read ({_problem(exc)})"
    finally:
        db.close()
    if found is not None:
        raise DamagedResults(f"{path}: {found}; expected the tables `lanewarden campaign` "
                             "writes (their rows stored in the file); nothing was read or "
                             "changed")


def _damage(path: Path) -> str | None:
    """Why the file at `path` is not a sound results database, or None."""
    try:
        db = sqlite3.connect(_read_only_uri(path), uri=True)
    except sqlite3.Error as exc:
        return _problem(exc)
    try:
        result = db.execute("PRAGMA quick_check(3)").fetchall()
        if [r[0] for r in result] != ["ok"]:
            # quick_check's rows may hold newlines: the problem is one line of the error
            return " ".join("; ".join(str(r[0]) for r in result).split())[:200]
        return None
    except sqlite3.Error as exc:
        return _problem(exc)
    finally:
        db.close()


def _computed(db: sqlite3.Connection) -> str | None:
    """What makes `runs` or `campaign` compute its rows (`computed_table`), the first found; None
    when both hold theirs or are absent. sqlite3.Error propagates (an unreadable schema)."""
    return next(filter(None, (computed_table(db, table, required=False) for table in _TABLES)),
                None)


def _computes_rows(db: sqlite3.Connection) -> bool:
    """Whether `runs` or `campaign` computes its rows (False when the schema cannot be read: the
    scans then find what they can)."""
    try:
        return _computed(db) is not None
    except sqlite3.Error:
        return False


def _scan(db: sqlite3.Connection, query: str, found: dict[str, dict[str, Any]]) -> None:
    try:
        for values in db.execute(query):
            row = _readable(values)
            if row is not None:
                found.setdefault(row["id"], row)
    except sqlite3.Error:
        pass  # the scan reached the damage: what came before is kept


def _readable(values: tuple[Any, ...]) -> dict[str, Any] | None:
    """A row read with `_bounded_select` as a campaign writes it, or None: a field longer than
    any run writes (never fetched), or a row every reader would refuse (`checked_row`). Such a
    run is not carried over but run again: recovered, it would have held every later reader
    up (a 300 MB field had also been read whole)."""
    row = _row_read(values)
    try:
        checked_row(row, "")  # (refuses an Oversized field too)
    except UnreadableRow:
        return None
    return row


def _row_read(values: tuple[Any, ...]) -> dict[str, Any]:
    """A row as `_bounded_select` reads it: each column's value, or `Oversized` (its length)
    where it was longer than `field_limit` and so not fetched."""
    width = len(COLUMN_NAMES)
    return {name: (Oversized(int(length)) if length is not None and length > field_limit(name)
                   else value)
            for name, value, length in zip(COLUMN_NAMES, values[:width], values[width:],
                                           strict=True)}


def _recover(path: Path) -> Recovery:
    """Move the damaged file aside and read back every row that can still be read."""
    kept = path.with_name(path.name + DAMAGED_SUFFIX)
    n = 2
    while kept.exists():
        kept, n = path.with_name(f"{path.name}{DAMAGED_SUFFIX}-{n}"), n + 1
    try:
        path.rename(kept)
        for suffix in ("-journal", "-wal", "-shm"):
            side = path.with_name(path.name + suffix)
            if side.exists():
                side.rename(kept.with_name(kept.name + suffix))
    except OSError as exc:
        raise DamagedResults(f"{path}: cannot keep the damaged database as {kept} "
                             f"({exc.strerror}); nothing was changed") from None
    found: dict[str, dict[str, Any]] = {}
    identity: dict[str, str] = {}
    ids: set[str] = set()
    try:
        db = sqlite3.connect(f"file:{kept}?mode=ro", uri=True)
    except sqlite3.Error:
        return Recovery([], {}, kept, 0)
    try:
        if _computes_rows(db):
            return Recovery([], {}, kept, 0)  # rows it computes are no campaign's (nor bounded)
        select = _bounded_select()
        _scan(db, f"{select} ORDER BY rowid", found)
        _scan(db, f"{select} ORDER BY rowid DESC", found)
        try:  # the primary key's own index: the ids of rows the table scans could not reach
            for (id_,) in db.execute("SELECT id FROM runs INDEXED BY sqlite_autoindex_runs_1"):
                ids.add(id_)
        except sqlite3.Error:
            pass
        for id_ in sorted(ids - set(found)):
            try:
                values = db.execute(f"{select} WHERE id = ?", (id_,)).fetchone()
            except sqlite3.Error:
                continue
            if values is not None and (row := _readable(values)) is not None:
                found[id_] = row
        try:
            identity = identity_read(db.execute(_IDENTITY_SELECT).fetchall(), kept)
        except (sqlite3.Error, UnreadableRow):
            identity = {}  # (a campaign then claims the recovered file as its own)
    finally:
        db.close()
    return Recovery(sorted(found.values(), key=lambda r: (r.get("idx") or 0, r["id"])),
                    identity, kept, len(ids - set(found)))
