"""An empty path is refused by every command, in one line naming the flag (or argument), the
empty value and what was expected; exit 2, nothing written.

`Path("")` is `.`, the current folder, and `value or default` takes `""` for no value: `--out ""`
had written into the current folder (detect, undistort, demo), fallen back to the default folder
(sim, replay, survey; `--check-image` to its default name, replay's `--calibration` to the
recording's), been taken for `.` (`run --record`: "already exists") or been a traceback
(`sim --camera-out`); an empty SOURCE, FOLDER, `--camera` or `--images` read the current folder.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import click
import cv2
import numpy as np
import pytest

from lanewarden.cli import cli, main
from lanewarden.commands.flags import PathFlag


def path_parameters(command: click.Command, path: tuple[str, ...] = ()
                    ) -> Iterator[tuple[tuple[str, ...], click.Parameter]]:
    """(the command's words, a parameter) for every parameter that takes a path."""
    for param in command.params:
        if isinstance(param.type, click.Path):
            yield path, param
    if isinstance(command, click.Group):
        for name, sub in command.commands.items():
            yield from path_parameters(sub, (*path, name))


PATH_PARAMETERS = list(path_parameters(cli))
#: Paths typed as plain strings before (a camera may be an index or a URL, a glob is no file).
ALSO_PATHS = {("replay", "source"), ("survey", "folder"), ("run", "camera"),
              ("calibrate capture", "camera"), ("calibrate", "images")}


def test_every_path_parameter_is_a_path_flag() -> None:
    found = {(" ".join(words), param.name) for words, param in PATH_PARAMETERS}
    assert ALSO_PATHS <= found
    assert len(found) >= 25  # every --out, --config, --calibration, --record, ... of every command
    for words, param in PATH_PARAMETERS:
        assert isinstance(param.type, PathFlag), (words, param.name)


@pytest.mark.parametrize(("words", "param"), PATH_PARAMETERS,
                         ids=[f"{' '.join(w)} {p.name}" for w, p in PATH_PARAMETERS])
def test_an_empty_path_is_one_line_exit_2(words: tuple[str, ...], param: click.Parameter,
                                          tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    given = [param.opts[0], ""] if isinstance(param, click.Option) else [""]
    if isinstance(param, click.Argument):  # the arguments before it (compare's BEFORE): "."
        command: click.Command = cli
        for word in words:
            command = command.commands[word] if isinstance(command, click.Group) else command
        arguments = [p for p in command.params if isinstance(p, click.Argument)]
        given = ["."] * arguments.index(param) + given
    code = main([*words, *given])
    err = capsys.readouterr().err
    assert code == 2, err
    name = param.opts[0] if isinstance(param, click.Option) else param.human_readable_name
    assert err.count("\n") == 1 and f"Invalid value for '{name}" in err and (
        "': '' is empty; expected " in err), err
    assert list(tmp_path.iterdir()) == []


def test_detect_with_an_empty_out_writes_nothing_in_the_current_folder(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    """It had written lane_detect.png into the current folder, exit 0."""
    monkeypatch.chdir(tmp_path)
    cv2.imwrite("lane.png", np.full((480, 640), 128, np.uint8))
    assert main(["detect", "lane.png", "--out", ""]) == 2
    assert capsys.readouterr().err == ("lanewarden: error: lanewarden detect: Invalid value for "
                                       "'--out': '' is empty; expected a folder\n")
    assert [p.name for p in tmp_path.iterdir()] == ["lane.png"]


def test_a_folder_flag_given_a_file_says_what_was_expected(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """click's own refusal ("Directory 'afile' is a file.") named no expectation, unlike every
    other error (a new user's review); it now ends with what the flag takes."""
    afile = tmp_path / "afile"
    afile.write_text("")
    assert main(["sim", "--scenario", "straight", "--out", str(afile), "--quiet"]) == 2
    assert capsys.readouterr().err == (
        f"lanewarden: error: lanewarden sim: Invalid value for '--out': Directory '{afile}' is "
        "a file; expected a folder\n")
    assert main(["run", "--calibration", str(tmp_path)]) == 2
    assert capsys.readouterr().err == (
        f"lanewarden: error: lanewarden run: Invalid value for '--calibration': File "
        f"'{tmp_path}' is a directory; expected a calibration file\n")
