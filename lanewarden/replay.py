"""Replay: perception and the supervisor on recorded frames, on a fake clock, step by step.

Sources (`open_replay_source`):
- a run folder (`lanewarden run --record`): its steps are fed back exactly as recorded (step times,
  frame identities and times, base feedback, failures, operator requests; see
  `lanewarden.run_record`) with the run's own config and calibration, and every replayed step is
  compared with the recorded one (frame, state, events, command, halt reason): the first
  divergence is reported, so a change in perception or the supervisor can be tested on real runs;
- a video file, a folder or glob of images, or a Donkeycar tub (catalog_*.catalog + images/): one
  step per frame at the frame's time (the tub's recorded timestamps, the video's frame rate, the
  configured camera rate for images), a base whose feedback is always fresh, and a start at the
  first step.

The loop is the very `ControlLoop` the robot and the simulator run; only its frame source and base
are scripted from the recording. Never reads a clock and never sleeps.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from lanewarden.actuation.base import BaseFeedback, VelocityCommand
from lanewarden.actuation.errors import ActuationError
from lanewarden.assembly import build_stack
from lanewarden.camera_source import image_sequence_paths, quiet_opencv
from lanewarden.config import LanewardenConfig, config_from_mapping, load_config
from lanewarden.errors import UsageError
from lanewarden.perception.calibration import CameraCalibration, load_calibration
from lanewarden.perception.detector import DetectionDebug
from lanewarden.perception.observation import LaneObservation
from lanewarden.run_record import FORMAT_VERSION, StepInput, step_input_from_line
from lanewarden.supervisor.loop import Frame, StepRecord

SOURCE_HELP = ("a run folder (lanewarden run --record), a video file, a folder or glob of "
               "images, or a Donkeycar tub")


# ---- where the images come from ---------------------------------------------------------------
class FrameStore:
    """Images by frame index. Subclasses: a run folder's frames, a list of files, a video."""

    def image(self, index: int) -> np.ndarray | None:
        raise NotImplementedError

    def close(self) -> None:
        pass


class PathFrames(FrameStore):
    """Frame i is `paths[i]`; a missing or unreadable file is None."""

    def __init__(self, paths: list[Path]) -> None:
        self.paths = paths

    def image(self, index: int) -> np.ndarray | None:
        if not 0 <= index < len(self.paths):
            return None
        image = cv2.imread(str(self.paths[index]), cv2.IMREAD_UNCHANGED)
        return image if image is not None and image.dtype == np.uint8 else None


class RunFolderFrames(FrameStore):
    def __init__(self, folder: Path, suffix: str) -> None:
        self.folder = folder
        self.suffix = suffix

    def image(self, index: int) -> np.ndarray | None:
        image = cv2.imread(str(self.folder / f"{index:06d}{self.suffix}"), cv2.IMREAD_UNCHANGED)
        return image


class VideoFrames(FrameStore):
    """Decodes forward only (replay asks for increasing indices)."""

    def __init__(self, capture: cv2.VideoCapture) -> None:
        self._capture = capture
        self._index = -1
        self._image: np.ndarray | None = None

    def image(self, index: int) -> np.ndarray | None:
        while self._index < index:
            ok, image = self._capture.read()
            if not ok:
                return None
            self._index += 1
            self._image = image
        return self._image if self._index == index else None

    def close(self) -> None:
        self._capture.release()


@dataclass
class ReplaySource:
    """What to replay: the steps, where their images are, and for a run folder the recording."""

    kind: str  # "run", "video", "images", "tub"
    name: str
    steps: list[StepInput]
    frames: FrameStore
    recorded: list[dict[str, Any]] | None = None
    config: LanewardenConfig | None = None
    calibration: CameraCalibration | None = None
    controller: str | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    config_origin: str = "defaults"


def _synthetic_steps(times: list[float]) -> list[StepInput]:
    """One step per frame at its time, feedback always fresh, a start at the first step."""
    return [StepInput(t=t, frame=(i, t), feedback=BaseFeedback(received_at_s=t),
                      requests=("start",) if i == 0 else ())
            for i, t in enumerate(times)]


def _read_json(path: Path, what: str) -> Any:
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise UsageError(f"{path}: cannot read the {what} ({exc})") from exc


def _load_run_folder(folder: Path) -> ReplaySource:
    meta = _read_json(folder / "meta.json", "recording's meta.json")
    if meta.get("format") != FORMAT_VERSION:
        raise UsageError(f"{folder / 'meta.json'}: recording format {meta.get('format')!r}, this "
                         f"lanewarden replays format {FORMAT_VERSION}")
    lines: list[dict[str, Any]] = []
    steps: list[StepInput] = []
    run_log = folder / "run.jsonl"
    try:
        text = run_log.read_text(encoding="utf-8")
    except OSError as exc:
        raise UsageError(f"{run_log}: cannot read ({exc.strerror or exc})") from exc
    for number, raw in enumerate(text.splitlines(), start=1):
        if not raw.strip():
            continue
        try:
            line = json.loads(raw)
            steps.append(step_input_from_line(line))
        except (ValueError, KeyError, TypeError, IndexError) as exc:
            if number == len(text.splitlines()):
                break  # the last line of a killed run may be cut short: replay the rest
            raise UsageError(f"{run_log}:{number}: not a recorded step ({exc})") from exc
        lines.append(line)
    if not steps:
        raise UsageError(f"{run_log}: no recorded steps")
    config_path = folder / "config.yaml"
    config = None
    if config_path.exists():
        try:
            data = yaml.safe_load(config_path.read_text(encoding="utf-8"))
        except (OSError, yaml.YAMLError) as exc:
            raise UsageError(f"{config_path}: cannot read the recorded config ({exc})") from exc
        config = config_from_mapping(data, str(config_path))
    calibration_path = folder / "calibration.yaml"
    calibration = load_calibration(calibration_path) if calibration_path.exists() else None
    summary_path = folder / "summary.json"
    summary = _read_json(summary_path, "recording's summary") if summary_path.exists() else {}
    pattern = str(meta.get("frames", "frames/%06d.png"))
    return ReplaySource(
        kind="run", name=folder.name, steps=steps,
        frames=RunFolderFrames(folder / "frames", Path(pattern).suffix or ".png"),
        recorded=lines, config=config, calibration=calibration,
        controller=meta.get("controller"), meta=meta, summary=summary,
        config_origin=f"recorded ({config_path})" if config is not None else "defaults")


def _load_tub(folder: Path, catalogs: list[Path]) -> ReplaySource:
    records: list[dict[str, Any]] = []
    for catalog in catalogs:
        for number, raw in enumerate(catalog.read_text(encoding="utf-8").splitlines(), 1):
            if raw.strip():
                try:
                    records.append(json.loads(raw))
                except ValueError as exc:
                    raise UsageError(f"{catalog}:{number}: not a JSON record ({exc})") from exc
    deleted: set[int] = set()
    manifest = folder / "manifest.json"
    if manifest.exists():
        for raw in manifest.read_text(encoding="utf-8").splitlines():
            try:
                entry = json.loads(raw)
            except ValueError:
                continue
            if isinstance(entry, dict):
                deleted |= set(entry.get("deleted_indexes", []))
    records = [r for r in records if r.get("_index") not in deleted]
    try:
        records.sort(key=lambda r: int(r["_index"]))
        paths = [folder / "images" / str(r["cam/image_array"]) for r in records]
        stamps = [float(r["_timestamp_ms"]) / 1000.0 for r in records]
    except (KeyError, TypeError, ValueError) as exc:
        raise UsageError(f"{folder}: a tub record lacks _index, _timestamp_ms or cam/image_array "
                         f"({exc})") from exc
    if not records:
        raise UsageError(f"{folder}: the tub holds no records")
    times = [t - stamps[0] for t in stamps]
    if any(b <= a for a, b in zip(times, times[1:], strict=False)):
        raise UsageError(f"{folder}: the tub's _timestamp_ms do not increase frame to frame")
    return ReplaySource(kind="tub", name=folder.name, steps=_synthetic_steps(times),
                        frames=PathFrames(paths), meta={"frames_per_s_recorded":
                                                        len(times) / max(times[-1], 1e-9)})


def open_replay_source(source: str, camera_rate_hz: float) -> ReplaySource:
    """Recognise SOURCE (see the module docstring); UsageError naming it when it is none."""
    path = Path(source)
    if path.is_dir():
        if (path / "run.jsonl").exists() and (path / "meta.json").exists():
            return _load_run_folder(path)
        catalogs = sorted(path.glob("catalog_*.catalog"))
        if catalogs and (path / "images").is_dir():
            return _load_tub(path, catalogs)
    paths = image_sequence_paths(source)
    if paths is not None:
        if not paths:
            raise UsageError(f"SOURCE '{source}': no images there; expected {SOURCE_HELP}")
        times = [i / camera_rate_hz for i in range(len(paths))]
        return ReplaySource(kind="images", name=path.name or source, steps=_synthetic_steps(times),
                            frames=PathFrames(paths))
    if path.is_file():
        with quiet_opencv():
            capture = cv2.VideoCapture(str(path))
            opened = capture.isOpened()
        count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT) or 0) if opened else 0
        if not opened or count <= 0:
            capture.release()
            raise UsageError(f"SOURCE '{source}': not a video OpenCV can read; expected "
                             f"{SOURCE_HELP}")
        fps = float(capture.get(cv2.CAP_PROP_FPS) or 0.0)
        fps = fps if 1.0 <= fps <= 240.0 else camera_rate_hz
        times = [i / fps for i in range(count)]
        return ReplaySource(kind="video", name=path.stem, steps=_synthetic_steps(times),
                            frames=VideoFrames(capture), meta={"fps": fps})
    raise UsageError(f"SOURCE '{source}': no such file or folder; expected {SOURCE_HELP}")


def replay_config(source: ReplaySource, config_path: str | None) -> LanewardenConfig:
    """--config wins; else the recording's own config; else the defaults."""
    if config_path is not None:
        source.config_origin = config_path
        return load_config(config_path)
    return source.config if source.config is not None else LanewardenConfig()


# ---- the scripted parts of the loop -----------------------------------------------------------
_NAMED: dict[tuple[str, type[Exception]], type[Exception]] = {}


def recorded_error(name: str, message: str, base: type[Exception]) -> Exception:
    """An exception that reads exactly like the recorded one (type name and message), so the
    loop's event detail comes out the same."""
    key = (name, base)
    if key not in _NAMED:
        _NAMED[key] = type(name, (base,), {})
    return _NAMED[key](message)


class ScriptedFrames:
    """The loop's FrameSource during replay: the frame the recording says the step got."""

    def __init__(self, store: FrameStore) -> None:
        self._store = store
        self.step: StepInput | None = None
        self._cache: tuple[int, np.ndarray] | None = None
        self.missing: list[int] = []

    def read(self, now: float) -> Frame | None:
        step = self.step
        assert step is not None
        if step.frame_error is not None:
            raise recorded_error(*step.frame_error, Exception)
        if step.frame is None:
            return None
        index, time_s = step.frame
        if self._cache is None or self._cache[0] != index:
            image = self._store.image(index)
            if image is None:
                self.missing.append(index)
                if self._cache is None:
                    return None
                image = self._cache[1]  # not what the run saw: the replay cannot be exact
            self._cache = (index, image)
        return Frame(image=self._cache[1], index=index, time_s=time_s)


class ScriptedBase:
    """The loop's Base during replay: the recorded feedback and failures; sends go nowhere."""

    def __init__(self) -> None:
        self.step: StepInput | None = None
        self._failed_sends = 0
        self.sent: list[VelocityCommand] = []

    def begin(self, step: StepInput) -> None:
        self.step = step
        self._failed_sends = 0

    def send(self, command: VelocityCommand, now: float) -> None:
        self.sent.append(command)
        step = self.step
        if step is not None and self._failed_sends < step.send_errors:
            self._failed_sends += 1
            raise ActuationError("replayed send failure")

    def feedback(self, now: float) -> BaseFeedback:
        step = self.step
        assert step is not None
        if step.feedback_error is not None:
            raise recorded_error(*step.feedback_error, ActuationError)
        return step.feedback if step.feedback is not None else BaseFeedback()

    def close(self) -> None:
        pass


@dataclass(frozen=True)
class Divergence:
    step: int
    time_s: float
    what: str
    recorded: object
    replayed: object

    def describe(self) -> str:
        return (f"step {self.step} (t = {self.time_s:.3f} s): {self.what} was "
                f"{self.recorded!r} in the recording, {self.replayed!r} in the replay")


def compare_step(step: int, line: dict[str, Any], step_input: StepInput,
                 replayed: StepRecord) -> Divergence | None:
    """The first field of a step that differs: frame, state, events, command, halt reason."""
    command = (replayed.command.linear_m_s, replayed.command.angular_rad_s)
    checks: list[tuple[str, object, object]] = [
        ("frame index", line.get("frame_index"), replayed.frame_index),
        ("state", line.get("state"), replayed.state),
        ("events", list(line.get("events", [])), list(replayed.events)),
        ("command", step_input.command, command),
        ("halt reason", line.get("halt_reason"), replayed.halt_reason),
    ]
    for what, recorded, now in checks:
        if recorded != now:
            return Divergence(step, step_input.t, what, recorded, now)
    return None


@dataclass(frozen=True)
class ReplayedStep:
    """One replayed step, for the caller's outputs (video, plot, log)."""

    index: int
    step_input: StepInput
    record: StepRecord
    image: np.ndarray | None
    detection: tuple[LaneObservation, DetectionDebug] | None
    divergence: Divergence | None


def replay_steps(source: ReplaySource, config: LanewardenConfig,
                 calibration: CameraCalibration | None,
                 controller: str) -> Iterator[ReplayedStep]:
    """Run the loop over the source's steps; yields each replayed step (compared with the
    recording for a run folder)."""
    first = source.frames.image(0)
    size = None if first is None else (first.shape[1], first.shape[0])
    stack = build_stack(config, controller=controller, calibration=calibration, debug_tap=True,
                        image_size=size)
    tap = stack.tap
    assert tap is not None
    frames = ScriptedFrames(source.frames)
    base = ScriptedBase()
    loop = stack.connect(frames, base)  # the very stack `run` drives: detector, controller, gate
    for k, step_input in enumerate(source.steps):
        now = step_input.t
        for request in step_input.requests:
            if request == "start":
                loop.start(now)
            elif request == "resume":
                loop.resume(now)
            else:
                loop.operator_stop(now)
        frames.step = step_input
        base.begin(step_input)
        record = loop.step(now)
        detection = None
        if tap.last is not None and tap.last[0] == record.frame_index and record.observation:
            detection = (tap.last[1], tap.last[2])
        tap.last = None
        divergence = None
        if source.recorded is not None:
            divergence = compare_step(k, source.recorded[k], step_input, record)
        image = frames._cache[1] if frames._cache is not None else None
        yield ReplayedStep(k, step_input, record, image, detection, divergence)
    source.frames.close()


def missing_frames(source: ReplaySource) -> int:
    """Frames a run folder's steps name that are not in its frames/ (dropped while recording)."""
    if source.kind != "run":
        return 0
    wanted = {s.frame[0] for s in source.steps if s.frame is not None}
    folder = source.frames
    assert isinstance(folder, RunFolderFrames)
    return sum(not (folder.folder / f"{i:06d}{folder.suffix}").exists() for i in wanted)


