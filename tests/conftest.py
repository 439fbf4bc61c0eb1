"""Shared test fixtures: the folder of shared real data, and paths into it (skip with a reason
where absent).

The data folder is `$LANEWARDEN_DATA` when set, else `../shared/data` next to the project root
(where a worktree under /work finds it). It holds `chessboard/opencv-left/` and
`donkeycar-tub/` (see its README.md).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

PROJECT_ROOT = Path(__file__).resolve().parents[1]
DATA_ENV = "LANEWARDEN_DATA"
DEFAULT_DATA = PROJECT_ROOT.parent / "shared" / "data"


def data_folder() -> Path:
    """`$LANEWARDEN_DATA`, or ../shared/data beside the project root."""
    value = os.environ.get(DATA_ENV, "").strip()
    return Path(value).expanduser() if value else DEFAULT_DATA


def shared_data(relative: str) -> Path:
    """Path under the data folder, or skip the test saying where it looked and how to point it
    elsewhere."""
    folder = data_folder()
    path = folder / relative
    if not path.exists():
        source = f"${DATA_ENV}" if os.environ.get(DATA_ENV, "").strip() else "the default"
        pytest.skip(
            f"shared data not available: {path} is missing ({source} data folder {folder}); "
            f"set {DATA_ENV} to the folder holding {relative.split('/')[0]}/ to run this test"
        )
    return path
