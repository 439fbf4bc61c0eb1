"""What `lanewarden replay SOURCE` replays: the steps, where their images are, and for a recorded
run what it recorded. `open_replay_source` recognises SOURCE:

- a run folder (`lanewarden run --record`): its run.mcap (formats 2 and 3,
  lanewarden.run_mcap), or the run.jsonl and frames/ of format 1; a Lanewarden run.mcap on its
  own is the same recording (it carries its meta, config and calibration). Its steps are fed
  back exactly as recorded; frames recorded as perception's prepared input come out as
  `PreparedImage`s, which the detector takes as they are;
- a ROS 2 bag (an .mcap or .db3 file, or a rosbag2 folder with metadata.yaml) with a
  `sensor_msgs/msg/Image` or `CompressedImage` topic (the only one, or `--topic`): one step per
  image at its header stamp;
- a Donkeycar tub (catalog_*.catalog + images/): one step per record at its `_timestamp_ms`;
- a video file, or a folder or glob of camera frames (images of one size): one step per frame at
  the video's frame rate or the configured camera rate.

Everything read is bounded and checked before it costs time or memory (a recording is input like
any other file): the YAML documents by lanewarden.documents' limits, every recorded step by
lanewarden.run_record (types, finite and increasing times, a bounded span), images by
`perception.max_image_pixels` from their header before decoding, MCAP and bag files by
lanewarden.ros_bag. A problem is one line naming the file (and line, message or field): a
`UsageError` or `InputFileError`, exit code 2. A recording that is readable but not whole (cut
short, its last line damaged, no summary) replays as far as it goes and says so in `incomplete`.

Never reads a clock, never prints.
"""

from __future__ import annotations

import io
import math
import os
import tempfile
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from lanewarden.actuation.base import BaseFeedback
from lanewarden.camera_source import (
    NOT_A_VIDEO,
    image_sequence_paths,
    quiet_opencv,
    require_camera_view,
)
from lanewarden.config import LanewardenConfig, config_from_mapping, load_config
from lanewarden.documents import (
    MAX_DOCUMENT_BYTES,
    NOT_A_REGULAR_FILE,
    is_special_file,
    leads_outside,
    parse_yaml_text,
    read_json,
    shorten,
    shown_value,
)
from lanewarden.errors import ConfigError, InputFileError, UsageError
from lanewarden.image_files import (
    IMAGE_SUFFIXES,
    decode_image,
    file_problem,
    header_facts,
    header_problem,
    read_image,
    too_many_pixels,
)
from lanewarden.perception.calibration import (
    CameraCalibration,
    load_calibration,
    require_usable_calibration,
)
from lanewarden.perception.calibration_config import CalibrationConfig
from lanewarden.perception.detector import PreparedImage
from lanewarden.perception.errors import PerceptionError
from lanewarden.ros_bag import (
    EMPTY,
    Bag,
    BagMessage,
    BagTopic,
    McapFile,
    decode,
    is_bag,
    message_name,
    open_bag,
)
from lanewarden.run_mcap import (
    CALIBRATION_ATTACHMENT,
    COMPRESSED_IMAGE,
    CONFIG_ATTACHMENT,
    IMAGE,
    IMAGE_KINDS,
    IMAGE_TOPIC,
    META_NAME,
    PERCEPTION_INPUT,
    STEP_TOPIC,
    SUMMARY_NAME,
)
from lanewarden.run_outcome import LoopEnd
from lanewarden.run_record import (
    MAX_RUN_DURATION_S,
    MAX_STEP_BYTES,
    MAX_STEPS,
    READABLE_FORMATS,
    RecordedStep,
    StepError,
    StepInput,
    StepTimes,
    read_step,
)
from lanewarden.wording import shown_name

SOURCE_HELP = ("a run folder (lanewarden run --record) or its run.mcap, a ROS 2 bag (.mcap, .db3 "
               "or a rosbag2 folder), a video file, a folder or glob of camera frames, or a "
               "Donkeycar tub")
RUN_MCAP = "run.mcap"
#: Files that mark a folder as lanewarden's own output (sim, replay, demo), not a recording.
OUTPUT_MARKERS = ("metrics.json", "report.html")
#: sensor_msgs/msg/Image encodings replay decodes, and how to make BGR (or gray) of them.
RAW_ENCODINGS: dict[str, tuple[int, int | None]] = {
    "mono8": (1, None), "8UC1": (1, None), "bgr8": (3, None), "8UC3": (3, None),
    "rgb8": (3, cv2.COLOR_RGB2BGR), "bgra8": (4, None), "rgba8": (4, cv2.COLOR_RGBA2BGR),
    "yuv422_yuy2": (2, cv2.COLOR_YUV2BGR_YUY2), "yuyv": (2, cv2.COLOR_YUV2BGR_YUY2),
}
IMAGE_TYPES = (IMAGE, COMPRESSED_IMAGE)
#: A format-2 recording's meta names no kind of frames: the camera's gray PNG or colour JPEG.
CAMERA_GRAY_OR_JPEG = "camera"


# ---- where the images come from ---------------------------------------------------------------
class FrameStore:
    """Images by frame index. Subclasses: files, a video, a run's or a bag's messages.
    `undecoded`: the indices of frames a recorded run holds that did not decode (damaged), as
    against frames it never recorded (dropped while recording)."""

    def __init__(self) -> None:
        self.undecoded: set[int] = set()

    def image(self, index: int) -> np.ndarray | None:
        raise NotImplementedError

    def stream_end(self) -> int | None:
        """The first frame index the source's stream could not give although its header claimed
        it (a video whose stream ends early), once a read found it; None otherwise."""
        return None

    def close(self) -> None:
        pass


class PathFrames(FrameStore):
    """Frame i is `paths[i]`; a missing, unreadable or too large file is None."""

    def __init__(self, paths: list[Path], max_pixels: int) -> None:
        super().__init__()
        self.paths = paths
        self.max_pixels = max_pixels

    def image(self, index: int) -> np.ndarray | None:
        if not 0 <= index < len(self.paths):
            return None
        image, _ = read_image(self.paths[index], cv2.IMREAD_UNCHANGED, self.max_pixels)
        return image if image is not None and image.dtype == np.uint8 else None


class RunFolderFrames(PathFrames):
    """A format-1 run folder's frames/%06d.png (or .jpg)."""

    def __init__(self, folder: Path, suffix: str, max_pixels: int) -> None:
        super().__init__([], max_pixels)
        self.folder = folder
        self.suffix = suffix

    def path(self, index: int) -> Path:
        return self.folder / f"{index:06d}{self.suffix}"

    def image(self, index: int) -> np.ndarray | None:
        path = self.path(index)
        image, _ = read_image(path, cv2.IMREAD_UNCHANGED, self.max_pixels)
        if image is None and path.exists():
            self.undecoded.add(index)
        return image


class VideoFrames(FrameStore):
    """Decodes forward only (replay asks for increasing indices). A frame larger than
    `max_pixels` (a stream whose size changes past its header's) is no frame."""

    def __init__(self, capture: cv2.VideoCapture, max_pixels: int) -> None:
        super().__init__()
        self._capture = capture
        self._max_pixels = max_pixels
        self._index = -1
        self._image: np.ndarray | None = None
        self._end: int | None = None

    def stream_end(self) -> int | None:
        return self._end

    def image(self, index: int) -> np.ndarray | None:
        if self._end is not None and index >= self._end:
            return None  # (no read again: the stream ended)
        while self._index < index:
            ok, image = self._capture.read()
            if not ok:
                self._end = self._index + 1
                return None
            self._index += 1
            too_large = too_many_pixels(image.shape[1], image.shape[0], self._max_pixels)
            self._image = None if too_large else image
        return self._image if self._index == index else None

    def close(self) -> None:
        self._capture.release()


def _decode_encoded(data: bytes, max_pixels: int) -> np.ndarray | None:
    """A compressed frame, or None when it does not decode (counted and reported by replay;
    `decode_image` silences OpenCV's own message for each)."""
    image, _ = decode_image(data, cv2.IMREAD_UNCHANGED, max_pixels)
    return image if image is not None and image.dtype == np.uint8 else None


def _decode_raw(message: Any) -> np.ndarray | None:
    channels, conversion = RAW_ENCODINGS[message.encoding]
    rows = np.frombuffer(message.data, np.uint8)[: message.step * message.height]
    rows = rows.reshape(message.height, message.step)[:, : message.width * channels]
    image = rows.reshape(message.height, message.width, channels)
    if channels == 1:
        return np.ascontiguousarray(image[:, :, 0])
    return cv2.cvtColor(image, conversion) if conversion is not None else image.copy()


class MessageFrames(FrameStore):
    """Frames from a bag's or run.mcap's image messages, decoded forward only. Frame i is the
    message whose key is i: its `sequence` (a Lanewarden run.mcap: the frame index) or its
    position on the topic (a bag)."""

    def __init__(self, bag: Bag, topic: str, max_pixels: int, *, by_sequence: bool,
                 prepared: bool = False) -> None:
        super().__init__()
        self._max_pixels = max_pixels
        self._messages: Iterator[BagMessage] = bag.messages(lambda t: t.name == topic)
        self._by_sequence = by_sequence
        self._prepared = prepared
        self._pending: BagMessage | None = None
        self._cache: tuple[int, np.ndarray | None] | None = None
        self._where = str(bag.path)

    def _key(self, message: BagMessage) -> int:
        return message.sequence if self._by_sequence else message.number

    def image(self, index: int) -> np.ndarray | None:
        if self._cache is not None and self._cache[0] == index:
            return self._cache[1]
        while True:
            message = self._pending or next(self._messages, None)
            self._pending = None
            if message is None:
                return None
            key = self._key(message)
            if key < index:
                continue
            if key > index:
                self._pending = message  # this index was not recorded (dropped)
                return None
            decoded = decode(message, self._where)
            if message.topic.type == IMAGE:
                image = _decode_raw(decoded)
            else:
                image = _decode_encoded(bytes(decoded.data), self._max_pixels)
            if image is None:
                self.undecoded.add(index)
            if self._prepared and image is not None and image.ndim == 2:
                image = image.view(PreparedImage)
            self._cache = (index, image)
            return image


# ---- the source -------------------------------------------------------------------------------
@dataclass
class ReplaySource:
    """What to replay: the steps, where their images are, and for a run what it recorded."""

    kind: str  # "run", "bag", "video", "images", "tub"
    name: str
    steps: list[StepInput]
    frames: FrameStore
    recorded: list[RecordedStep] | None = None
    config: LanewardenConfig | None = None
    calibration: CameraCalibration | None = None
    controller: str | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    config_origin: str = "defaults"
    #: Why a recorded run or a bag is not whole (cut short, a damaged last line, no summary): it
    #: replays as far as it goes, and cannot be checked.
    incomplete: list[str] = field(default_factory=list)
    #: A recorded run's frame indices that are there (None: every one its steps name).
    frames_recorded: set[int] | None = None


def camera_steps(frames: Iterable[tuple[int, float]],
                 later: tuple[str, ...] = ()) -> list[StepInput]:
    """One loop step per (frame index, time), at the frame's time: base feedback always fresh,
    a start at the first step and the operator's `later` requests (e.g. a resume) at every
    other."""
    return [StepInput(t=t, frame=(index, t), feedback=BaseFeedback(received_at_s=t),
                      requests=("start",) if k == 0 else later)
            for k, (index, t) in enumerate(frames)]


def _check_times(times: list[float], where: str) -> None:
    """Frame times strictly increasing, finite, within MAX_RUN_DURATION_S: else one line naming
    where and the frame, by its index counted from 0 as every message and metrics.json count
    frames (frames_undecoded, the loop's frame index)."""
    for i in range(1, len(times)):
        if not times[i] > times[i - 1]:
            raise InputFileError(f"{where}: frame {i} (counted from 0) is at {times[i]!r} s, "
                                 f"not after frame {i - 1} ({times[i - 1]!r} s); times must "
                                 "increase")
    if times and times[-1] - times[0] > MAX_RUN_DURATION_S:
        raise InputFileError(f"{where}: spans {times[-1] - times[0]:.0f} s, more than a "
                             f"recording may ({MAX_RUN_DURATION_S:.0f} s)")


def _read_small(path: Path, what: str) -> bytes:
    if is_special_file(path):  # reading a FIFO waits for a writer, a device may never end
        raise InputFileError(f"{path}: the {what} is {NOT_A_REGULAR_FILE}")
    try:
        with path.open("rb") as stream:
            data = stream.read(MAX_DOCUMENT_BYTES + 1)
    except OSError as exc:
        raise InputFileError(f"{path}: cannot read the {what} ({exc.strerror or exc})") from None
    if len(data) > MAX_DOCUMENT_BYTES:
        raise InputFileError(f"{path}: the {what} is larger than {MAX_DOCUMENT_BYTES // 1000} kB, "
                             "refusing to read it")
    return data


def _json_problem(exc: Exception) -> str:
    """Why a text is not JSON, in a few words (Python's parser recurses: a few kB of '[' are
    more than it nests)."""
    return "nested too deeply" if isinstance(exc, RecursionError) else shorten(str(exc))


def _unsaid_end(summary: Mapping[str, Any]) -> str:
    """'' when a recorded summary says what ended the run (a valid `ended_by`, which the replay
    ends the same way by), else what it lacks. Without it the replay cannot tell where the run
    ended, as for a run cut short: `--check` had passed a recording whose summary was `{}` (or
    held values of the wrong types) while saying it stopped where its steps stop. A summary
    written before `ended_by` was (2026-12-02: its `end_reason` text alone) is whole: such a run
    ends where its steps stop."""
    if LoopEnd.from_json(summary.get("ended_by")) is not None or (
            "ended_by" not in summary and isinstance(summary.get("end_reason"), str)):
        return ""
    return ("does not say what ended the run (no valid 'ended_by'): the replay cannot tell "
            "where it ended")


def _json_object(data: bytes, where: str, what: str) -> dict[str, Any]:
    try:
        value = read_json(data.decode("utf-8"))
    except (ValueError, RecursionError) as exc:
        raise InputFileError(f"{where}: the {what} is not JSON ({_json_problem(exc)})") from None
    if not isinstance(value, dict):
        raise InputFileError(f"{where}: the {what} is not a JSON object")
    return value


def _recorded_config(text: bytes, where: str) -> LanewardenConfig:
    try:
        data = parse_yaml_text(text.decode("utf-8"), where, ConfigError)
    except UnicodeDecodeError:
        raise ConfigError(f"{where}: not UTF-8 text") from None
    return config_from_mapping(data, where)


def _recorded_calibration(data: bytes, where: str) -> CameraCalibration:
    """A calibration carried inside a recording, read by the same code as a file."""
    if len(data) > MAX_DOCUMENT_BYTES:
        raise InputFileError(f"{where}: larger than {MAX_DOCUMENT_BYTES // 1000} kB, refusing "
                             "to read it")
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / CALIBRATION_ATTACHMENT
        path.write_bytes(data)
        try:
            return load_calibration(path)
        except PerceptionError as exc:
            raise InputFileError(f"{where}: {str(exc).removeprefix(f'{path}: ')}") from None


def _step_problem(where: str, exc: StepError | str) -> InputFileError:
    return InputFileError(f"{where}: {exc}; not a recorded step lanewarden can replay")


class _StepReader:
    """Recorded steps in order, each checked (run_record.read_step, StepTimes, MAX_STEPS)."""

    def __init__(self) -> None:
        self.steps: list[StepInput] = []
        self.recorded: list[RecordedStep] = []
        self._times = StepTimes()

    def add(self, line: object, where: str) -> None:
        if len(self.steps) >= MAX_STEPS:
            raise InputFileError(f"{where}: more than {MAX_STEPS} steps; longer than a "
                                 "recording replay reads")
        try:
            step_input, recorded = read_step(line)
        except StepError as exc:
            raise _step_problem(where, exc) from None
        problem = self._times.check(step_input.t)
        if problem:
            raise _step_problem(where, problem)
        self.steps.append(step_input)
        self.recorded.append(recorded)


def _load_run_mcap(path: Path, name: str, max_pixels: int) -> ReplaySource:
    """A format-2 recording: its steps, meta, config, calibration and summary from run.mcap."""
    bag = Bag(path, [McapFile(path)])
    mcap = bag.files[0]
    assert isinstance(mcap, McapFile)
    reader = _StepReader()
    recorded_frames: set[int] = set()
    image_topics = {topic for topic, _ in IMAGE_KINDS.values()}
    seen_topics: set[str] = set()
    for message in bag.messages(lambda t: t.name == STEP_TOPIC or t.name in image_topics):
        where = f"{path}: {message_name(message.topic.name, message.number)}"
        if message.topic.name != STEP_TOPIC:
            _check_image_message(message, decode(message, str(path)), where, max_pixels)
            recorded_frames.add(message.sequence)
            seen_topics.add(message.topic.name)
            continue
        if not reader.steps:
            _check_format(mcap, path)
        text = decode(message, str(path)).record
        if len(text) > MAX_STEP_BYTES:
            raise _step_problem(where, f"record is {len(text)} characters (at most "
                                f"{MAX_STEP_BYTES})")
        try:
            line = read_json(text)
        except (ValueError, RecursionError) as exc:
            raise _step_problem(where, f"record is not JSON ({_json_problem(exc)})") from None
        reader.add(line, where)
        refused = reader.steps[-1]
        if refused.frame_refused is not None and refused.frame is not None:
            recorded_frames.add(refused.frame[0])  # perception refused it: nothing to record
    meta = _check_format(mcap, path)
    if not reader.steps:
        ended = ""  # a run that ended before its first step says why in its summary
        if SUMMARY_NAME in mcap.metadata:
            about = _json_object(mcap.metadata[SUMMARY_NAME].get("summary", "").encode(),
                                 str(path), "recorded summary").get("end_reason")
            ended = f": the run ended before its first step ({shorten(str(about), 300)})" if (
                about) else ""
        elif mcap.cut_short is not None:  # as for a bag cut before its first image
            ended = (f": cut short before its first step (it {mcap.cut_short}); a run killed at "
                     "its start, or its disk full?")
        raise InputFileError(f"{path}: no recorded steps{ended}")
    kind = meta.get("image", CAMERA_GRAY_OR_JPEG)
    topic = meta.get("frames", IMAGE_TOPIC)
    known = {k: t for k, (t, _) in IMAGE_KINDS.items()} | {CAMERA_GRAY_OR_JPEG: IMAGE_TOPIC}
    if not isinstance(kind, str) or known.get(kind) != topic:
        raise InputFileError(
            f"{path}: its meta says its frames are {shorten(repr(kind))} on "
            f"{shorten(repr(topic))}; replay reads "
            + ", ".join(f"{k} on {t}" for k, (t, _) in IMAGE_KINDS.items()))
    if seen_topics - {topic}:
        raise InputFileError(f"{path}: images on {', '.join(sorted(seen_topics - {topic}))}, but "
                             f"its meta says its frames are on {topic}")
    incomplete = []
    summary: dict[str, Any] = {}
    if SUMMARY_NAME in mcap.metadata:
        summary = _json_object(mcap.metadata[SUMMARY_NAME].get("summary", "").encode(),
                               str(path), "recorded summary")
    if mcap.cut_short is not None:
        incomplete.append(f"{path.name} was cut short after {len(reader.steps)} steps (it "
                          f"{mcap.cut_short}): the run was killed or its disk filled")
    elif not summary:
        incomplete.append(f"{path.name} has no summary: the run did not end normally")
    elif gap := _unsaid_end(summary):
        incomplete.append(f"{path.name}'s summary {gap}")
    config = calibration = None
    if CONFIG_ATTACHMENT in mcap.attachments:
        config = _recorded_config(mcap.attachments[CONFIG_ATTACHMENT],
                                  f"{path}:{CONFIG_ATTACHMENT}")
    if CALIBRATION_ATTACHMENT in mcap.attachments:
        calibration = _recorded_calibration(mcap.attachments[CALIBRATION_ATTACHMENT],
                                            f"{path}:{CALIBRATION_ATTACHMENT}")
    return ReplaySource(
        kind="run", name=name, steps=reader.steps,
        frames=MessageFrames(bag, topic, max_pixels, by_sequence=True,
                             prepared=kind == PERCEPTION_INPUT),
        recorded=reader.recorded,
        config=config, calibration=calibration, controller=_recorded_controller(meta), meta=meta,
        summary=summary, incomplete=incomplete, frames_recorded=recorded_frames,
        config_origin=(f"recorded ({path}:{CONFIG_ATTACHMENT})" if config is not None
                       else "defaults"))


def _recorded_controller(meta: dict[str, Any]) -> str | None:
    """The controller a run's meta names (None: none, or not a name: a list had been a
    TypeError where `replay` looked it up)."""
    controller = meta.get("controller")
    return controller if isinstance(controller, str) else None


def _check_format(mcap: McapFile, path: Path) -> dict[str, Any]:
    """The recording's meta; InputFileError when its format is not one replay reads."""
    record = mcap.metadata.get(META_NAME)
    if record is None and mcap.cut_short is not None and not mcap.topics:
        # cut within its first records, before any channel: a Lanewarden recording's meta comes
        # first (another program's file cut anywhere is still not one)
        detail = "empty (0 bytes)" if mcap.cut_short == EMPTY else mcap.cut_short
        raise InputFileError(f"{path}: cut short before its '{META_NAME}' metadata record "
                             f"({detail}): a run killed as it began, or its disk full? (or not "
                             "a Lanewarden recording)")
    if record is None:
        raise InputFileError(f"{path}: no '{META_NAME}' metadata record before its steps; not "
                             "a Lanewarden recording")
    meta = _json_object(record.get("meta", "").encode(), str(path), "recorded meta")
    if meta.get("format") not in READABLE_FORMATS:
        raise InputFileError(f"{path}: recording format {meta.get('format')!r}, this lanewarden "
                             f"replays formats {', '.join(map(str, READABLE_FORMATS))}")
    return meta


def _is_run_mcap(path: Path) -> bool:
    """A Lanewarden recording: its 'lanewarden' metadata comes before its first message."""
    mcap = McapFile(path)
    for _ in mcap.messages():
        break
    return META_NAME in mcap.metadata


def _load_legacy_run(folder: Path, max_pixels: int) -> ReplaySource:
    """A format-1 run folder: meta.json, run.jsonl, frames/, config.yaml, calibration.yaml."""
    meta = _json_object(_read_small(folder / "meta.json", "recording's meta.json"),
                        str(folder / "meta.json"), "recording's meta.json")
    if meta.get("format") != 1:
        raise InputFileError(f"{folder / 'meta.json'}: recording format {meta.get('format')!r} "
                             "with a run.jsonl; this lanewarden replays format 1 that way")
    run_log = folder / "run.jsonl"
    reader = _StepReader()
    incomplete = []
    try:
        stream = run_log.open("rb")
    except OSError as exc:
        raise InputFileError(f"{run_log}: cannot read ({exc.strerror or exc})") from None
    with stream:
        number = 0
        while raw := stream.readline(MAX_STEP_BYTES + 1):
            number += 1
            where = f"{run_log}:{number}"
            if len(raw) > MAX_STEP_BYTES:
                raise _step_problem(where, f"a line longer than {MAX_STEP_BYTES} bytes")
            if not raw.strip():
                continue
            try:
                line = read_json(raw)
            except (ValueError, RecursionError) as exc:
                if not raw.endswith(b"\n") and not stream.read(1):
                    incomplete.append(f"the last line of run.jsonl ({number}) is cut short: "
                                      "the run was killed or its disk filled")
                    break
                raise _step_problem(where, f"not JSON ({_json_problem(exc)})") from None
            reader.add(line, where)
    if not reader.steps:
        raise InputFileError(f"{run_log}: no recorded steps")
    config_path = folder / "config.yaml"
    config = load_config(config_path) if config_path.exists() else None
    calibration_path = folder / "calibration.yaml"
    calibration = load_calibration(calibration_path) if calibration_path.exists() else None
    summary_path = folder / "summary.json"
    summary: dict[str, Any] = {}
    if summary_path.exists():
        summary = _json_object(_read_small(summary_path, "recording's summary"),
                               str(summary_path), "recording's summary")
        if gap := _unsaid_end(summary):
            incomplete.append(f"summary.json {gap}")
    else:
        incomplete.append("no summary.json: the run did not end normally (killed, or its disk "
                          "filled)")
    pattern = str(meta.get("frames", "frames/%06d.png"))
    suffix = ".jpg" if pattern.endswith(".jpg") else ".png"
    _check_frames_folder(folder / "frames", {f"{s.frame[0]:06d}{suffix}" for s in reader.steps
                                             if s.frame is not None})
    return ReplaySource(
        kind="run", name=folder.name, steps=reader.steps,
        frames=RunFolderFrames(folder / "frames", suffix, max_pixels),
        recorded=reader.recorded, config=config, calibration=calibration,
        controller=_recorded_controller(meta), meta=meta, summary=summary, incomplete=incomplete,
        config_origin=f"recorded ({config_path})" if config is not None else "defaults")


def _refuse_a_link_out(path: Path, inside: Path) -> None:
    """InputFileError when `path` is a link whose target lies outside the folder `inside`
    (resolved)."""
    if path.is_symlink() and leads_outside(path, inside):
        raise InputFileError(f"{shown_name(str(path))}: a link to "
                             f"{shown_name(str(path.resolve()))}, outside {inside}; expected the "
                             "recording's own frames in its folder")


def _check_frames_folder(frames: Path, names: set[str]) -> None:
    """InputFileError when a format-1 run's `frames` folder cannot give the frames its steps
    name (`names`, such as '000005.png'): it is missing, no folder (a file, a link to itself),
    unreadable, holds none of them, or holds one as something that is no image file (a FIFO or
    a device, refused unopened, or a folder). A frame that is simply not there was dropped while
    recording: the replay counts it. (A missing frames/ had replayed with 0 frames and exit 0; a
    link to /dev/zero as a frame was 'a damaged or cut file?'.)"""
    expected = "expected the folder of the recording's frames" + (f" ({min(names)}, ...)"
                                                                  if names else "")
    if not frames.is_dir():
        what = _what_is_there(frames, "folder") if os.path.lexists(frames) else "no such folder"
        raise InputFileError(f"{frames}: {what}, {expected}")
    # the recording's own frames: a link out of its folder (frames/ to another folder, a frame
    # to /etc/passwd) is refused, as survey refuses one out of its FOLDER (an attacker's review)
    inside = frames.parent.resolve()
    _refuse_a_link_out(frames, inside)
    try:
        with os.scandir(frames) as entries:  # a regular file costs no stat (its d_type)
            listed = [(e.name, e.is_file(), e.is_symlink()) for e in entries if e.name in names]
    except OSError as exc:
        raise InputFileError(f"{frames}: cannot read this folder ({exc.strerror or exc})"
                             ) from None
    there = {name: regular for name, regular, _ in listed}
    if names and not there:
        raise InputFileError(f"{frames}: none of the {len(names)} frames the recording's steps "
                             f"name is there, {expected}")
    problems = [(name, why) for name, regular in sorted(there.items()) if not regular
                and (why := file_problem(frames / name)) and why != "no such file"]
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise InputFileError(f"{frames / problems[0][0]}: {problems[0][1]}{more}, expected a "
                             "recorded frame (an image file)")
    for name, _, link in listed:  # (a link to a device was said above: not an image file)
        if link:
            _refuse_a_link_out(frames / name, inside)


def _check_image_message(message: BagMessage, decoded: Any, where: str,
                         max_pixels: int) -> float:
    """The image's header stamp (seconds), once its size and encoding check out."""
    try:
        stamp = decoded.header.stamp
        sec, nanosec = int(stamp.sec), int(stamp.nanosec)
        if message.topic.type == IMAGE:
            width, height = int(decoded.width), int(decoded.height)
            if decoded.encoding not in RAW_ENCODINGS:
                raise InputFileError(
                    f"{where}: encoding {shorten(repr(decoded.encoding))} is not one replay "
                    f"decodes ({', '.join(RAW_ENCODINGS)})")
            channels = RAW_ENCODINGS[decoded.encoding][0]
            if width <= 0 or height <= 0 or decoded.step < width * channels or (
                    len(decoded.data) < decoded.step * height):
                raise InputFileError(
                    f"{where}: a {width}x{height} {decoded.encoding} image with step "
                    f"{decoded.step} and {len(decoded.data)} bytes of data does not add up")
            if channels == 2 and width % 2:  # YUV 4:2:2: two pixels share their U and V
                raise InputFileError(f"{where}: a {width}x{height} {decoded.encoding} image: "
                                     "expected an even width (two pixels share one U and V)")
            problem = too_many_pixels(width, height, max_pixels)
        else:
            problem = header_problem(io.BytesIO(bytes(decoded.data)), max_pixels)
    except AttributeError:
        raise InputFileError(f"{where}: not a {message.topic.type}") from None
    if problem:
        raise InputFileError(f"{where}: {problem}")
    if not 0 <= nanosec < 1_000_000_000:
        raise InputFileError(f"{where}: header.stamp.nanosec = {nanosec}: expected 0 to "
                             "999999999")
    return sec + nanosec * 1e-9


def _load_bag(path: Path, topic: str | None, max_pixels: int) -> ReplaySource:
    """A ROS 2 bag's image topic: one step per image at its header stamp."""
    bag = open_bag(path)
    stamps: dict[str, list[float]] = {}
    logged: dict[str, list[float]] = {}

    def is_image(bag_topic: BagTopic) -> bool:
        return bag_topic.type in IMAGE_TYPES and (topic is None or bag_topic.name == topic)

    for message in bag.messages(is_image):
        where = f"{path}: {message_name(message.topic.name, message.number)}"
        stamp = _check_image_message(message, decode(message, str(path)), where, max_pixels)
        stamps.setdefault(message.topic.name, []).append(stamp)
        logged.setdefault(message.topic.name, []).append(message.log_time_ns * 1e-9)
        if len(stamps[message.topic.name]) > MAX_STEPS:
            raise InputFileError(f"{where}: more than {MAX_STEPS} images; longer than replay "
                                 "reads")
    topics = bag.topics
    cut = [(bag_file.path, bag_file.cut_short) for bag_file in bag.files
           if isinstance(bag_file, McapFile) and bag_file.cut_short is not None]
    if cut and not stamps:
        cut_file, how = cut[0]
        raise InputFileError(f"{cut_file}: " + ("empty (0 bytes)" if how == EMPTY else
                             f"cut short before any image (it {how})")
                             + "; a recording killed at its start, or its disk full?")
    if topic is not None and topic not in stamps:
        found = topics.get(topic)
        raise UsageError(f"--topic {topic}: " + (
            f"is {found.type}, not an image topic" if found is not None and found.type not in
            IMAGE_TYPES else "has no images in " + str(path)) + "; image topics: "
            + _candidates(topics))  # (only the named topic was read: no counts)
    if topic is None:
        if not stamps:
            raise InputFileError(f"{path}: no sensor_msgs/msg/Image or CompressedImage messages "
                                 f"(topics: {', '.join(sorted(topics)) or 'none'})")
        if len(stamps) > 1:
            raise UsageError(f"SOURCE '{path}': several image topics, choose one with --topic: "
                             + _candidates(topics, stamps))
        topic = next(iter(stamps))
    times = stamps[topic]
    note = "header stamps"
    if not any(times):  # a driver that does not stamp its images: the bag's receive times
        times, note = logged[topic], "receive times (the header stamps are all zero)"
    _check_times(times, f"{path}: {topic}")
    start = times[0]
    rel = [t - start for t in times]
    # a bag cut short (`ros2 bag record` killed, a full disk, half a copy): what it has is
    # replayed, and said, as for a run cut short
    incomplete = [f"{cut_file.name} was cut short after {len(rel)} images on {topic} (it "
                  f"{how})" for cut_file, how in cut]
    return ReplaySource(kind="bag", name=f"{path.stem or path.name}",
                        steps=camera_steps(enumerate(rel)),
                        frames=MessageFrames(bag, topic, max_pixels, by_sequence=False),
                        meta={"topic": topic, "times": note,
                              "frames_per_s_recorded": len(rel) / max(rel[-1], 1e-9)},
                        incomplete=incomplete)


def _candidates(topics: dict[str, BagTopic],
                stamps: dict[str, list[float]] | None = None) -> str:
    """The image topics to choose from, 'none' without one: those with images (`stamps`: each
    one's image stamps), with their type and count ('/front (CompressedImage, 10 images)');
    without `stamps` (only a named topic was read), every topic of an image type, with its type
    ('/front (CompressedImage)')."""
    names = (sorted(stamps) if stamps is not None
             else sorted(name for name, t in topics.items() if t.type in IMAGE_TYPES))
    return ", ".join(
        f"{name} ({topics[name].type.rsplit('/', 1)[-1]}"
        + ("" if stamps is None else f", {len(stamps[name])} images") + ")"
        for name in names) or "none"


def _load_tub(folder: Path, catalogs: list[Path], max_pixels: int) -> ReplaySource:
    records: list[dict[str, Any]] = []
    for catalog in catalogs:
        try:
            text = _read_small(catalog, "tub catalog").decode("utf-8")
        except UnicodeDecodeError as exc:
            raise InputFileError(f"{catalog}: not UTF-8 text ({exc.reason} at byte "
                                 f"{exc.start})") from None
        for number, raw in enumerate(text.splitlines(), 1):
            if raw.strip():
                try:
                    record = read_json(raw)
                except (ValueError, RecursionError) as exc:
                    raise InputFileError(f"{catalog}:{number}: not a JSON record "
                                         f"({_json_problem(exc)})") from None
                if not isinstance(record, dict):
                    raise InputFileError(f"{catalog}:{number}: a {type(record).__name__}, "
                                         "expected a JSON object (a tub record)")
                records.append(record)
                if len(records) > MAX_STEPS:  # (as a recording's steps: a tub's catalogs
                    # were read whole, 896k records naming one image in 59 MB of catalogs)
                    raise InputFileError(f"{folder}: more than {MAX_STEPS} records; longer "
                                         "than replay reads")
    deleted: set[int] = set()
    manifest = folder / "manifest.json"
    if manifest.exists():
        for raw in _read_small(manifest, "tub manifest").decode("utf-8", "replace").splitlines():
            try:
                entry = read_json(raw)
            except (ValueError, RecursionError):
                continue
            if isinstance(entry, dict) and isinstance(entry.get("deleted_indexes"), list):
                deleted |= {i for i in entry["deleted_indexes"] if isinstance(i, int)}
    try:
        # (an _index that is no whole number, [0], is no record: it had been looked up among
        # the deleted ones, a TypeError traceback)
        if bad := next((r for r in records if not isinstance(r.get("_index"), int)
                        or isinstance(r.get("_index"), bool)), None):
            raise TypeError(f"_index {shown_value(bad.get('_index'))} is not a whole number")
        records = [r for r in records if r["_index"] not in deleted]
        records.sort(key=lambda r: int(r["_index"]))
        paths = [folder / "images" / str(r["cam/image_array"]) for r in records]
        stamps = [float(r["_timestamp_ms"]) / 1000.0 for r in records]
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise UsageError(f"{folder}: a tub record lacks _index, _timestamp_ms or cam/image_array "
                         f"({shorten(str(exc))})") from None
    if not records:
        raise UsageError(f"{folder}: the tub holds no records")
    # each image and the first record naming it (records may name one image many times: each
    # image is checked and its header read once)
    named: dict[Path, dict[str, Any]] = {}
    for record, path in zip(records, paths, strict=True):
        named.setdefault(path, record)
    for path, record in named.items():
        # a record names a file in images/: never one elsewhere (../../etc/passwd), never one
        # that is not there (the replay would go on with fewer frames and no word)
        if path.parent != folder / "images" or path.name in ("", ".", ".."):
            raise InputFileError(f"{folder}: record {record.get('_index')}: cam/image_array "
                                 f"{shorten(str(record['cam/image_array']))!r}: expected a file "
                                 "name in images/")
        if why := file_problem(path):
            raise InputFileError(f"{folder}: record {record.get('_index')}: {path}: {why}")
    _one_size(list(named), str(folder), max_pixels)
    if not all(math.isfinite(s) for s in stamps):
        raise UsageError(f"{folder}: a tub record's _timestamp_ms is not a finite number")
    times = [t - stamps[0] for t in stamps]
    if any(b <= a for a, b in zip(times, times[1:], strict=False)):
        raise UsageError(f"{folder}: the tub's _timestamp_ms do not increase frame to frame")
    _check_times(times, str(folder))
    return ReplaySource(kind="tub", name=folder.name, steps=camera_steps(enumerate(times)),
                        frames=PathFrames(paths, max_pixels),
                        meta={"frames_per_s_recorded": len(times) / max(times[-1], 1e-9)})


def _one_size(paths: list[Path], source: str, max_pixels: int) -> None:
    """UsageError unless the images are of one size (from their headers, within the limit)."""
    sizes: dict[tuple[int, int], Path] = {}
    for path in paths:
        size, problem = header_facts(path, max_pixels)  # one read of each header
        if problem:
            raise InputFileError(f"{path}: {problem}")
        if size is None:
            continue  # a format Pillow does not know: refused when decoded
        sizes.setdefault(size, path)
        if len(sizes) > 1:
            (a, path_a), (b, path_b) = list(sizes.items())[:2]
            raise UsageError(
                f"SOURCE '{source}': images of different sizes ({path_a.name} {a[0]}x{a[1]}, "
                f"{path_b.name} {b[0]}x{b[1]}): not a sequence of camera frames; expected "
                f"{SOURCE_HELP}")


def _frame_sequence(source: str, paths: list[Path], max_pixels: int,
                    camera_rate_hz: float) -> ReplaySource:
    """A folder or glob of camera frames: images of one size (from their headers)."""
    if not paths:
        raise UsageError(f"SOURCE '{source}': no images there; expected {SOURCE_HELP}")
    _one_size(paths, source, max_pixels)
    times = [i / camera_rate_hz for i in range(len(paths))]
    path = Path(source)
    name = path.name or source
    if any(c in name for c in "*?["):  # a glob: the folder it picks from names the replay
        name = path.parent.resolve().name or "images"
    return ReplaySource(kind="images", name=name,
                        steps=camera_steps(enumerate(times)),
                        frames=PathFrames(paths, max_pixels))


def _one_image(path: Path, source: str, max_pixels: int, camera_rate_hz: float) -> ReplaySource:
    """One photo, a sequence of one frame, read as `detect` and `survey` read it: refused in one
    line when it cannot be decoded (OpenCV's video reader took a cut JPEG for a 1-frame video
    and a text file for a video whose only frame it could not decode, a summary then the
    error)."""
    image, why = read_image(path, cv2.IMREAD_UNCHANGED, max_pixels)
    if image is None:
        raise InputFileError(f"SOURCE '{source}': {why}")
    return replace(_frame_sequence(source, [path], max_pixels, camera_rate_hz), name=path.stem)


def _video(path: Path, source: str, camera_rate_hz: float, max_pixels: int) -> ReplaySource:
    # FFmpeg logs each frame it cannot decode itself; the replay says what it could not read.
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
    with quiet_opencv():
        capture = cv2.VideoCapture(str(path))
        opened = capture.isOpened()
    count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT) or 0) if opened else 0
    if not opened or count <= 0:
        capture.release()
        raise UsageError(f"SOURCE '{source}': {NOT_A_VIDEO}; expected "
                         f"{SOURCE_HELP}")
    # the container's header says both, before a frame is decoded: a 12 kB AVI claiming 2**31
    # frames had made a list of as many times (a MemoryError at 5 GB), and claiming a million,
    # a replay of a million steps (1.2 GB); a 2 MB MPEG-4 of 8000x8000 frames took 1.7 GB.
    # No codec stores a frame in less than a byte.
    width, height = (int(capture.get(prop) or 0)
                     for prop in (cv2.CAP_PROP_FRAME_WIDTH, cv2.CAP_PROP_FRAME_HEIGHT))
    size = path.stat().st_size
    problem = (f"{count} frames, more than replay reads ({MAX_STEPS})" if count > MAX_STEPS
               else f"its header claims {count} frames in {size} bytes" if count > size
               else too_many_pixels(width, height, max_pixels))
    if problem:
        capture.release()
        raise InputFileError(f"SOURCE '{source}': {problem}")
    fps = float(capture.get(cv2.CAP_PROP_FPS) or 0.0)
    fps = fps if 1.0 <= fps <= 240.0 else camera_rate_hz
    # a run's own video (captions and a map around the camera view) is not a camera's view,
    # as `run --camera` says too; read its first frame, then start again from the beginning
    with quiet_opencv():
        ok, first = capture.read()
    if ok and first is not None:
        try:
            require_camera_view(first, f"SOURCE '{source}'")
        except UsageError:
            capture.release()
            raise
    capture.release()
    with quiet_opencv():
        capture = cv2.VideoCapture(str(path))
    times = [i / fps for i in range(count)]
    return ReplaySource(kind="video", name=path.stem, steps=camera_steps(enumerate(times)),
                        frames=VideoFrames(capture, max_pixels), meta={"fps": fps})


def _what_is_there(path: Path, wanted: str) -> str:
    """What is at `path` (which exists), in a few words, for a message that expected a `wanted`
    ('file', 'folder') there."""
    if path.is_dir():
        return "a folder"
    if path.is_file():
        return "a file"
    if is_special_file(path):
        return NOT_A_REGULAR_FILE
    return f"a link that leads to no {wanted}"  # to nothing, or to itself


def _recording_file_problem(path: Path, expected: str = "the recording file") -> str:
    """Why the recording file a run folder names (run.mcap, run.jsonl, meta.json) cannot be read
    although something of that name is there, or '' (missing, or a regular file): a folder said
    'a run folder without its recording' of a run.mcap that was a FIFO, a link to /dev/zero, a
    folder or a link to itself, and 'no recording and no images there' of a FIFO meta.json (an
    attacker's reviews)."""
    if not os.path.lexists(path) or path.is_file():
        return ""
    return f"{path}: {_what_is_there(path, 'file')}, expected {expected}"


def frame_name(source: ReplaySource, index: int, files_of: tuple[str, ...] = ("images",)) -> str:
    """"frame 51", and where the frames are files of a source of a kind in `files_of` (by
    default a folder or pattern of images, whose names the numbers do not tell) the file too:
    "frame 51 (frame_0204.png)" (a new user had to count files to find a frame a survey named
    by number; replay's error lines name a tub's files too)."""
    paths = (source.frames.paths if isinstance(source.frames, PathFrames)
             and source.kind in files_of else None)
    return f"frame {index}" + (f" ({paths[index].name})" if paths and 0 <= index < len(paths)
                               else "")


#: Each `ReplaySource.kind` in words, for a line naming what SOURCE was taken for.
KIND_WORDS = {"run": "a recorded run", "bag": "a ROS bag", "tub": "a Donkeycar tub",
              "images": "a folder of images", "video": "a video"}


def recording_kind(path: Path) -> str | None:
    """What recording the folder `path` is, as `_folder` recognises one ("a recorded run", "a
    ROS bag", "a Donkeycar tub"), or None: for a command that takes recordings only with more
    (`survey` needs --labels) to say so."""
    if (path / RUN_MCAP).is_file() or ((path / "run.jsonl").is_file()
                                       and (path / "meta.json").is_file()):
        return KIND_WORDS["run"]
    if is_bag(path):
        return KIND_WORDS["bag"]
    if any(path.glob("catalog_*.catalog")) and (path / "images").is_dir():
        return KIND_WORDS["tub"]
    return None


def _folder(path: Path, source: str, topic: str | None, max_pixels: int,
            camera_rate_hz: float) -> ReplaySource:
    for name in (RUN_MCAP, "run.jsonl"):
        if problem := _recording_file_problem(path / name):
            raise InputFileError(problem)
    if (path / RUN_MCAP).is_file():
        return _load_run_mcap(path / RUN_MCAP, path.name, max_pixels)
    if problem := _recording_file_problem(path / "meta.json", "the recording's meta.json"):
        raise InputFileError(problem)
    if (path / "run.jsonl").is_file() and (path / "meta.json").is_file():
        return _load_legacy_run(path, max_pixels)
    if (path / "meta.json").is_file():
        raise InputFileError(f"{path}: a run folder without its recording ({RUN_MCAP} or "
                             "run.jsonl)")
    if is_bag(path):
        return _load_bag(path, topic, max_pixels)
    catalogs = sorted(path.glob("catalog_*.catalog"))
    if catalogs and (path / "images").is_dir():
        return _load_tub(path, catalogs, max_pixels)
    markers = [name for name in OUTPUT_MARKERS if (path / name).exists()]
    if markers:
        raise UsageError(f"SOURCE '{source}': an output folder of lanewarden sim, replay or demo "
                         f"({', '.join(markers)}), not a recording; expected {SOURCE_HELP}")
    paths = image_sequence_paths(source)
    if not paths:
        raise UsageError(f"SOURCE '{source}': no recording and no images there; expected "
                         f"{SOURCE_HELP}")
    return _frame_sequence(source, paths, max_pixels, camera_rate_hz)


def open_replay_source(source: str, camera_rate_hz: float, *, topic: str | None = None,
                       max_pixels: int = LanewardenConfig().perception.max_image_pixels,
                       ) -> ReplaySource:
    """Recognise SOURCE (see the module docstring); one line naming it when it is none."""
    path = Path(source)
    if is_special_file(path):
        raise UsageError(f"SOURCE '{source}': {NOT_A_REGULAR_FILE}; expected {SOURCE_HELP}")
    if topic is not None and not is_bag(path):
        raise UsageError(f"--topic {topic}: only for a ROS 2 bag; SOURCE '{source}' is not one")
    if path.is_dir():
        return _folder(path, source, topic, max_pixels, camera_rate_hz)
    if path.is_file() and path.suffix == ".mcap" and topic is None and _is_run_mcap(path):
        name = path.parent.name if path.name == RUN_MCAP else path.stem
        return _load_run_mcap(path, name, max_pixels)
    if is_bag(path):
        return _load_bag(path, topic, max_pixels)
    paths = image_sequence_paths(source)
    if paths is not None:
        return _frame_sequence(source, paths, max_pixels, camera_rate_hz)
    if path.is_file() and path.suffix.lower() in IMAGE_SUFFIXES:
        return _one_image(path, source, max_pixels, camera_rate_hz)
    if path.is_file():
        return _video(path, source, camera_rate_hz, max_pixels)
    raise UsageError(f"SOURCE '{source}': no such file or folder; expected {SOURCE_HELP}")


def usable_calibration(calibration_path: str | None, recorded: CameraCalibration | None,
                       gates: CalibrationConfig, recorded_named: str) -> CameraCalibration | None:
    """The calibration `replay` and `survey` use: --calibration's (`calibration_path`), else the
    recording's own (`recorded`); refused in one line, as `run` refuses it
    (`require_usable_calibration`), naming the flag or, for the recording's, `recorded_named`."""
    calibration = load_calibration(calibration_path) if calibration_path else recorded
    if calibration is not None:
        require_usable_calibration(calibration, calibration.image_size, gates,
                                   f"--calibration {calibration_path}" if calibration_path
                                   else recorded_named)
    return calibration


def replay_config(source: ReplaySource, config_path: str | None) -> LanewardenConfig:
    """--config wins; else the recording's own config; else the defaults."""
    if config_path is not None:
        source.config_origin = config_path
        return load_config(config_path)
    return source.config if source.config is not None else LanewardenConfig()


def frame_indices(source: ReplaySource) -> set[int]:
    """The frames the source's steps name: every frame of it, whether it decodes or not, and for
    a run also those it did not record (dropped while recording)."""
    return {s.frame[0] for s in source.steps if s.frame is not None}


def missing_frames(source: ReplaySource) -> int:
    """Frames a run's steps name that it did not record (dropped while recording)."""
    if source.kind != "run":
        return 0
    wanted = frame_indices(source)
    if source.frames_recorded is not None:
        return len(wanted - source.frames_recorded)
    frames = source.frames
    assert isinstance(frames, RunFolderFrames)
    return sum(not frames.path(i).exists() for i in wanted)
