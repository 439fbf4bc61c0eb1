"""Survey tests compare stderr exactly: without a terminal, `scenarios.progress` prints a line
once a survey has run for `FIRST_LINE_S` of wall time, which a loaded machine could reach. Here no
progress line is ever due unless a test sets the times itself (the progress test does), so no
test depends on how fast the machine is."""

from __future__ import annotations

import pytest

from lanewarden.scenarios import progress


@pytest.fixture(autouse=True)
def _no_progress_line_due(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(progress, "FIRST_LINE_S", float("inf"))
    monkeypatch.setattr(progress, "PLAIN_EVERY_S", float("inf"))
