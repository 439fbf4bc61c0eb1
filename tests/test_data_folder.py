"""Data-dependent tests find the shared data through $LANEWARDEN_DATA and say so when they skip."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import DEFAULT_DATA, data_folder, shared_data


def test_the_environment_variable_points_at_the_data(tmp_path: Path,
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "chessboard" / "opencv-left").mkdir(parents=True)
    monkeypatch.setenv("LANEWARDEN_DATA", str(tmp_path))
    assert data_folder() == tmp_path
    assert shared_data("chessboard/opencv-left") == tmp_path / "chessboard" / "opencv-left"


def test_without_it_the_default_is_beside_the_project(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("LANEWARDEN_DATA", raising=False)
    assert data_folder() == DEFAULT_DATA
    assert DEFAULT_DATA == Path(__file__).resolve().parents[2] / "shared" / "data"


def test_a_missing_folder_skips_saying_how_to_point_at_the_data(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("LANEWARDEN_DATA", str(tmp_path / "nowhere"))
    with pytest.raises(pytest.skip.Exception) as skipped:
        shared_data("donkeycar-tub")
    message = str(skipped.value)
    assert message == (
        f"shared data not available: {tmp_path / 'nowhere' / 'donkeycar-tub'} is missing "
        f"($LANEWARDEN_DATA data folder {tmp_path / 'nowhere'}); set LANEWARDEN_DATA to the "
        "folder holding donkeycar-tub/ to run this test")
