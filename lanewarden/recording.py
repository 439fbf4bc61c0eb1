"""Every run recorded into its own folder, without ever slowing the control loop.

    runs/<UTC time>/            (or --record DIR; never overwritten)
      run.mcap                  the recording (lanewarden.run_mcap): every frame perception saw,
                                the commands on /cmd_vel, the base's feedback and every step with
                                its inputs (lanewarden.run_record), ROS 2 messages that Foxglove,
                                Lichtblick and `ros2 bag` open; self-contained (it carries the
                                meta, config and calibration below); enough to replay it exactly
      meta.json                 command line, camera, base, controller, software/package versions
      config.yaml               the effective config the run used
      calibration.yaml          the calibration file it used (if any)
      summary.json              written at the end: steps, frames written/dropped, end reason

Frames are kept as perception consumes them: by default the PNG (lanewarden.frame_png) of what
the lane detector made of the frame before looking for edges (`LaneDetector.prepare`: gray,
undistorted, blurred; perception depends on a frame only through it), lossless, prepared again
here on the writer thread by a detector with the run's own config and calibration
(`prepare_with`), so the control thread does no more work; with the frame's supervisor
fingerprint beside it (the watchdog compares the camera's frames, which the recording no longer
holds: run_record). `--record-gray` keeps the camera frame's gray version instead (exact too,
about 1.7 times the disk), `--record-lossy` a colour JPEG (not exact).

`InputTap` wraps the loop's frame source, base and controller to note what came in during each
step (frame identity, base feedback, failures, operator requests) and what the controller
decided. `RunRecorder` takes one step at a time from the control thread and hands it to one
writer thread (lower CPU priority) through a bounded queue, which never blocks: with more than
FRAME_QUEUE_FRAMES frames waiting, a new frame is dropped (its step is still recorded), counted
and said once while running; replay then reports that it cannot be exact.

When the recording cannot be written (a full disk, the folder removed, no permission), it stops
and says so once (`problem`, which the run's status shows); the run goes on: the recording is
not part of what keeps the robot safe, and a halt in mid-lane for a full disk would trade a lost
log for a stopped robot the operator did not ask for. The file then ends without its summary,
which replay reports as "cut short". summary.json is still written where the disk allows.
"""

from __future__ import annotations

import datetime as dt
import errno
import json
import os
import platform
import queue
import shutil
import subprocess
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from importlib import metadata
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from lanewarden import __version__
from lanewarden.actuation.base import Base, BaseFeedback, VelocityCommand
from lanewarden.actuation.errors import ActuationError
from lanewarden.documents import dangling_link
from lanewarden.errors import UsageError
from lanewarden.frame_png import FILTER_SUB, FILTER_UP, gray_png
from lanewarden.perception.config import PerceptionConfig
from lanewarden.perception.detector import LaneDetector, perception_gray
from lanewarden.run_mcap import (
    CALIBRATION_ATTACHMENT,
    CAMERA_GRAY,
    CAMERA_JPEG,
    CONFIG_ATTACHMENT,
    IMAGE_KINDS,
    JPEG_FORMAT,
    PERCEPTION_INPUT,
    PNG_FORMAT,
    RunMcapWriter,
)
from lanewarden.run_record import FORMAT_VERSION, MAX_TEXT_CHARS, StepInput, step_line
from lanewarden.supervisor.control_io import ControlInputs, ControlOutput
from lanewarden.supervisor.errors import SupervisorError
from lanewarden.supervisor.events import Event
from lanewarden.supervisor.loop import Frame, FrameSource, Gate, StepRecord
from lanewarden.supervisor.watchdog import frame_fingerprint

RUN_MCAP = "run.mcap"
#: Frames waiting for the writer before new ones are dropped (about 2 s at 30 Hz).
FRAME_QUEUE_FRAMES = 64
#: Steps waiting for the writer (they are small; dropping one is a bug worth reporting).
STEP_QUEUE_STEPS = 4096
JPEG_QUALITY = 90
#: Every this many steps the writer checks that run.mcap is still in a folder (on Linux, writing
#: into a deleted file succeeds, and everything would be lost without a word).
DELETED_CHECK_STEPS = 30
#: The writer thread runs at this lower priority (Linux nice, per thread): on a busy machine the
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

    def gate(self, inner: Gate) -> Gate:
        return _TappedGate(self, inner)

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


class _TappedGate:
    def __init__(self, tap: InputTap, inner: Gate) -> None:
        self._tap = tap
        self.inner = inner

    @property
    def lane_memory_s(self) -> float:
        return self.inner.lane_memory_s

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
    """Make `folder`; UsageError when it already holds anything (never overwrite), or is
    something else than a folder (a FIFO, a device, a link to nowhere)."""
    if link := dangling_link(folder):
        raise UsageError(f"{flag} {folder}: {link}; choose a new folder")
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"{flag} {folder}: already exists and is not a folder; choose a new "
                         "folder")
    if folder.exists() and any(folder.iterdir()):
        raise UsageError(f"{flag} {folder}: already exists and is not empty (a recording is never "
                         "overwritten; choose a new folder)")
    try:
        folder.mkdir(parents=True, exist_ok=True)
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
    steps_written: int = 0
    frames_written: int = 0
    #: Frames perception could not prepare (recorded as refused: replay raises the same).
    frames_refused: int = 0
    frames_dropped: list[int] = field(default_factory=list)
    lines_dropped: int = 0
    write_errors: list[str] = field(default_factory=list)
    #: Why the recording stopped before the run ended (None: it did not).
    problem: str | None = None

    @property
    def complete(self) -> bool:
        return not (self.frames_dropped or self.lines_dropped or self.write_errors
                    or self.problem)


_CLOSE = object()


def lower_priority(niceness: int = WRITER_NICENESS) -> None:
    """Make the calling thread yield the CPU to the control loop (Linux: nice is per thread);
    best effort elsewhere."""
    try:
        os.setpriority(os.PRIO_PROCESS, threading.get_native_id(), niceness)
    except (AttributeError, OSError):
        pass


def _why(exc: BaseException) -> str:
    if isinstance(exc, OSError):
        return exc.strerror or str(exc)
    return f"{type(exc).__name__}: {exc}"


@dataclass(frozen=True)
class _Step:
    record: StepRecord
    step_input: StepInput
    frame: Frame | None


@dataclass(frozen=True)
class _Header:
    meta: dict[str, Any]
    attachments: dict[str, bytes]
    time_s: float


class RunRecorder:
    """Writes one run folder. `record(...)` is called from the control thread and never blocks.
    `image_kind`: which frames it keeps (lanewarden.run_mcap.IMAGE_KINDS; by default
    perception's input, prepared like the detector given to `prepare_with`, else like a
    detector with the default perception config and no calibration). `epoch_offset_s`: UNIX
    time minus the loop's clock, for the MCAP's log times."""

    def __init__(self, folder: Path, *, image_kind: str = PERCEPTION_INPUT,
                 epoch_offset_s: float = 0.0) -> None:
        if image_kind not in IMAGE_KINDS:
            raise ValueError(f"image_kind = {image_kind!r}: expected one of "
                             f"{', '.join(IMAGE_KINDS)}")
        self.folder = folder
        self.image_kind = image_kind
        self.lossy = image_kind == CAMERA_JPEG
        self.summary = RecordingSummary(folder)
        self._items: queue.Queue[Any] = queue.Queue(STEP_QUEUE_STEPS)
        self._lock = threading.Lock()
        self._frames_waiting = 0
        self._preparer: LaneDetector | None = None
        path = folder / RUN_MCAP
        try:
            self._file = path.open("xb")
            self._mcap = RunMcapWriter(self._file, epoch_offset_s, image_kind)
        except OSError as exc:
            raise SupervisorError(f"{path}: cannot create the recording ({_why(exc)})") from exc
        self._thread = threading.Thread(target=self._write, name="record-writer", daemon=True)
        self._thread.start()
        self._closed = False

    def prepare_with(self, detector: LaneDetector) -> None:
        """Prepare frames as `detector` does (its config, undistorter and ground model), with a
        detector of the writer's own (its buffers are not the control thread's). Call before
        the first frame."""
        self._preparer = LaneDetector(detector.config, detector.undistorter,
                                      ground=detector.ground)

    @property
    def problem(self) -> str | None:
        """Why the recording stopped (a full disk, ...), once it did; None while it works."""
        return self.summary.problem

    def write_header(self, meta: dict[str, Any], config: dict[str, Any],
                     calibration: Path | None, now: float = 0.0) -> None:
        """meta.json, config.yaml and calibration.yaml, and the same in run.mcap (before the
        first step). SupervisorError when they cannot be written: the run does not start."""
        meta = {"format": FORMAT_VERSION, "recording": RUN_MCAP, "frames": self._mcap.image_topic,
                "image": self.image_kind, "lossless": not self.lossy, **meta,
                "software": software_versions()}
        try:
            config_text = yaml.safe_dump(config, sort_keys=False).encode("utf-8")
            attachments = {CONFIG_ATTACHMENT: config_text}
            (self.folder / "meta.json").write_text(json.dumps(meta, indent=2) + "\n",
                                                   encoding="utf-8")
            (self.folder / CONFIG_ATTACHMENT).write_bytes(config_text)
            if calibration is not None:
                attachments[CALIBRATION_ATTACHMENT] = calibration.read_bytes()
                shutil.copyfile(calibration, self.folder / CALIBRATION_ATTACHMENT)
        except OSError as exc:
            raise SupervisorError(f"{self.folder}: cannot write the recording's header "
                                  f"({_why(exc)})") from exc
        self._items.put(_Header(meta, attachments, now))

    def record(self, record: StepRecord, step_input: StepInput, new_frame: Frame | None) -> None:
        """Queue one step (and its new frame). Never blocks: too many frames waiting drops the
        frame, a full queue the step; both are counted."""
        self.summary.steps += 1
        frame = None
        if new_frame is not None:
            with self._lock:
                if self._frames_waiting < FRAME_QUEUE_FRAMES:
                    self._frames_waiting += 1
                    frame = new_frame
                else:
                    self.summary.frames_dropped.append(new_frame.index)
        try:
            self._items.put_nowait(_Step(record, step_input, frame))
        except queue.Full:
            with self._lock:
                self.summary.lines_dropped += 1
                if frame is not None:
                    self._frames_waiting -= 1
                    self.summary.frames_dropped.append(frame.index)

    def close(self, extra: dict[str, Any] | None = None) -> RecordingSummary:
        """Drain the queue (bounded by what it holds), finish run.mcap with its summary, write
        summary.json. Idempotent; never raises for the disk (the summary says what failed)."""
        if self._closed:
            return self.summary
        self._closed = True
        self._items.put(_CLOSE)
        self._thread.join()
        summary = self.summary
        body = self._summary_body(extra)
        if summary.problem is None:
            try:
                self._mcap.finish(body)
                self._file.close()
            except OSError as exc:
                self._stop(exc)
                body = self._summary_body(extra)
        if summary.problem is not None:
            try:
                self._file.close()
            except OSError:
                pass  # already said: the recording stopped
        try:
            (self.folder / "summary.json").write_text(json.dumps(body, indent=2) + "\n",
                                                      encoding="utf-8")
        except OSError as exc:
            summary.write_errors.append(f"summary.json: {_why(exc)}")
        return summary

    def _summary_body(self, extra: dict[str, Any] | None) -> dict[str, Any]:
        summary = self.summary
        return {"steps": summary.steps, "steps_written": summary.steps_written,
                "frames_written": summary.frames_written,
                "frames_refused": summary.frames_refused,
                "frames_dropped": len(summary.frames_dropped),
                "frames_dropped_indices": summary.frames_dropped[:1000],
                "lines_dropped": summary.lines_dropped, "write_errors": summary.write_errors,
                "recording_stopped": summary.problem, "complete": summary.complete,
                **(extra or {})}

    def _stop(self, exc: BaseException) -> None:
        with self._lock:
            if self.summary.problem is None:
                self.summary.problem = (f"{self.folder / RUN_MCAP}: {_why(exc)} (after "
                                        f"{self.summary.steps_written} steps)")

    # ---- the writer thread --------------------------------------------------------------------
    def _write(self) -> None:
        lower_priority()
        while True:
            item = self._items.get()
            if item is _CLOSE:
                return
            if isinstance(item, _Header):
                self._guarded(self._mcap.start, item.meta, item.attachments, item.time_s)
                continue
            assert isinstance(item, _Step)
            step_input = item.step_input
            if item.frame is not None:
                noted = self._guarded(self._write_frame, item.frame, item.record.time_s)
                with self._lock:
                    self._frames_waiting -= 1
                if noted is not None:
                    step_input = replace(step_input, **noted)
            self._guarded(self._write_step, item.record, step_input)

    def _guarded(self, write: Callable[..., Any], *args: Any) -> Any:
        """Run one write unless the recording stopped; a failure stops it (said once)."""
        if self.summary.problem is not None:
            return None
        try:
            return write(*args)
        except Exception as exc:  # the disk (OSError) or a bug: reported, never silent
            self._stop(exc)
            return None

    def _prepared(self, image: np.ndarray) -> np.ndarray:
        """Perception's input for PERCEPTION_INPUT (raises as the detector does); else the
        frame itself."""
        if self.image_kind != PERCEPTION_INPUT:
            return image
        if self._preparer is None:
            self._preparer = LaneDetector(PerceptionConfig())
        return self._preparer.prepare(image)

    def _encode(self, image: np.ndarray) -> tuple[bytes, str]:
        """The image as this recording keeps it: (encoded image, its CompressedImage format)."""
        if self.image_kind == CAMERA_JPEG:
            ok, encoded = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
            return (encoded.tobytes() if ok else b""), JPEG_FORMAT
        if self.image_kind == CAMERA_GRAY:
            # perception's gray: the run's `perception.gray`, from the detector it prepares with
            boost = 0.0 if self._preparer is None else self._preparer.config.gray.yellow_boost
            return gray_png(perception_gray(image, yellow_boost=boost), FILTER_SUB), PNG_FORMAT
        return gray_png(image, FILTER_UP), PNG_FORMAT

    def _write_frame(self, frame: Frame, logged_at: float) -> dict[str, Any]:
        """Write one frame; returns what its step notes about it (fingerprint, refusal)."""
        noted: dict[str, Any] = {}
        fingerprint = frame_fingerprint(frame.image)
        if fingerprint is not None:
            noted["frame_fingerprint"] = fingerprint.hex()
        try:
            image = self._prepared(frame.image)
        except Exception as exc:  # perception refused it, as the run's detector did: noted
            noted["frame_refused"] = (type(exc).__name__, str(exc)[:MAX_TEXT_CHARS])
            with self._lock:
                self.summary.frames_refused += 1
            return noted
        try:
            data, image_format = self._encode(image)
        except (cv2.error, ValueError, IndexError) as exc:
            data, image_format = b"", f"{type(exc).__name__}: {exc}"
        if not data:  # a frame no codec takes (perception refused it too): counted, not written
            with self._lock:
                self.summary.frames_dropped.append(frame.index)
                if len(self.summary.write_errors) < 10:
                    self.summary.write_errors.append(f"frame {frame.index}: cannot encode "
                                                     f"({image_format})")
            return noted
        self._mcap.frame(frame.index, frame.time_s, logged_at, image_format, data)
        with self._lock:
            self.summary.frames_written += 1
        return noted

    def _write_step(self, record: StepRecord, step_input: StepInput) -> None:
        line = json.dumps(step_line(record, step_input), separators=(",", ":"))
        self._mcap.step(record, step_input, line)
        with self._lock:
            self.summary.steps_written += 1
        if self.summary.steps_written % DELETED_CHECK_STEPS == 0 and (
                os.fstat(self._file.fileno()).st_nlink == 0):
            raise FileNotFoundError(errno.ENOENT, "the file or its folder was deleted while "
                                    "recording")
