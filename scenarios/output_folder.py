"""A folder a run writes a known set of files into, never mixing old and new outputs.

`begin()` creates the folder (and missing parents), deletes the files of that set left by an
earlier run (only those: anything else in the folder is the user's and stays), and writes a
`PARTIAL` marker naming every output. `finish()` deletes the marker once all outputs are complete.
So after an interrupted or failed run the folder says which of its files are incomplete, and a
complete folder never holds a stale file from another run (e.g. an old video.mp4 beside a new
`--no-video` run's metrics).

File I/O only; the caller decides what the outputs are. A folder it cannot write is a runtime
failure (ScenarioOutputError, exit 1), as every command says of an output it cannot write.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from lanewarden.scenarios.errors import ScenarioOutputError

PARTIAL = "PARTIAL"


class OutputFolder:
    """`files`: output names in the folder; `subfolders`: folders of nested runs, each with its
    own marker (listed in this one's)."""

    def __init__(self, folder: Path, files: Sequence[str],
                 subfolders: Sequence[str] = ()) -> None:
        self.folder = folder
        self.files = tuple(files)
        self.subfolders = tuple(subfolders)

    @property
    def marker(self) -> Path:
        return self.folder / PARTIAL

    def begin(self) -> None:
        """Create the folder, clear this set's old files, write the PARTIAL marker."""
        lines = [
            "This folder's outputs are incomplete: the run writing them did not finish",
            "(interrupted or failed). These files are missing, partial or from no run at all:",
            *(f"  {name}" for name in self.files),
            *(f"  {name}/ (see {name}/{PARTIAL} if it is there)" for name in self.subfolders),
            "",
        ]
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            for name in (*self.files, PARTIAL):
                (self.folder / name).unlink(missing_ok=True)
            self.marker.write_text("\n".join(lines), encoding="utf-8")
        except OSError as exc:
            raise ScenarioOutputError(
                f"{self.folder}: cannot prepare the output folder ({exc})") from exc

    def note(self, line: str) -> None:
        """One more line in the PARTIAL marker (an output written outside the folder)."""
        try:
            with self.marker.open("a", encoding="utf-8") as marker:
                marker.write(f"  {line}\n")
        except OSError as exc:
            raise ScenarioOutputError(f"{self.marker}: cannot write ({exc})") from exc

    def finish(self) -> None:
        """All outputs are complete: remove the marker."""
        try:
            self.marker.unlink(missing_ok=True)
        except OSError as exc:
            raise ScenarioOutputError(f"{self.marker}: cannot remove ({exc})") from exc
