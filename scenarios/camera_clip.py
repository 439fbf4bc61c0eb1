"""A camera clip from the simulator (`lanewarden sim --camera-out FILE`): the robot camera's raw
view, what its sensor captured each frame (through the lens, with sensor noise, motion blur and
the scenario's image faults; no overlay, no map), at the camera's size and frame rate.

- FILE with a video suffix (`VIDEO_SUFFIXES`): an H.264 video (imageio-ffmpeg's ffmpeg, as the
  run's video.mp4), near-lossless (`CLIP_CRF`).
- any other FILE: a folder of lossless PNG frames, `frame_000000.png` on (natural order).

Beside it, what `lanewarden run` needs to see those frames as the simulated robot did: the
camera's calibration, `<FILE without suffix>.calibration.yaml` (its lens and its pose over the
floor, as `calibrate` and `calibrate ground` write them), and, when the run's config differs from
the defaults (a scenario's own `config:` or `--config`), `<FILE without suffix>.config.yaml`.
`run_command` is the command line that plays the clip back.

Writing only: the frames come from the simulator's `camera_frames` callback; never runs the
simulation, never reads a clock. The camera's own drop/freeze/latency faults act in its driver,
after the sensor, so they are not in a clip (a clip plays at a constant rate).
"""

from __future__ import annotations

import errno
import logging
import os
import re
import shlex
import subprocess
import tempfile
from collections.abc import Generator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml
from numpy.typing import NDArray

from lanewarden.documents import dangling_link
from lanewarden.image_files import write_image
from lanewarden.perception.calibration import CameraCalibration, save_calibration
from lanewarden.perception.errors import PerceptionError
from lanewarden.scenarios.encoder_pipe import (
    FFMPEG_LOG_LEVEL,
    close_encoder,
    encoder_failure,
    encoder_process,
    ffmpeg_output,
    send_whole,
)
from lanewarden.scenarios.errors import ScenarioError, ScenarioOutputError

#: FILE endings written as a video (what OpenCV and `lanewarden run --camera` read back).
VIDEO_SUFFIXES = (".mp4", ".mkv", ".avi", ".mov")
#: x264 quality of a camera clip: near-lossless (the composite video.mp4 uses a coarser one).
CLIP_CRF = 18
_FRAME_NAME = re.compile(r"^frame_\d{6}\.png$")


@dataclass(frozen=True)
class ClipFiles:
    """Where a clip and its companions go."""

    clip: Path
    calibration: Path
    config: Path

    @property
    def is_video(self) -> bool:
        return self.clip.suffix.lower() in VIDEO_SUFFIXES

    @classmethod
    def for_target(cls, target: Path) -> ClipFiles:
        stem = target.with_suffix("") if target.suffix.lower() in VIDEO_SUFFIXES else target
        return cls(target, stem.with_name(stem.name + ".calibration.yaml"),
                   stem.with_name(stem.name + ".config.yaml"))


def clip_calibration_hint(camera: str) -> str:
    """'; the clip's own calibration lies beside it: --calibration FILE' when `--camera` is a
    simulator clip with its calibration beside it (or beside the folder a pattern picks its
    frames from: 'clip/*.png', 'clip/frame_%06d.png'; `sim --camera-out clip` writes
    clip.calibration.yaml), else ''."""
    given = Path(camera)
    places = [given, given.parent] if any(c in camera for c in "*?[%") else [given]
    beside = next((c for c in (ClipFiles.for_target(p).calibration for p in places)
                   if c.is_file()), None)
    return "" if beside is None else (
        f"; the clip's own calibration lies beside it: --calibration {beside}")


def check_clip_target(target: Path) -> ClipFiles:
    """The clip's files, or ScenarioError (one line naming --camera-out) when FILE cannot be
    used: a folder where a video should go, a file where frames should go, a folder holding
    anything but an earlier clip's frames, or a place the clip and its calibration cannot be
    written (`_unwritable`). Leaves every file as it was: called before the run's output folder
    is prepared, so a refused --camera-out leaves an earlier run's outputs as they were."""
    files = ClipFiles.for_target(target)
    where = f"--camera-out {target}"
    if files.is_video:
        if target.is_dir():
            raise ScenarioError(f"{where}: is a folder (expected a video file name ending in "
                                f"{', '.join(VIDEO_SUFFIXES)}, or a folder name for PNG frames)")
    elif target.exists() and not target.is_dir():
        raise ScenarioError(f"{where}: exists and is not a folder (a name without a video suffix "
                            f"is a folder of PNG frames; for a video end it in "
                            f"{', '.join(VIDEO_SUFFIXES)})")
    elif target.is_dir():
        others = sorted(p.name for p in target.iterdir() if not _FRAME_NAME.match(p.name))
        if others:
            raise ScenarioError(f"{where}: the folder holds other files ({', '.join(others[:3])}"
                                f"{', ...' if len(others) > 3 else ''}): expected a new or empty "
                                "folder, or one with an earlier clip's frame_NNNNNN.png only")
    if problem := _unwritable(files):
        raise ScenarioError(f"{where}: {problem}")
    return files


def _unwritable(files: ClipFiles) -> str | None:
    """Why the clip and the files beside it could not be written, or None. Their folder (the
    clip's parent) must exist or be creatable: its nearest existing part a folder that takes a
    new file (tried with a file created and removed at once: root may write anywhere by its
    permissions, yet /proc takes no file), and so must a frames folder that exists; a file that
    is there already must be a file this process may write. Found before the run: ffmpeg had
    found an output it could not open only at the first frames, in two lines of its own."""
    clip = files.clip
    if link := dangling_link(clip):
        return f"{link}; expected a new {'file' if files.is_video else 'folder'} name"
    folder = clip.parent
    while not (folder.exists() or folder.is_symlink()):  # "." and "/" always exist
        folder = folder.parent
    if not folder.is_dir():
        return f"a part of this path exists and is not a folder ({folder})"
    for place in (folder, clip if not files.is_video and clip.is_dir() else None):
        if place is None:
            continue
        try:
            fd, probe = tempfile.mkstemp(prefix=".lanewarden-probe-", dir=place)
            os.close(fd)
            os.unlink(probe)
        except OSError as exc:
            return f"cannot write there (cannot create a file in {place}: {exc.strerror or exc})"
    for path in (clip if files.is_video else None, files.calibration, files.config):
        if path is None or not path.exists():
            continue
        if not path.is_file():
            return f"{path} exists and is not a file"
        if not os.access(path, os.W_OK):
            return f"cannot write there ({path}: {os.strerror(errno.EACCES)})"
    return None


class CameraClipWriter:
    """Streams the camera's frames into `files.clip` (see the module docstring). `size`: (width,
    height); `fps`: the camera's frame rate; `preset`: x264's speed preset for a video."""

    def __init__(self, files: ClipFiles, size: tuple[int, int], fps: float, preset: str,
                 gray: bool) -> None:
        self.files = files
        self.size = size
        self.fps = fps
        self.frames = 0
        self._writer: Generator[Any, Any, None] | None = None
        self._process: subprocess.Popen[bytes] | None = None
        try:
            files.clip.parent.mkdir(parents=True, exist_ok=True)
            if files.is_video:
                import imageio_ffmpeg

                logging.getLogger("imageio_ffmpeg").setLevel(logging.ERROR)
                writer = imageio_ffmpeg.write_frames(
                    ffmpeg_output(files.clip), size, fps=fps, codec="libx264",
                    pix_fmt_in="gray" if gray else "bgr24", pix_fmt_out="yuv420p",
                    macro_block_size=2, ffmpeg_log_level=FFMPEG_LOG_LEVEL,
                    output_params=["-preset", preset, "-crf", str(CLIP_CRF),
                                   "-movflags", "+faststart"])
                writer.send(None)
                self._writer = writer
                self._process = encoder_process(writer)
            else:
                files.clip.mkdir(exist_ok=True)
                for old in files.clip.glob("frame_*.png"):
                    old.unlink()
        except (OSError, RuntimeError) as exc:
            raise ScenarioOutputError(f"--camera-out {files.clip}: cannot write the camera clip "
                                      f"({exc})") from exc

    def add(self, image: NDArray[np.uint8], now: float) -> None:
        """One camera frame (gray or BGR, at `size`)."""
        try:
            if self._writer is not None:
                send_whole(self._writer, np.ascontiguousarray(image))
            else:
                write_image(self.files.clip / f"frame_{self.frames:06d}.png", image,
                            [cv2.IMWRITE_PNG_COMPRESSION, 1])
        except (OSError, RuntimeError) as exc:
            why = (getattr(exc, "strerror", None) or exc if self._writer is None
                   else encoder_failure(self._process, exc))
            self._writer = None  # ffmpeg is gone: closing it has nothing more to say
            raise ScenarioOutputError(f"--camera-out {self.files.clip}: cannot write frame "
                                      f"{self.frames} ({why})") from exc
        self.frames += 1

    def close(self, calibration: CameraCalibration,
              config_overrides: Mapping[str, Any]) -> dict[str, object]:
        """Finish the clip, write its calibration (and config, when not the defaults); what was
        written (for metrics.json)."""
        writer, self._writer = self._writer, None
        if writer is not None and (failed := close_encoder(writer, self._process,
                                                           self.files.clip, self.frames)):
            raise ScenarioOutputError(f"--camera-out {self.files.clip}: video encoding failed "
                                      f"({failed})")
        try:
            save_calibration(calibration, self.files.calibration)
            if config_overrides:
                self.files.config.write_text(
                    "# the config this clip's run used (its scenario's config: and --config)\n"
                    + yaml.safe_dump(dict(config_overrides), sort_keys=False), encoding="utf-8")
            elif self.files.config.exists():
                self.files.config.unlink()  # an earlier clip's: it would not be this run's
        except (OSError, RuntimeError, PerceptionError) as exc:
            raise ScenarioOutputError(f"--camera-out {self.files.clip}: cannot finish the camera "
                                      f"clip ({exc})") from exc
        return {"path": str(self.files.clip), "frames": self.frames,
                "size": list(self.size), "fps": self.fps,
                "calibration": str(self.files.calibration),
                "config": str(self.files.config) if config_overrides else None,
                "run": run_command(self.files, bool(config_overrides))}

    def abort(self) -> Path | None:
        """After a failure or an interrupt: stop the encoder and move the incomplete clip aside,
        to `<name>.partial<suffix>` (a frames folder: `<name>.partial`; `.partial-2` and on when
        taken), so that it is never played as the clip; an earlier clip's calibration and config
        beside it go (the clip they described was overwritten). Returns where it went (None: it
        could not be moved)."""
        writer, self._writer = self._writer, None
        if writer is not None:
            try:
                writer.close()
            except (OSError, RuntimeError):
                pass
        clip = self.files.clip

        def partial_name(n: int) -> Path:  # NAME.partial.mp4, NAME.partial-2.mp4, ...
            tag = "partial" if n == 1 else f"partial-{n}"
            return (clip.with_name(f"{clip.stem}.{tag}{clip.suffix}") if self.files.is_video
                    else clip.with_name(f"{clip.name}.{tag}"))

        try:
            partial = next((partial_name(n) for n in range(1, 1000)
                            if not partial_name(n).exists()), None)
            if not clip.exists() or partial is None:
                return None
            clip.rename(partial)
            self.files.calibration.unlink(missing_ok=True)
            self.files.config.unlink(missing_ok=True)
        except OSError:
            return None
        return partial


def run_command(files: ClipFiles, with_config: bool) -> str:
    """The command that plays the clip back through the whole loop on a simulated base."""
    config = f" --config {_shell(files.config)}" if with_config else ""
    return (f"lanewarden run --camera {_shell(files.clip)} --calibration "
            f"{_shell(files.calibration)}{config} --base sim")


def _shell(path: Path) -> str:
    return shlex.quote(str(path))
