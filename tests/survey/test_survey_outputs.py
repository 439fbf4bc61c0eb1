"""Where `lanewarden survey` writes: never among its own input, never a report cut off, and a
folder it cannot write into is found before the work, not after it."""

from __future__ import annotations

import errno
import shutil
from pathlib import Path

import pytest

from lanewarden.cli import main
from tests.conftest import PROJECT_ROOT

RENDERED = PROJECT_ROOT / "data" / "survey" / "rendered"


def _floor(folder: Path) -> Path:
    for expect, name in (("lane", "straight"), ("no-lane", "tiles")):
        (folder / expect).mkdir(parents=True)
        shutil.copy(RENDERED / expect / f"{name}.jpg", folder / expect)
    return folder


def _frames(folder: Path) -> tuple[Path, Path]:
    """A folder of two frames (a recording), and its frame labels beside it."""
    folder.mkdir()
    shutil.copy(RENDERED / "lane" / "straight.jpg", folder / "000.jpg")
    shutil.copy(RENDERED / "no-lane" / "tiles.jpg", folder / "001.jpg")
    labels = folder.parent / "frames.csv"
    labels.write_text("frames,expect\n0,lane\n1,none\n")
    return folder, labels


@pytest.mark.parametrize("case", ["no-lane/", "lane/sub", "frames/", "frames/sub", "a glob's"])
def test_out_among_the_surveys_input_is_refused(tmp_path: Path, case: str,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    """--out floor/no-lane wrote report.html and survey.json among the no-lane photos (the next
    survey: 'no-lane/report.html: not an image the survey reads'); --out into a folder of frames
    made it 'an output folder of lanewarden sim' to the next survey and replay."""
    if case in ("no-lane/", "lane/sub"):
        argv = [str(_floor(tmp_path / "floor"))]
        out, inside = tmp_path / "floor" / case, tmp_path / "floor" / case.split("/")[0]
    else:
        frames, labels = _frames(tmp_path / "frames")
        argv = [str(frames / "*.jpg") if case == "a glob's" else str(frames), "--labels",
                str(labels)]
        out, inside = frames / case.removeprefix("frames/").replace("a glob's", ""), frames
    code = main(["survey", *argv, "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err == (f"lanewarden: error: --out '{out}': inside {inside}, where the survey's "
                   "report.html and survey.json would be read as input the next time; expected "
                   "a folder outside it\n")
    assert not list(inside.rglob("*.html"))


def test_the_default_output_folder_among_the_photos_is_refused(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """`cd floor/no-lane && lanewarden survey ..` wrote lanewarden-out/ under no-lane/."""
    _floor(tmp_path / "floor")
    monkeypatch.chdir(tmp_path / "floor" / "no-lane")
    assert main(["survey", ".."]) == 2
    assert capsys.readouterr().err == (
        "lanewarden: error: the default output folder 'lanewarden-out/survey-floor' (give --out, "
        "or run the survey from another folder): inside ../no-lane, where the survey's "
        "report.html and survey.json would be read as input the next time; expected a folder "
        "outside it\n")


def test_a_disk_that_fills_up_leaves_no_report_cut_off(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """The disk full halfway through report.html had left its first part, verdict on top, beside
    a whole survey.json; exit 1. Now neither is left (nor the folder the survey made)."""
    write_text = Path.write_text

    def fill_up(path: Path, text: str, *args: object, **kwargs: object) -> int:
        if "report.html" in path.name:
            write_text(path, text[: len(text) // 2], encoding="utf-8")
            raise OSError(errno.ENOSPC, "No space left on device")
        return write_text(path, text, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(Path, "write_text", fill_up)
    out = tmp_path / "out"
    code = main(["survey", str(_floor(tmp_path / "floor")), "--out", str(out)])
    assert code == 1
    assert capsys.readouterr().err.endswith(
        "cannot write the survey's outputs (No space left on device)\n")
    assert not out.exists()


def test_a_folder_the_outputs_cannot_go_into_is_found_before_the_work(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A read-only --out was found after every frame had been analysed (minutes on a large set)."""
    import lanewarden.survey_run

    def no_work(*args: object, **kwargs: object) -> None:
        raise AssertionError("the frames were analysed before --out was found unwritable")

    monkeypatch.setattr(lanewarden.survey_run, "survey_stills", no_work)
    code = main(["survey", str(_floor(tmp_path / "floor")), "--out", "/proc/self"])
    assert code == 1
    assert capsys.readouterr().err.startswith("lanewarden: error: --out '/proc/self': cannot "
                                              "write there (")
