"""Recorded runs for the recording and replay tests, made on a fake clock: the same ControlLoop
`run` drives, a rendered clip, a SimBase, and the real RunRecorder; and the tools to change a
recording as a damaged or forged one would be (through the `mcap` library's own reader and
writer, never by patching our code).

The runner's real-time run is in test_run_end_to_end.py."""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from mcap.reader import make_reader
from mcap.writer import CompressionType
from mcap_ros2.decoder import DecoderFactory
from mcap_ros2.writer import Writer

from lanewarden.actuation.sim_base import SimBase
from lanewarden.assembly import build_stack
from lanewarden.camera_source import CameraLost
from lanewarden.config import LanewardenConfig
from lanewarden.perception.calibration import CameraCalibration
from lanewarden.recording import InputTap, RunRecorder, create_run_folder
from lanewarden.run_mcap import CAMERA_GRAY, PERCEPTION_INPUT
from lanewarden.supervisor.loop import ControlLoop, Frame, FrameSource, StepRecord

DT = 1.0 / 30.0
T0 = 1000.0 + 1.0 / 3.0  # not a round number: times must survive the trip exactly


class ClipFrames:
    """Frame i at t0 + i*DT; after the last one the clip has ended (CameraLost)."""

    def __init__(self, frames: list[np.ndarray], t0: float) -> None:
        self.frames = frames
        self.t0 = t0

    def read(self, now: float) -> Frame | None:
        i = int(np.floor((now - self.t0) / DT + 1e-9))
        if i >= len(self.frames) + 1:
            raise CameraLost(f"end of the recorded clip after {len(self.frames)} frames")
        i = min(i, len(self.frames) - 1)
        return Frame(self.frames[i], i, self.t0 + i * DT)


def record_run(folder: Path, frames: list[np.ndarray], config: LanewardenConfig, *,
               stop_at_step: int | None = None, resume_at_step: int | None = None,
               image_kind: str = PERCEPTION_INPUT,
               calibration: Path | None = None,
               loaded_calibration: CameraCalibration | None = None,
               close: bool = True, source: FrameSource | None = None) -> list[StepRecord]:
    """A run on a fake clock, recorded as `lanewarden run` records it (`close=False`: left as a
    killed run leaves it, without its end; `source`: these frames instead of `frames` at
    T0 + i * DT)."""
    create_run_folder(folder)
    recorder = RunRecorder(folder, image_kind=image_kind, epoch_offset_s=1.7e9)
    recorder.write_header({"camera": "clip", "controller": "supervised"},
                          config.model_dump(mode="json"), calibration, T0)
    tap = InputTap()

    def on_step(record: StepRecord) -> None:
        step_input, new_frame = tap.take(record.time_s)
        recorder.record(record, step_input, new_frame)

    stack = build_stack(config, calibration=loaded_calibration)  # what `run` builds
    recorder.prepare_with(stack.detector)  # as RunSession.wrap does
    loop = ControlLoop(tap.frames(source or ClipFrames(frames, T0)), stack.detector,
                       tap.gate(stack.gate), tap.base(SimBase()),
                       record=on_step)
    records = []
    for k in range(len(frames) + 3):
        now = T0 + k * DT + 0.003
        if k == 0:
            loop.start(now)
        if stop_at_step is not None and k == stop_at_step:
            loop.operator_stop(now)
        if resume_at_step is not None and k == resume_at_step:
            loop.resume(now)
        records.append(loop.step(now))
    if close:
        summary = recorder.close({"end_reason": "end of the clip", "exit_code": 0})
        assert summary.complete, summary
    return records


def rewrite_mcap(source: Path, target: Path,
                 change: Callable[[str, int, dict[str, Any]], dict[str, Any] | None],
                 attachments: dict[str, bytes] | None = None,
                 metadata: dict[str, dict[str, str]] | None = None) -> None:
    """A copy of an MCAP recording written by the `mcap` libraries, each message decoded to a
    dict and passed through `change(topic, number on its topic, message)` (None: leave it out);
    the metadata and attachments copied as they are (`attachments`, `metadata`: these instead,
    by name)."""
    with source.open("rb") as stream, target.open("wb") as out:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        writer = Writer(out, compression=CompressionType.ZSTD)
        for record in reader.iter_metadata():
            writer.add_metadata(record.name, (metadata or {}).get(record.name,
                                                                  dict(record.metadata)))
        for attachment in reader.iter_attachments():
            data = (attachments or {}).get(attachment.name, attachment.data)
            writer.add_attachment(attachment.create_time, attachment.log_time, attachment.name,
                                  attachment.media_type, data)
        registered: dict[int, Any] = {}
        numbers: dict[str, int] = {}
        for schema, channel, message, decoded in reader.iter_decoded_messages(
                log_time_order=False):
            assert schema is not None
            if schema.id not in registered:
                registered[schema.id] = writer.register_msgdef(schema.name,
                                                               schema.data.decode())
            numbers[channel.topic] = numbers.get(channel.topic, 0) + 1
            changed = change(channel.topic, numbers[channel.topic], _as_dict(decoded))
            if changed is not None:
                writer.write_message(channel.topic, registered[schema.id], changed,
                                     log_time=message.log_time,
                                     publish_time=message.publish_time,
                                     sequence=message.sequence)
        writer.finish()


def _as_dict(value: Any) -> Any:
    if hasattr(value, "__slots__") and not isinstance(value, bytes | str):
        return {name: _as_dict(getattr(value, name)) for name in value.__slots__}
    if isinstance(value, list):
        return [_as_dict(v) for v in value]
    return value


def change_step(number: int, edit: Callable[[dict[str, Any]], None]
                ) -> Callable[[str, int, dict[str, Any]], dict[str, Any]]:
    """A `rewrite_mcap` change: step message `number` (1-based) with its record edited."""
    def change(topic: str, n: int, message: dict[str, Any]) -> dict[str, Any]:
        if topic == "/lanewarden/step" and n == number:
            record = json.loads(message["record"])
            edit(record)
            message["record"] = json.dumps(record)
        return message
    return change


def _older_step(text: str) -> str:
    """A recorded step as formats 1 and 2 wrote it (no frame fingerprint or refusal)."""
    record = json.loads(text)
    for key in ("frame_fingerprint", "frame_refused"):
        record["input"].pop(key, None)
    return json.dumps(record)


def as_format_1(run: Path, target: Path) -> Path:
    """The same recording in the run folder layout of format 1 (run.jsonl + frames/*.png +
    meta.json, config.yaml, summary.json), as lanewarden recorded before run.mcap (`run`: one
    recorded with the camera's gray frames, `CAMERA_GRAY`)."""
    assert json.loads((run / "meta.json").read_text())["image"] == CAMERA_GRAY
    target.mkdir(parents=True)
    (target / "frames").mkdir()
    lines = []
    with (run / "run.mcap").open("rb") as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _, channel, message, decoded in reader.iter_decoded_messages(
                log_time_order=False):
            if channel.topic == "/lanewarden/step":
                lines.append(_older_step(decoded.record))
            elif channel.topic == "/camera/image/compressed":
                image = cv2.imdecode(np.frombuffer(decoded.data, np.uint8), cv2.IMREAD_UNCHANGED)
                cv2.imwrite(str(target / "frames" / f"{message.sequence:06d}.png"), image)
    (target / "run.jsonl").write_text("\n".join(lines) + "\n")
    meta = json.loads((run / "meta.json").read_text())
    meta.update(format=1, frames="frames/%06d.png")
    (target / "meta.json").write_text(json.dumps(meta))
    for name in ("config.yaml", "summary.json", "calibration.yaml"):
        if (run / name).exists():
            shutil.copyfile(run / name, target / name)
    return target


def as_format_2(run: Path, target: Path) -> Path:
    """The same recording as format 2 wrote it (`run`: recorded with `CAMERA_GRAY`): run.mcap
    with the camera's gray frames, steps without frame fingerprints, a meta without `image`."""
    meta = json.loads((run / "meta.json").read_text())
    assert meta["image"] == CAMERA_GRAY
    del meta["image"]
    meta["format"] = 2
    target.mkdir(parents=True)
    for name in ("config.yaml", "summary.json", "calibration.yaml"):
        if (run / name).exists():
            shutil.copyfile(run / name, target / name)
    (target / "meta.json").write_text(json.dumps(meta))

    def older(topic: str, number: int, message: dict[str, Any]) -> dict[str, Any]:
        if topic == "/lanewarden/step":
            message["record"] = _older_step(message["record"])
        return message

    rewrite_mcap(run / "run.mcap", target / "run.mcap", older,
                 metadata={"lanewarden": {"format": "2", "meta": json.dumps(meta)}})
    return target


def forged_format_1(run: Path, target: Path, number: int,
                    edit: Callable[[dict[str, Any]], None]) -> Path:
    """`as_format_1(run, target)` with line `number` (1-based) of its run.jsonl edited."""
    old = as_format_1(run, target)
    lines = (old / "run.jsonl").read_text().splitlines()
    line = json.loads(lines[number - 1])
    edit(line)
    lines[number - 1] = json.dumps(line)
    (old / "run.jsonl").write_text("\n".join(lines) + "\n")
    return old
