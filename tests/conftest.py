"""Shared test fixtures: the folder of shared real data, and paths into it (skip with a reason
where absent); the `slow` marker, given from one list; hypothesis's profile for the mutation run.

The data folder is `$LANEWARDEN_DATA` when set, else `../shared/data` next to the project root
(where a worktree under /work finds it). It holds `chessboard/opencv-left/` and
`donkeycar-tub/` (see its README.md).

Slow tests are listed in one place, tests/slow_tests.txt (a test file, or a test by node id
without its parameters), measured with `pytest --durations=0`: `pytest -m "not slow"` is the
fast subset (DEVELOPERS.md); plain `pytest` runs everything.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import Phase, settings

PROJECT_ROOT = Path(__file__).resolve().parents[1]
DATA_ENV = "LANEWARDEN_DATA"
DEFAULT_DATA = PROJECT_ROOT.parent / "shared" / "data"
SLOW_TESTS = Path(__file__).with_name("slow_tests.txt")

# The mutation run (tests/mutation/run.py) only needs to know that a property fails, not its
# smallest counterexample: no shrinking, no explaining (the examples themselves stay the same).
settings.register_profile("mutation", phases=(Phase.explicit, Phase.reuse, Phase.generate))


def pytest_configure(config: pytest.Config) -> None:
    """Before any test (in the controller, before xdist's workers start): perception's compiled
    kernel is made ready once (`perception.line_kernel.ready`), so that no test, nor a command a
    test runs, waits for numba's compile or sees its one-line notice on stderr."""
    if not hasattr(config, "workerinput"):
        from lanewarden.perception import line_kernel

        line_kernel.ready(lambda text: print(text, file=sys.stderr))


def slow_tests(path: Path = SLOW_TESTS) -> tuple[str, ...]:
    """The listed node ids (`tests/x.py` or `tests/x.py::test_y`), comments and blanks dropped."""
    text = path.read_text(encoding="utf-8")
    entries = (line.split("#", 1)[0].strip() for line in text.splitlines())
    return tuple(entry for entry in entries if entry)


def is_slow(nodeid: str, listed: tuple[str, ...]) -> bool:
    """Whether `nodeid` is listed: itself, its file, or its test without the parameters."""
    base = nodeid.split("[", 1)[0]
    return any(base == entry or base.startswith(entry + "::") for entry in listed)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    listed = slow_tests()
    for item in items:
        if is_slow(item.nodeid, listed):
            item.add_marker(pytest.mark.slow)


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


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A real 400 KiB file system (tmpfs), mounted for the test: a full disk, not a limit."""
    disk = tmp_path / "disk"
    disk.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=400k", "tmpfs", str(disk)],
                             capture_output=True, text=True, check=False) if shutil.which(
        "mount") else None
    if mounted is None or mounted.returncode != 0:
        pytest.skip("cannot mount a small tmpfs here (needs root and CAP_SYS_ADMIN): "
                    f"{'no mount command' if mounted is None else mounted.stderr.strip()}")
    try:
        yield disk
    finally:
        subprocess.run(["umount", str(disk)], check=False)
