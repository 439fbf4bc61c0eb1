"""Frame labels against a recording whose camera dropped frames (a run folder records only what
perception saw): a range labels the frames the recording has, a dropped frame is no gap in the
sequence order, and a label for a frame the recording lacks is one line naming the line."""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from lanewarden.errors import InputFileError, UsageError
from lanewarden.replay_sources import PathFrames, ReplaySource
from lanewarden.run_record import StepInput
from lanewarden.survey import parse_labels
from lanewarden.survey_source import (
    _class_folders,
    _labelled_files,
    _labelled_frames,
    open_survey_source,
)

#: frames 2, 5 and 6 were dropped; frame 3 came with two steps
RUN = ReplaySource(kind="run", name="run-1", frames=PathFrames([], 1), steps=[
    StepInput(t=k / 30.0, frame=None if i is None else (i, i / 30.0))
    for k, i in enumerate((0, 1, 3, 3, None, 4, 7))])


def test_ranges_label_the_frames_the_recording_has_in_sequence_order() -> None:
    table = parse_labels("frames,expect,note\n0-4,lane,two tapes\n7,none,tiles\n", "run.csv")
    labelled, skipped = _labelled_frames(RUN, table)
    assert skipped == [2]  # in the range 0-4, not in the recording: the survey says so
    assert {i: (f.name, f.expect, f.order, f.note) for i, f in labelled.items()} == {
        0: ("frame 0", "lane", 0, "two tapes"), 1: ("frame 1", "lane", 1, "two tapes"),
        3: ("frame 3", "lane", 2, "two tapes"), 4: ("frame 4", "lane", 3, "two tapes"),
        7: ("frame 7", "none", 4, "tiles")}


@pytest.mark.parametrize(("labels", "message"), [
    # "frames 0-7" alone had read as a contradiction: the recording has no frame 2
    ("frames,expect\n2,lane\n", "run.csv:2: frame 2 is not in run-1 (run, frames 0-7); it has no "
                                 "frame there (one dropped or skipped while recording)"),
    ("frames,expect\n0-1,lane\n5-6,none\n",
     "run.csv:3: frames 5-6: none of these frames is in run-1 (run, frames 0-7)"),
    ("frames,expect\n4-9,lane\n", "run.csv:2: frames 4-9: frame 9 is not in run-1 (run, frames "
                                  "0-7)"),
])
def test_labels_for_frames_the_recording_lacks(labels: str, message: str) -> None:
    with pytest.raises(InputFileError) as caught:
        _labelled_frames(RUN, parse_labels(labels, "run.csv"))
    assert str(caught.value) == message


def test_a_link_loop_under_a_class_folder_ends(tmp_path: Path) -> None:
    """no-lane/again -> no-lane: each image is read once, and the walk ends (a crafted folder
    must not hang the tool)."""
    (tmp_path / "lane").mkdir()
    (tmp_path / "no-lane").mkdir()
    (tmp_path / "lane" / "a.png").write_bytes(b"")
    (tmp_path / "no-lane" / "b.png").write_bytes(b"")
    (tmp_path / "no-lane" / "again").symlink_to(tmp_path / "no-lane", target_is_directory=True)
    names = [(s.frame.name, s.frame.expect) for s in _class_folders(tmp_path)[0]]
    assert names == [("lane/a.png", "lane"), ("no-lane/b.png", "none")]


def test_a_link_out_of_the_survey_folder_is_refused(tmp_path: Path) -> None:
    """no-lane/loop -> / walked the whole filesystem (23 s) and surveyed whatever images it held."""
    (tmp_path / "survey" / "no-lane").mkdir(parents=True)
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "survey" / "no-lane" / "loop").symlink_to(tmp_path / "elsewhere",
                                                          target_is_directory=True)
    with pytest.raises(InputFileError, match=r"no-lane/loop: a link to .*elsewhere, outside "):
        _class_folders(tmp_path / "survey")


def _outside_photo(tmp_path: Path) -> Path:
    """tmp_path/outside/x.png, beside the survey's folder tmp_path/survey (made here)."""
    (tmp_path / "outside").mkdir()
    (tmp_path / "outside" / "x.png").write_bytes(b"")
    _class_set(tmp_path / "survey")
    return tmp_path / "outside" / "x.png"


@pytest.mark.parametrize("link", ["lane/link.png", "lane", "no-lane/sub/link.png"])
def test_every_link_out_of_the_survey_folder_is_refused_alike(tmp_path: Path, link: str) -> None:
    """A linked photo (lane/link.png -> /elsewhere/x.png) or a linked class folder (lane ->
    /elsewhere) had been surveyed without a word while a linked folder under a class folder was
    refused: one rule for every link that is followed, one message."""
    photo = _outside_photo(tmp_path)
    survey = tmp_path / "survey"
    target = photo if link.endswith(".png") else photo.parent
    if link == "lane":
        shutil.rmtree(survey / "lane")
    (survey / link).parent.mkdir(parents=True, exist_ok=True)
    (survey / link).symlink_to(target)
    with pytest.raises(InputFileError) as caught:
        _class_folders(survey)
    assert str(caught.value) == (f"{survey / link}: a link to {target}, outside {survey}; "
                                 "expected the survey's photos inside its folder (copy them in)")


def test_links_inside_the_survey_folder_are_followed(tmp_path: Path) -> None:
    """A class folder linked to a folder inside FOLDER, a photo linked to one inside, and under
    that linked class folder a link to another folder inside FOLDER (judged against FOLDER, not
    the linked folder's parent) are surveyed; a hidden link leading out is skipped as hidden, as
    hidden files are."""
    survey = tmp_path / "survey"
    _outside_photo(tmp_path)
    # kept in hidden folders beside the class folders (images elsewhere there are an error)
    for name in (".store/lane/a.png", ".store/lane/b.png", ".extra/c.png", ".kept/d.png"):
        (survey / name).parent.mkdir(parents=True, exist_ok=True)
        (survey / name).write_bytes(name.encode())
    shutil.rmtree(survey / "lane")
    (survey / "lane").symlink_to(survey / ".store" / "lane")
    (survey / ".store" / "lane" / "more").symlink_to(survey / ".extra")
    (survey / "no-lane" / "d.png").symlink_to(survey / ".kept" / "d.png")
    (survey / "no-lane" / ".x.png").symlink_to(tmp_path / "outside" / "x.png")
    stills, hidden = _class_folders(survey)
    assert [s.frame.name for s in stills] == ["lane/a.png", "lane/b.png", "lane/more/c.png",
                                              "no-lane/c.png", "no-lane/d.png"]
    assert hidden == ["no-lane/.x.png"]


def test_a_photo_that_links_to_itself_is_one_line(tmp_path: Path) -> None:
    """A link loop as a photo, or as a labelled file: Path.resolve raised RuntimeError ("Symlink
    loop from ...", a traceback) when a labels row named one; it is a file that cannot be read."""
    _class_set(tmp_path / "classes")
    (tmp_path / "classes" / "no-lane" / "loop.png").symlink_to("loop.png")
    with pytest.raises(InputFileError, match=r"no-lane/loop\.png: cannot read file \(Too many "
                                             r"levels of symbolic links\)"):
        open_survey_source(str(tmp_path / "classes"), None, 30.0, 10**7)
    (tmp_path / "listed").mkdir()
    (tmp_path / "listed" / "loop.png").symlink_to("loop.png")
    table = parse_labels("file,expect\nloop.png,none\n", "labels.csv")
    with pytest.raises(InputFileError) as caught:
        _labelled_files(tmp_path / "listed", table)
    assert str(caught.value) == ("labels.csv:2: loop.png: cannot read file (Too many levels of "
                                 f"symbolic links) (paths are relative to {tmp_path / 'listed'})")


def test_a_labelled_files_name_reaches_the_terminal_escaped(tmp_path: Path) -> None:
    """A labels row's raw text ('\\x1b]0;pwned\\x07.png', an OSC sequence that sets the
    terminal's title) was written as it was into the error line naming it."""
    table = parse_labels("file,expect,note\n\x1b]0;pwned\x07.png,lane,x\n", "labels.csv")
    with pytest.raises(InputFileError) as caught:
        _labelled_files(tmp_path, table)
    assert str(caught.value) == ("labels.csv:2: \\x1b]0;pwned\\x07.png: no such file (paths are "
                                 f"relative to {tmp_path})")


@pytest.mark.parametrize("row, message", [
    ("../outside.png", "../outside.png: outside"),
    ("{absolute}", "expected a path relative to it, inside it"),
    ("fifo.png", "fifo.png: not a regular file (a FIFO, socket or device)"),
])
def test_a_labelled_file_must_be_a_file_inside_the_folder(tmp_path: Path, row: str,
                                                        message: str) -> None:
    """labels.csv rows reached ../../../etc/passwd and absolute paths; a FIFO hung the survey."""
    folder = tmp_path / "survey"
    folder.mkdir()
    (tmp_path / "outside.png").write_bytes(b"")
    os.mkfifo(folder / "fifo.png")
    row = row.format(absolute=tmp_path / "outside.png")
    table = parse_labels(f"file,expect\n{row},none\n", "labels.csv")
    with pytest.raises(InputFileError) as caught:
        _labelled_files(folder, table)
    assert str(caught.value).startswith(f"labels.csv:2: {row}"[:20])
    assert message in str(caught.value)


def test_a_folder_nested_deeper_than_pythons_recursion_limit_is_walked(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A crafted no-lane/ nested 1200 deep (past the default recursion limit of 1000): the image
    at the bottom is found, with no RecursionError."""
    (tmp_path / "lane").mkdir()
    (tmp_path / "lane" / "a.png").write_bytes(b"")
    (tmp_path / "no-lane").mkdir()
    monkeypatch.chdir(tmp_path / "no-lane")
    for _ in range(1200):  # one level at a time: no long path handed to the system at once
        Path("d").mkdir()
        os.chdir("d")
    Path("b.png").write_bytes(b"")
    monkeypatch.chdir(tmp_path)
    try:
        stills, _ = _class_folders(tmp_path)
        assert [s.frame.expect for s in stills] == ["lane", "none"]
        assert stills[1].frame.name == "no-lane/" + "d/" * 1200 + "b.png"
    finally:
        _remove_deep(tmp_path / "no-lane", 1200)


def _remove_deep(top: Path, depth: int) -> None:
    """Remove top/d/d/.../b.png bottom-up, one level at a time: shutil.rmtree (and so pytest's
    own clean-up of old temporary folders) recurses once per level and would fail on it."""
    os.chdir(top / ("d/" * depth))
    Path("b.png").unlink()
    for _ in range(depth):
        os.chdir("..")
        Path("d").rmdir()
    os.chdir(top.parent)


def test_a_run_frame_dropped_while_recording_is_the_frame_before_in_a_survey(
        tmp_path: Path) -> None:
    """A survey plays a run folder through `CheckedFrames`; a frame the run never recorded
    (dropped while recording) is the frame before, as `replay` gives it, not a camera error
    (a code review found every step from the gap on halted CAMERA_ERROR: AttributeError, the
    wrapper lacking the store's `undecoded`)."""
    import cv2

    from lanewarden.config import LanewardenConfig
    from lanewarden.replay import replay_steps
    from lanewarden.survey_run import CheckedFrames
    from tests.perception import synthetic as syn

    paths = []
    for i in range(12):
        paths.append(tmp_path / f"{i:06d}.png")
        if i != 5:  # frame 5 dropped while recording
            cv2.imwrite(str(paths[-1]), syn.frame(syn.STRAIGHT, 320, 240))
    run = ReplaySource(kind="run", name="run-1", frames=CheckedFrames(
        PathFrames(paths, 10**7), 10**7, None), steps=[
        StepInput(t=i / 30.0, frame=(i, i / 30.0)) for i in range(12)])
    config = LanewardenConfig()
    reasons = [step.record.halt_reason for step in replay_steps(run, config, None, "supervised")]
    assert len(reasons) == 12
    assert not any("CAMERA_ERROR" in (r or "") or "Error" in (r or "") for r in reasons), reasons


def _class_set(folder: Path) -> None:
    for name in ("lane/a.png", "lane/b.png", "no-lane/c.png"):
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(b"")


@pytest.mark.parametrize(("link", "target", "message"), [
    ("no-lane/a.png", "../lane/a.png", "no-lane/a.png is the same file as lane/a.png"),
    ("no-lane/lane", "../lane", "no-lane/lane/a.png is the same file as lane/a.png"),
    # a link back to the survey's folder itself: every lane photo had become a no-lane one too
    ("no-lane/up", "..", "no-lane/up/lane/a.png is the same file as lane/a.png"),
    ("no-lane/d.png", "c.png", "no-lane/d.png is the same file as no-lane/c.png"),
    ("no-lane/hard.png", None, "no-lane/hard.png is the same file as lane/b.png"),
])
def test_one_file_reached_twice_under_the_class_folders_is_refused(
        tmp_path: Path, link: str, target: str | None, message: str) -> None:
    """A photo linked (or hard-linked) from no-lane/ to lane/ was surveyed as both: a lane photo
    labelled no-lane is a false lane, NOT SAFE on a frame the user had labelled lane."""
    _class_set(tmp_path)
    if target is None:
        os.link(tmp_path / "lane" / "b.png", tmp_path / link)
    else:
        (tmp_path / link).symlink_to(target)
    with pytest.raises(InputFileError) as caught:
        _class_folders(tmp_path)
    assert str(caught.value).startswith(f"{tmp_path}: {message} (a link, or a hard link); "
                                        "expected each photo once")


@pytest.mark.parametrize("row", ["./a.png", "sub/../a.png", "alias.png"])
def test_one_file_labelled_twice_under_two_names_is_refused(tmp_path: Path, row: str) -> None:
    """'a.png,lane' and './a.png,none' were two frames, the second a false lane."""
    (tmp_path / "sub").mkdir()
    (tmp_path / "a.png").write_bytes(b"")
    (tmp_path / "alias.png").symlink_to("a.png")
    table = parse_labels(f"file,expect\na.png,lane\n{row},none\n", "labels.csv")
    with pytest.raises(InputFileError) as caught:
        _labelled_files(tmp_path, table)
    assert str(caught.value) == (f"labels.csv:3: {row}: the same file as line 2; expected each "
                                 "image labelled once")


def test_a_class_folder_whose_name_has_a_percent_sign_is_read(tmp_path: Path) -> None:
    """'no-lane/dim 50%/' was taken for a printf pattern ('frame_%03d.png') and its photos left
    out without a word: a false lane among them, and the survey said SAFE."""
    _class_set(tmp_path / "50% light")
    (tmp_path / "50% light" / "no-lane" / "dim 50%").mkdir()
    (tmp_path / "50% light" / "no-lane" / "dim 50%" / "d.png").write_bytes(b"")
    names = [(s.frame.name, s.frame.expect) for s in _class_folders(tmp_path / "50% light")[0]]
    assert names == [("lane/a.png", "lane"), ("lane/b.png", "lane"), ("no-lane/c.png", "none"),
                     ("no-lane/dim 50%/d.png", "none")]


def test_hidden_files_and_hidden_folders_under_a_class_folder_are_skipped_alike(
        tmp_path: Path) -> None:
    """no-lane/.thumbs/straight.png was left out without a word while no-lane/.hidden.png was
    surveyed: both are skipped now, and both named (every image under a hidden folder, however
    deep; a hidden folder's other files are no error, nor is a hidden file that is no image)."""
    _class_set(tmp_path)
    for name in ("no-lane/.thumbs/straight.png", "no-lane/.hidden.png", "lane/.thumbs/notes.txt",
                 "lane/sub/.cache/deeper/x.jpg", "lane/.DS_Store", "no-lane/._c.png"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_bytes(b"")
    stills, hidden = _class_folders(tmp_path)
    assert [(s.frame.name, s.frame.expect) for s in stills] == [
        ("lane/a.png", "lane"), ("lane/b.png", "lane"), ("no-lane/c.png", "none")]
    assert hidden == ["lane/sub/.cache/deeper/x.jpg", "no-lane/._c.png", "no-lane/.hidden.png",
                      "no-lane/.thumbs/straight.png"]


def test_folders_beside_the_class_folders_matter_only_for_their_images(tmp_path: Path) -> None:
    """A survey folder kept in git (.git/HEAD) or with notes (docs/notes.txt) beside lane/ and
    no-lane/ was refused: "not an image the survey reads (a file under a class folder ...)",
    which it is not. A hidden folder there is passed over (images and all: it is no class); any
    other folder is looked into for images only: images there are still an unknown class. A
    link in such a folder, or in or as a hidden folder under a class folder, is not followed (a
    link to /tmp in no-lane/.thumbs/ had refused the survey as a link outside FOLDER)."""
    _class_set(tmp_path)
    for name in (".git/HEAD", ".git/objects/x.png", "docs/notes.txt", "docs/old/readme.md"):
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_bytes(b"")
    stills, hidden = _class_folders(tmp_path)
    assert [s.frame.name for s in stills] == ["lane/a.png", "lane/b.png", "no-lane/c.png"]
    assert hidden == []
    # links there are not followed: a link to a folder outside FOLDER is no error there
    (tmp_path / "docs" / "tmp").symlink_to("/tmp")
    (tmp_path / "no-lane" / ".thumbs").mkdir()
    (tmp_path / "no-lane" / ".thumbs" / "out").symlink_to("/tmp")
    (tmp_path / "no-lane" / ".cache").symlink_to("/tmp")
    stills, hidden = _class_folders(tmp_path)
    assert [s.frame.name for s in stills] == ["lane/a.png", "lane/b.png", "no-lane/c.png"]
    assert hidden == []
    (tmp_path / "docs" / "old" / "shot.jpg").write_bytes(b"")
    with pytest.raises(UsageError, match=r"docs: unknown class folder 'docs' with 1 image; "
                                         r"expected lane/ or no-lane/$"):
        _class_folders(tmp_path)


@pytest.mark.parametrize("target", ["/dev/null", "missing.csv", "labels.csv"])
def test_a_labels_csv_that_is_no_file_is_named(tmp_path: Path, target: str) -> None:
    """FOLDER/labels.csv linked to a device, to nothing or to itself had been passed over: 'no
    images in lane/ or no-lane/ and no labels.csv'."""
    (tmp_path / "labels.csv").symlink_to(target)
    with pytest.raises(InputFileError) as caught:
        open_survey_source(str(tmp_path), None, 30.0, 10**7)
    # named as the folder's own file: no --labels was given
    assert re.fullmatch(rf"{tmp_path}/labels\.csv: (not a regular file .*|no such file|cannot "
                        r"read \(Too many levels of symbolic links\))", str(caught.value))


class _TwoSizes(PathFrames):
    """Frame 1 decodes at another size than frame 0 (a JPEG turned by its EXIF orientation in a
    folder of frames: its header passed the one-size check)."""

    def image(self, index: int) -> np.ndarray | None:
        return np.zeros((320, 240, 3) if index == 1 else (240, 320, 3), np.uint8)


def test_a_recordings_frame_of_another_size_is_a_problem_without_a_calibration() -> None:
    from lanewarden.survey_run import CheckedFrames

    checked = CheckedFrames(_TwoSizes([], 10**7), 10**7, None, (320, 240))
    assert checked.image(0) is not None and checked.problem is None
    assert checked.image(1) is None
    assert checked.problem == "frame 1: decoded as 240x320; the first frame is 320x240"


def test_a_frame_is_named_in_one_line_whatever_its_file_is_called(tmp_path: Path) -> None:
    """A photo named 'fake<newline>lane.jpg' split the NOT SAFE line (and the error line naming
    an unreadable photo) in two; an ESC in a name reached the terminal."""
    _class_set(tmp_path)
    (tmp_path / "no-lane" / "fake\nlane.png").write_bytes(b"")
    (tmp_path / "no-lane" / "red\x1b[31m.png").write_bytes(b"")
    names = [s.frame.name for s in _class_folders(tmp_path)[0]]
    assert names[2:] == ["no-lane/c.png", "no-lane/fake\\nlane.png", "no-lane/red\\x1b[31m.png"]
    table = parse_labels("file,expect\nno-lane/red\x1b[31m.png,none\n", "labels.csv")
    assert [s.frame.name for s in _labelled_files(tmp_path, table)] == ["no-lane/red\\x1b[31m.png"]


def test_a_labels_files_folder_nested_deeper_than_pythons_recursion_limit_is_looked_through(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The images a labels file leaves out were found with Path.rglob, which recursed once per
    level: a folder 1200 deep beside labels.csv was a RecursionError traceback."""
    from lanewarden.survey_source import _unlabelled

    (tmp_path / "a.png").write_bytes(b"")
    (tmp_path / "no-lane").mkdir()
    (tmp_path / ".git").mkdir()
    (tmp_path / ".git" / "hidden.png").write_bytes(b"")
    monkeypatch.chdir(tmp_path / "no-lane")
    for _ in range(1200):
        Path("d").mkdir()
        os.chdir("d")
    Path("b.png").write_bytes(b"")
    monkeypatch.chdir(tmp_path)
    try:
        table = parse_labels("file,expect\na.png,lane\n", "labels.csv")
        assert _unlabelled(tmp_path, _labelled_files(tmp_path, table)) == [
            "no-lane/" + "d/" * 1200 + "b.png"]
    finally:
        _remove_deep(tmp_path / "no-lane", 1200)


@pytest.mark.parametrize(("files", "kind"), [
    (("run.mcap",), "a recorded run"),
    (("run.jsonl", "meta.json"), "a recorded run"),
    (("catalog_0.catalog", "images/0_cam_image_array_.jpg"), "a Donkeycar tub"),
], ids=["run", "run-format-1", "tub"])
def test_a_recording_without_labels_is_told_to_name_them(tmp_path: Path, files: tuple[str, ...],
                                                         kind: str) -> None:
    """A new user surveyed a tub without --labels and was told its images/ folder was an
    unknown class folder (expected lane/ or no-lane/), as if to rename it; a run folder got the
    line for an empty folder."""
    for name in files:
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_bytes(b"")
    with pytest.raises(UsageError) as caught:
        open_survey_source(str(tmp_path), None, 30.0, 10**7)
    assert str(caught.value) == (f"FOLDER '{tmp_path}': {kind}; a recording needs --labels FILE "
                                 "(frames,expect[,note]: which of its frames show the lane)")


def test_a_labelled_file_misspelt_gets_the_closest_name_in_its_folder(tmp_path: Path) -> None:
    """A typo in a labels file's name said 'no such file' alone (a new user's review)."""
    (tmp_path / "lane").mkdir()
    (tmp_path / "lane" / "shot_01.jpg").write_bytes(b"")
    table = parse_labels("file,expect\nlane/shot_1.jpg,lane\nlane/other.jpg,none\n",
                         "labels.csv")
    with pytest.raises(InputFileError) as caught:
        _labelled_files(tmp_path, table)
    assert str(caught.value) == ("labels.csv:2: lane/shot_1.jpg: no such file; did you mean "
                                 f"lane/shot_01.jpg? (paths are relative to {tmp_path})")
    table = parse_labels("file,expect\nlane/other.jpg,none\n", "labels.csv")
    with pytest.raises(InputFileError) as caught:
        _labelled_files(tmp_path, table)
    assert str(caught.value) == ("labels.csv:2: lane/other.jpg: no such file (paths are "
                                 f"relative to {tmp_path})")
