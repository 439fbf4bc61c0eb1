"""run.jsonl: one JSON line per control step, written and flushed as it happens.

A crash or a kill loses at most the line being written. Usable as the control loop's `record`
callback and as a context manager. Opening failures become one-line SupervisorErrors naming the
file.
"""

from __future__ import annotations

import json
from pathlib import Path
from types import TracebackType
from typing import TextIO

from lanewarden.supervisor.errors import SupervisorError
from lanewarden.supervisor.loop import StepRecord


class JsonlRecorder:
    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            self._file: TextIO | None = self.path.open("w", encoding="utf-8")
        except OSError as exc:
            raise SupervisorError(
                f"{self.path}: cannot open the run log for writing ({exc.strerror or exc})"
            ) from exc
        self.lines = 0

    def __call__(self, record: StepRecord) -> None:
        if self._file is None:
            raise SupervisorError(f"{self.path}: run log already closed")
        try:
            self._file.write(json.dumps(record.as_json(), separators=(",", ":")) + "\n")
            self._file.flush()
        except OSError as exc:
            raise self._named(exc) from exc
        self.lines += 1

    def close(self) -> None:
        if self._file is not None:
            file, self._file = self._file, None
            try:
                file.close()
            except OSError as exc:
                raise self._named(exc) from exc

    def _named(self, exc: OSError) -> OSError:
        """The write error with this log's path (a full disk had been 'cannot write the output
        (No space left on device)', naming no file)."""
        return OSError(exc.errno, exc.strerror or str(exc), str(self.path))

    def __enter__(self) -> JsonlRecorder:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
