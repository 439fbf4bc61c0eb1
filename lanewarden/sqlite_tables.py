"""Whether a table in a SQLite file someone handed us holds its rows, or computes them.

A view, a virtual table or a generated column makes work the file does not hold: a recursive
view never ends (`compare` once wrote a sort file in /var/tmp until the disk was full, deaf to
Ctrl-C), and a generated column of `zeroblob(10**9)` makes a gigabyte per row. The readers of
such files (rosbag2 `.db3` bags, a campaign's `results.sqlite`) refuse them before reading a row.

Reads the schema only; never reads a row or changes the file.
"""

from __future__ import annotations

import sqlite3

from lanewarden.documents import shorten


def computed_table(connection: sqlite3.Connection, table: str, *,
                   required: bool = True) -> str | None:
    """What keeps `table` from being a table whose rows are stored in the file ("no 'runs'
    table", "'runs' is a view, not a table", "'runs' is a virtual table, not a table", "'runs'
    has computed columns (a, b)"), or None when it is one (or, not `required`, is absent).
    sqlite3.Error propagates (a damaged schema)."""
    row = connection.execute("SELECT type, sql FROM sqlite_master WHERE name = ? "
                             "COLLATE NOCASE", (table,)).fetchone()
    if row is None:
        return f"no '{table}' table" if required else None
    kind, sql = row
    if kind != "table" or str(sql).lstrip().upper().startswith("CREATE VIRTUAL"):
        return f"'{table}' is a {'virtual table' if kind == 'table' else kind}, not a table"
    computed = [str(column[1]) for column in connection.execute(f"PRAGMA table_xinfo({table})")
                if column[6]]
    if computed:
        return f"'{table}' has computed columns ({shorten(', '.join(computed))})"
    return None
