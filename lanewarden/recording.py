"""Every run recorded into its own folder, without ever slowing the control loop.

    runs/<UTC time>/            (or --record DIR; never overwritten)
      meta.json                 command line, camera, base, controller, software/package versions
      config.yaml               the effective config the run used
      calibration.yaml          the calibration file it used (if any)
      run.jsonl                 one line per step: the StepRecord plus the step's inputs
                                (lanewarden.run_record), enough to replay it exactly
      frames/000123.png         every frame perception saw, lossless (.jpg with --record-lossy)
      summary.json              written at the end: steps, frames written/dropped, end reason

`InputTap` wraps the loop's frame source, base and controller to note what came in during each
step (frame identity, base feedback, failures, operator requests) and what the controller
decided. `RunRecorder` takes one step at a time from the control thread and hands it to two writer
threads through bounded queues: a full queue drops (and counts) instead of blocking, so a slow disk
costs frames in the recording, never time in the loop. A recording with dropped frames says so in
summary.json, and replay reports that it cannot be exact.
"""

from __future__ import annotations

import datetime as dt
import json
import os
import platform
import queue
import shutil
import subprocess
import sys
import threading
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from lanewarden import __version__
from lanewarden.actuation.base import Base, BaseFeedback, VelocityCommand
from lanewarden.actuation.errors import ActuationError
from lanewarden.errors import UsageError
from lanewarden.run_record import FORMAT_VERSION, StepInput, step_line
from lanewarden.supervisor.control_io import ControlInputs, Controller, ControlOutput
from lanewarden.supervisor.errors import SupervisorError
from lanewarden.supervisor.events import Event
from lanewarden.supervisor.loop import Frame, FrameSource, StepRecord

#: Frames waiting for the disk before new ones are dropped (about 2 s at 30 Hz).
FRAME_QUEUE_FRAMES = 64
#: Step lines waiting for the disk (they are small; dropping one is a bug worth reporting).
LINE_QUEUE_LINES = 4096
#: PNG compression 1 with the "up" filter: the cheapest lossless setting OpenCV offers that still
#: halves the size (640x480: about 17 ms of CPU and 390 KiB a frame; see docs/operator.md).
PNG_PARAMS = [cv2.IMWRITE_PNG_COMPRESSION, 1] + (
    [cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_UP] if hasattr(cv2, "IMWRITE_PNG_FILTER")
    else [])
JPEG_QUALITY = 90
#: The writer threads run at this lower priority (Linux nice, per thread): on a busy machine the
#: control loop wins the CPU, and the recording drops frames (counted) instead.
WRITER_NICENESS = 10
#: Packages whose versions go into meta.json.
PACKAGES = ("numpy", "opencv-python-headless", "filterpy", "transitions", "pyserial", "pydantic",
            "PyYAML", "click", "imageio-ffmpeg", "matplotlib")


def _pair(exc: BaseException) -> tuple[str, str]:
    return type(exc).__name__, str(exc)


class InputTap:
    """Notes what the loop takes in during a step; `take()` ends the step and returns it.

    The wrapped parts behave exactly as the originals (same values, same exceptions)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._builder: dict[str, Any] = {}
        self.new_frame: Frame | None = None
        self.latest_feedback: BaseFeedback | None = None
        self._last_index: int | None = None

    # ---- wrappers -----------------------------------------------------------------------------
    def frames(self, inner: FrameSource) -> FrameSource:
        return _TappedFrames(self, inner)

    def base(self, inner: Base) -> Base:
        return _TappedBase(self, inner)

    def controller(self, inner: Controller) -> Controller:
        return _TappedController(self, inner)

    # ---- what the wrappers note ---------------------------------------------------------------
    def _note(self, **values: Any) -> None:
        with self._lock:
            self._builder.update(values)

    def _note_frame(self, frame: Frame | None) -> None:
        if frame is not None and frame.index != self._last_index:
            self._last_index = frame.index
            self.new_frame = frame
        self._note(frame=None if frame is None else (frame.index, frame.time_s))

    def _note_send_error(self) -> None:
        with self._lock:
            self._builder["send_errors"] = self._builder.get("send_errors", 0) + 1

    def take(self, now: float) -> tuple[StepInput, Frame | None]:
        """The step's inputs, and the frame if it was new this step; starts the next step."""
        with self._lock:
            values, self._builder = self._builder, {}
        new_frame, self.new_frame = self.new_frame, None
        if "feedback" in values:
            self.latest_feedback = values["feedback"]
        return StepInput(t=now, **values), new_frame


class _TappedFrames:
    def __init__(self, tap: InputTap, inner: FrameSource) -> None:
        self._tap = tap
        self.inner = inner

    def read(self, now: float) -> Frame | None:
        try:
            frame = self.inner.read(now)
        except Exception as exc:
            self._tap._note(frame=None, frame_error=_pair(exc))
            raise
        self._tap._note_frame(frame)
        return frame


class _TappedBase:
    def __init__(self, tap: InputTap, inner: Base) -> None:
        self._tap = tap
        self.inner = inner

    def send(self, command: VelocityCommand, now: float) -> None:
        try:
            self.inner.send(command, now)
        except ActuationError:
            self._tap._note_send_error()
            raise

    def feedback(self, now: float) -> BaseFeedback:
        try:
            feedback = self.inner.feedback(now)
        except ActuationError as exc:
            self._tap._note(feedback=None, feedback_error=_pair(exc))
            raise
        self._tap._note(feedback=feedback)
        return feedback

    def close(self) -> None:
        self.inner.close()


class _TappedController:
    def __init__(self, tap: InputTap, inner: Controller) -> None:
        self._tap = tap
        self.inner = inner

    def step(self, inputs: ControlInputs, now: float) -> ControlOutput:
        requests = tuple(name for name, asked in (
            ("start", inputs.start_requested), ("resume", inputs.resume_requested),
            ("stop", Event.OPERATOR_STOP in inputs.events)) if asked)
        output = self.inner.step(inputs, now)
        self._tap._note(requests=requests, command=(output.command.linear_m_s,
                                                     output.command.angular_rad_s))
        return output


# ---- the run folder ---------------------------------------------------------------------------
def default_run_folder(root: Path, now_utc: dt.datetime) -> Path:
    """runs/<UTC time>/, with -2, -3, ... appended when that name is taken (never overwrite)."""
    stamp = now_utc.strftime("%Y-%m-%dT%H-%M-%SZ")
    candidate = root / stamp
    suffix = 2
    while candidate.exists():
        candidate = root / f"{stamp}-{suffix}"
        suffix += 1
    return candidate


def create_run_folder(folder: Path, flag: str = "--record") -> Path:
    """Make `folder` (and frames/); UsageError when it already holds anything (never overwrite)."""
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        raise UsageError(f"{flag} {folder}: already exists and is not empty (a recording is never "
                         "overwritten; choose a new folder)")
    try:
        (folder / "frames").mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SupervisorError(f"{flag} {folder}: cannot create the folder "
                              f"({exc.strerror or exc})") from exc
    return folder


def software_versions() -> dict[str, Any]:
    versions: dict[str, Any] = {"lanewarden": __version__, "python": sys.version.split()[0],
                                "platform": platform.platform(), "opencv": cv2.__version__}
    packages: dict[str, str | None] = {}
    for name in PACKAGES:
        try:
            packages[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            packages[name] = None
    versions["packages"] = packages
    versions["git"] = _git_commit(Path(__file__).resolve().parent)
    return versions


def _git_commit(where: Path) -> str | None:
    """The source tree's commit (+ '-dirty'), when lanewarden runs from a git clone."""
    try:
        head = subprocess.run(["git", "-C", str(where), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=2.0, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(where), "status", "--porcelain", "-uno"],
                               capture_output=True, text=True, timeout=2.0, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("-dirty" if dirty.strip() else "")


@dataclass
class RecordingSummary:
    folder: Path
    steps: int = 0
    frames_written: int = 0
    frames_dropped: list[int] = field(default_factory=list)
    lines_dropped: int = 0
    write_errors: list[str] = field(default_factory=list)

    @property
    def complete(self) -> bool:
        return not (self.frames_dropped or self.lines_dropped or self.write_errors)


_CLOSE = object()


def lower_priority(niceness: int = WRITER_NICENESS) -> None:
    """Make the calling thread yield the CPU to the control loop (Linux: nice is per thread);
    best effort elsewhere."""
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), niceness)
    except (AttributeError, OSError):
        pass


class RunRecorder:
    """Writes one run folder. `record(...)` is called from the control thread and never blocks."""

    def __init__(self, folder: Path, *, lossy: bool = False) -> None:
        self.folder = folder
        self.frame_suffix = ".jpg" if lossy else ".png"
        self._params = [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY] if lossy else PNG_PARAMS
        self.summary = RecordingSummary(folder)
        self._frames: queue.Queue[Any] = queue.Queue(FRAME_QUEUE_FRAMES)
        self._lines: queue.Queue[Any] = queue.Queue(LINE_QUEUE_LINES)
        self._lock = threading.Lock()
        try:
            self._log = (folder / "run.jsonl").open("x", encoding="utf-8")
        except OSError as exc:
            raise SupervisorError(f"{folder / 'run.jsonl'}: cannot create the run log "
                                  f"({exc.strerror or exc})") from exc
        self._threads = [
            threading.Thread(target=self._write_frames, name="record-frames", daemon=True),
            threading.Thread(target=self._write_lines, name="record-lines", daemon=True),
        ]
        for thread in self._threads:
            thread.start()
        self._closed = False

    def write_header(self, meta: dict[str, Any], config: dict[str, Any],
                     calibration: Path | None) -> None:
        """meta.json, config.yaml and calibration.yaml (before the first step)."""
        meta = {"format": FORMAT_VERSION, "frames": f"frames/%06d{self.frame_suffix}",
                "lossless": self.frame_suffix == ".png", **meta,
                "software": software_versions()}
        try:
            (self.folder / "meta.json").write_text(json.dumps(meta, indent=2) + "\n",
                                                   encoding="utf-8")
            (self.folder / "config.yaml").write_text(
                yaml.safe_dump(config, sort_keys=False), encoding="utf-8")
            if calibration is not None:
                shutil.copyfile(calibration, self.folder / "calibration.yaml")
        except OSError as exc:
            raise SupervisorError(f"{self.folder}: cannot write the recording's header "
                                  f"({exc.strerror or exc})") from exc

    def record(self, record: StepRecord, step_input: StepInput, new_frame: Frame | None) -> None:
        """Queue one step (and its new frame). Never blocks: a full queue drops and counts."""
        self.summary.steps += 1
        if new_frame is not None:
            try:
                self._frames.put_nowait((new_frame.index, new_frame.image))
            except queue.Full:
                with self._lock:
                    self.summary.frames_dropped.append(new_frame.index)
        try:
            self._lines.put_nowait((record, step_input))
        except queue.Full:
            with self._lock:
                self.summary.lines_dropped += 1

    def close(self, extra: dict[str, Any] | None = None) -> RecordingSummary:
        """Drain the queues (bounded by what they hold), write summary.json. Idempotent."""
        if not self._closed:
            self._closed = True
            self._frames.put(_CLOSE)
            self._lines.put(_CLOSE)
            for thread in self._threads:
                thread.join()
            self._log.close()
            summary = self.summary
            body = {"steps": summary.steps, "frames_written": summary.frames_written,
                    "frames_dropped": len(summary.frames_dropped),
                    "frames_dropped_indices": summary.frames_dropped[:1000],
                    "lines_dropped": summary.lines_dropped, "write_errors": summary.write_errors,
                    "complete": summary.complete, **(extra or {})}
            try:
                (self.folder / "summary.json").write_text(json.dumps(body, indent=2) + "\n",
                                                          encoding="utf-8")
            except OSError as exc:
                summary.write_errors.append(f"summary.json: {exc.strerror or exc}")
        return self.summary

    # ---- writer threads -----------------------------------------------------------------------
    def _write_frames(self) -> None:
        lower_priority()
        frames = self.folder / "frames"
        while True:
            item = self._frames.get()
            if item is _CLOSE:
                return
            index, image = item
            assert isinstance(index, int)
            path = frames / f"{index:06d}{self.frame_suffix}"
            ok = False
            try:
                ok = bool(cv2.imwrite(str(path), np.asarray(image), self._params))
            except cv2.error:
                ok = False
            with self._lock:
                if ok:
                    self.summary.frames_written += 1
                else:
                    self.summary.frames_dropped.append(index)
                    if len(self.summary.write_errors) < 10:
                        self.summary.write_errors.append(f"{path}: cannot write")

    def _write_lines(self) -> None:
        lower_priority()
        while True:
            item = self._lines.get()
            if item is _CLOSE:
                return
            record, step_input = item
            assert isinstance(record, StepRecord) and isinstance(step_input, StepInput)
            try:
                self._log.write(json.dumps(step_line(record, step_input),
                                           separators=(",", ":")) + "\n")
                self._log.flush()
            except OSError as exc:
                with self._lock:
                    self.summary.lines_dropped += 1
                    if len(self.summary.write_errors) < 10:
                        self.summary.write_errors.append(f"run.jsonl: {exc.strerror or exc}")
