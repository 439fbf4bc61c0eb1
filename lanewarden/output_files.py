"""Writing one output file where something may already be: never through it.

An output's name can already be taken by a symbolic link (left in an output folder, it can point
anywhere: `detect --out` had overwritten a file outside its folder through one), by a FIFO
(opening one for writing waits for a reader: `calibrate --ros` hung), or by a device (`calibrate
--out /dev/null`, run as root, had replaced the system's /dev/null with a regular file).
`replace_file` writes into a new file beside the name, then moves it over the name: a link is
replaced, not followed, and a write that fails (a full disk) leaves what was there. A FIFO,
socket, device or folder at the name is refused, never opened nor replaced.

A leaf module (the standard library only): every layer may use it. Never
prints.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

#: Why an output is not written where a FIFO, socket or device has its name.
TAKEN_BY_A_SPECIAL_FILE = "exists as a FIFO, socket or device, not a file: choose another name"


def unreplaceable(path: Path) -> str:
    """Why an output may not be written at `path` ('' when nothing is there, or a regular file
    or a link, which `replace_file` replaces): what is there, without following a link."""
    try:
        mode = path.lstat().st_mode
    except OSError:
        return ""  # nothing there (or its folder cannot be read: writing says why)
    if stat.S_ISDIR(mode):
        return "is a folder, expected a file name"
    if stat.S_ISREG(mode) or stat.S_ISLNK(mode):
        return ""
    return TAKEN_BY_A_SPECIAL_FILE


def replace_file(path: Path, data: bytes | memoryview) -> None:
    """Write `data` as the file `path`: into a hidden file beside it (created new, with the
    permissions a new file gets), then moved over it. Raises OSError with the reason in its
    `strerror`: `unreplaceable`'s, or the system's (a full disk, a read-only folder)."""
    if why := unreplaceable(path):
        raise OSError(errno.EEXIST, why, str(path))
    partial = path.with_name(f".{path.name}.{os.getpid()}.partial")
    flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
    try:
        descriptor = os.open(partial, flags, 0o666)
    except FileExistsError:  # left by a process of this id that was killed: never ours now
        partial.unlink()
        descriptor = os.open(partial, flags, 0o666)
    try:
        with os.fdopen(descriptor, "wb") as file:
            file.write(data)
        os.replace(partial, path)
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
