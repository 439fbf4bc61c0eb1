"""Frame sources for bench runs: folders and globs of images in natural order, a recorded source
held at its first frame until the run plays it, and its end raised as a lost camera once its last
frame was read."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from lanewarden.camera_source import (
    CameraFrameSource,
    CameraLost,
    ImageSequence,
    image_sequence_paths,
    open_camera,
)
from lanewarden.errors import UsageError
from lanewarden.runner import _first_frame
from lanewarden.supervisor.errors import SupervisorError
from lanewarden.ticker import Ticker


def _images(folder: Path, names: list[str]) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for value, name in enumerate(names):
        cv2.imwrite(str(folder / name), np.full((24, 32, 3), value * 10, np.uint8))


def test_folders_and_globs_in_natural_order(tmp_path: Path) -> None:
    _images(tmp_path / "shots", ["f_10.png", "f_2.png", "f_1.jpg"])
    (tmp_path / "shots" / "notes.txt").write_text("not an image")
    names = [p.name for p in image_sequence_paths(str(tmp_path / "shots")) or []]
    assert names == ["f_1.jpg", "f_2.png", "f_10.png"]
    names = [p.name for p in image_sequence_paths(str(tmp_path / "shots" / "f_*.png")) or []]
    assert names == ["f_2.png", "f_10.png"]
    assert image_sequence_paths(str(tmp_path / "clip.mp4")) is None
    assert image_sequence_paths("frame_%03d.png") is None
    assert image_sequence_paths("rtsp://camera/stream") is None
    assert image_sequence_paths("rtsp://camera/stream?channel=1") is None


def test_a_folder_or_glob_with_a_percent_sign_is_not_a_printf_pattern(tmp_path: Path) -> None:
    """'dim 50%/' was taken for 'frame_%03d.png': its images were left out of a survey's class
    folder without a word, and 'dim 50%/*.png' was 'no such file or folder'."""
    _images(tmp_path / "dim 50%", ["f_2.png", "f_1.png"])
    for source in ("dim 50%", "dim 50%/*.png"):
        names = [p.name for p in image_sequence_paths(str(tmp_path / source)) or []]
        assert names == ["f_1.png", "f_2.png"], source


def test_an_empty_folder_is_named(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(UsageError, match="--camera .*empty.*no images there"):
        open_camera(str(tmp_path / "empty"))


def test_an_unreadable_image_ends_the_sequence_with_its_name(tmp_path: Path) -> None:
    _images(tmp_path / "s", ["a_1.png"])
    (tmp_path / "s" / "a_2.png").write_text("not a png")
    sequence = open_camera(str(tmp_path / "s"))
    assert isinstance(sequence, ImageSequence)
    assert sequence.read()[0] is True
    assert sequence.read() == (False, None)
    assert sequence.failure == f"{tmp_path / 's' / 'a_2.png'}: not a readable image"


def test_a_clip_waits_for_play_then_ends_as_a_lost_camera(tmp_path: Path) -> None:
    _images(tmp_path / "s", [f"frame_{i}.png" for i in range(4)])
    frames = CameraFrameSource(open_camera(str(tmp_path / "s")), time.monotonic, replay_fps=200.0)
    try:
        deadline = time.monotonic() + 10.0
        pause = threading.Event()
        while frames.read(time.monotonic()) is None and time.monotonic() < deadline:
            pause.wait(0.01)
        first = frames.read(time.monotonic())
        assert first is not None and first.index == 0
        held = frames.read(time.monotonic())
        assert held is not None and held.index == 0 and frames.frames_captured == 1, \
            "held at its first frame until play()"
        before_play = time.monotonic()
        frames.play()
        replayed = frames.read(time.monotonic())
        assert replayed is not None and replayed.time_s >= before_play, "fresh when it plays"
        while not frames.ended and time.monotonic() < deadline:
            pause.wait(0.01)
        assert frames.ended and frames.frames_captured == 4
        # its last frame comes before its end, whenever the reader comes
        seen = [replayed.index]
        with pytest.raises(CameraLost, match="end of the recorded clip after 4 frames"):
            for _ in range(3):
                frame = frames.read(time.monotonic())
                assert frame is not None and not frames.end_seen
                seen.append(frame.index)
        assert seen[-1] == 3 and frames.end_seen
    finally:
        frames.close()


def test_a_clips_last_frame_is_read_before_its_end(tmp_path: Path) -> None:
    """Nobody reads until the clip has ended: its last frame, never read, still comes first,
    then the end (a loop that had not read the last frame when the end came lost it, and `run`
    ended a clip with or without a CAMERA_ERROR by chance)."""
    _images(tmp_path / "s", [f"frame_{i}.png" for i in range(3)])
    frames = CameraFrameSource(open_camera(str(tmp_path / "s")), time.monotonic, replay_fps=200.0)
    try:
        frames.play()
        deadline = time.monotonic() + 10.0
        while not frames.ended and time.monotonic() < deadline:
            threading.Event().wait(0.01)
        assert frames.ended and frames.frames_captured == 3
        last = frames.read(time.monotonic())
        assert last is not None and last.index == 2 and not frames.end_seen
        with pytest.raises(CameraLost, match="end of the recorded clip after 3 frames"):
            frames.read(time.monotonic())
        assert frames.end_seen
    finally:
        frames.close()


def test_a_one_frame_clip_read_before_the_run_still_gives_the_loop_its_frame(
        tmp_path: Path) -> None:
    """The runner reads the first frame before the run (`_first_frame`); play() restamps it,
    and the loop must get it once more before the clip's end, even when that end is already
    there (a one-frame clip: it raised at once)."""
    _images(tmp_path / "s", ["frame_0.png"])
    frames = CameraFrameSource(open_camera(str(tmp_path / "s")), time.monotonic, replay_fps=200.0)
    try:
        deadline = time.monotonic() + 10.0
        while frames.read(time.monotonic()) is None and time.monotonic() < deadline:
            threading.Event().wait(0.01)
        frames.play()
        while not frames.ended and time.monotonic() < deadline:
            threading.Event().wait(0.01)
        assert frames.ended
        first = frames.read(time.monotonic())
        assert first is not None and first.index == 0 and not frames.end_seen
        with pytest.raises(CameraLost, match="end of the recorded clip after 1 frame"):
            frames.read(time.monotonic())
    finally:
        frames.close()


def _failed_live_source(tmp_path: Path, good_frames: int) -> CameraFrameSource:
    """A live source (no replay pace) over `good_frames` images then an unreadable one, returned
    once its capture thread has failed: a camera that dropped out before the run began."""
    _images(tmp_path / "s", [f"a_{i}.png" for i in range(good_frames)])
    (tmp_path / "s" / f"a_{good_frames}.png").write_text("not a png")
    frames = CameraFrameSource(open_camera(str(tmp_path / "s")), time.monotonic, replay_fps=None)
    deadline = time.monotonic() + 10.0
    while frames.error is None and time.monotonic() < deadline:
        threading.Event().wait(0.01)
    assert frames.error is not None
    return frames


def test_a_camera_that_delivered_then_failed_before_the_run_still_gives_its_first_frame(
    tmp_path: Path,
) -> None:
    # the loop, not start-up, reports its loss (a safety stop with the base open); the frame it
    # gives is the newest the camera delivered (value 10 * index, written by _images)
    frames = _failed_live_source(tmp_path, good_frames=3)
    try:
        with pytest.raises(CameraLost):
            frames.read(time.monotonic())
        image = _first_frame(frames, Ticker(1 / 30), "cam")
        assert int(image[0, 0, 0]) == 20
    finally:
        frames.close()


def test_a_camera_that_never_delivered_is_refused_at_start_naming_it(tmp_path: Path) -> None:
    frames = _failed_live_source(tmp_path, good_frames=0)
    try:
        with pytest.raises(SupervisorError, match=r"^--camera cam: no frame within 3 s \(.*a_0"
                                                  r"\.png: not a readable image\)$"):
            _first_frame(frames, Ticker(1 / 30), "cam")
    finally:
        frames.close()
