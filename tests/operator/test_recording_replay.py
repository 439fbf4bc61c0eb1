"""Recording a run and replaying it: the recording taps change nothing, a recorded run replays
step for step (states, events, commands), a changed step is found, a run recorded with another
config replays with its own, and the writer never blocks the loop (drops and counts instead).

The recorded runs here are made on a fake clock (the runner's real-time run is in
test_run_end_to_end.py): the same ControlLoop, a rendered clip, a SimBase."""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import cast

import numpy as np
import pytest

from lanewarden.actuation.sim_base import SimBase
from lanewarden.assembly import build_stack
from lanewarden.camera_source import CameraLost
from lanewarden.cli import main
from lanewarden.config import LanewardenConfig, config_from_mapping
from lanewarden.errors import UsageError
from lanewarden.recording import (
    InputTap,
    RunRecorder,
    create_run_folder,
    default_run_folder,
)
from lanewarden.replay import Divergence, open_replay_source, replay_config, replay_steps
from lanewarden.replay_outputs import replay_metrics
from lanewarden.supervisor.gate import SafetyGate
from lanewarden.supervisor.loop import ControlLoop, Frame, StepRecord
from tests.operator.clips import lane_end_frames

DT = 1.0 / 30.0


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


@pytest.fixture(scope="module")
def clip() -> list[np.ndarray]:
    return lane_end_frames(start_m=2.2, end_m=3.4, speed_m_s=0.6)


def record_run(folder: Path, frames: list[np.ndarray], config: LanewardenConfig,
               *, stop_at_step: int | None = None, lossy: bool = False) -> list[StepRecord]:
    """A run on a fake clock, recorded as `lanewarden run` records it."""
    create_run_folder(folder)
    recorder = RunRecorder(folder, lossy=lossy)
    recorder.write_header({"camera": "clip", "controller": "supervised"},
                          config.model_dump(mode="json"), None)
    tap = InputTap()
    t0 = 1000.0 + 1.0 / 3.0  # not a round number: times must survive the trip exactly
    loop_ref: list[ControlLoop] = []

    def on_step(record: StepRecord) -> None:
        step_input, new_frame = tap.take(record.time_s)
        recorder.record(record, step_input, new_frame)

    base = SimBase()
    stack = build_stack(config)  # what `run` builds: detector, supervised controller, gate
    loop = ControlLoop(tap.frames(ClipFrames(frames, t0)), stack.detector,
                       cast(SafetyGate, tap.controller(stack.gate)), tap.base(base),
                       record=on_step)
    loop_ref.append(loop)
    records = []
    for k in range(len(frames) + 3):
        now = t0 + k * DT + 0.003
        if k == 0:
            loop.start(now)
        if stop_at_step is not None and k == stop_at_step:
            loop.operator_stop(now)
        records.append(loop.step(now))
    summary = recorder.close({"end_reason": "end of the clip", "exit_code": 0})
    assert summary.complete, summary
    return records


def replayed(folder: Path, config_path: str | None = None) -> tuple[list[StepRecord],
                                                                     list[Divergence]]:
    """The replay's core (no video, plot or report): every step and every divergence."""
    source = open_replay_source(str(folder), 30.0)
    config = replay_config(source, config_path)
    records, divergences = [], []
    for step in replay_steps(source, config, source.calibration, "supervised"):
        records.append(step.record)
        if step.divergence is not None:
            divergences.append(step.divergence)
    return records, divergences


def test_the_taps_change_nothing(clip: list[np.ndarray]) -> None:
    """The same run with and without the recording taps gives the same steps."""
    config = LanewardenConfig()
    t0 = 50.0
    plain = build_stack(config).connect(ClipFrames(clip, t0), SimBase())
    tap = InputTap()
    stack = build_stack(config)
    tapped = ControlLoop(tap.frames(ClipFrames(clip, t0)), stack.detector,
                         cast(SafetyGate, tap.controller(stack.gate)), tap.base(SimBase()),
                         record=lambda r: tap.take(r.time_s) and None)
    plain.start(t0)
    tapped.start(t0)
    for k in range(len(clip) + 2):
        a, b = plain.step(t0 + k * DT), tapped.step(t0 + k * DT)
        assert a.as_json() == b.as_json()


def test_a_recorded_run_replays_exactly(clip: list[np.ndarray], tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "run"
    records = record_run(folder, clip, LanewardenConfig(), stop_at_step=25)
    states = [r.state for r in records]
    assert "FOLLOW" in states and states[-1] == "HALT", states
    assert "OPERATOR_STOP" in records[25].events and "CAMERA_ERROR" in records[-1].events
    lines = (folder / "run.jsonl").read_text().splitlines()
    assert len(lines) == len(records)
    assert len(list((folder / "frames").glob("*.png"))) == len(clip)
    assert np.array_equal(
        __import__("cv2").imread(str(folder / "frames" / "000007.png")), clip[7]), \
        "lossless: the recorded frame is the frame perception saw"

    code = main(["replay", str(folder), "--check", "--no-video", "--out", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert code == 0, out
    assert f"reproduced: all {len(records)} steps match the recording" in out
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert metrics["reproduced"] is True and metrics["divergent_steps"] == 0
    assert metrics["exact_input"] is True
    replayed = [json.loads(line) for line in
                (tmp_path / "out" / "run.jsonl").read_text().splitlines()]
    assert [r["state"] for r in replayed] == states
    assert (tmp_path / "out" / "report.html").exists()
    assert (tmp_path / "out" / "plot.png").exists()


def test_a_changed_step_is_the_first_divergence(clip: list[np.ndarray], tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "run"
    records = record_run(folder, clip, LanewardenConfig())
    moving = next(k for k, r in enumerate(records) if r.command.linear_m_s > 0)
    lines = (folder / "run.jsonl").read_text().splitlines()
    line = json.loads(lines[moving + 3])
    line["input"]["command"][1] += 1e-12  # the smallest change still counts
    lines[moving + 3] = json.dumps(line)
    (folder / "run.jsonl").write_text("\n".join(lines) + "\n")
    code = main(["replay", str(folder), "--check", "--no-video", "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    assert code == 2
    assert f"DIVERGES at step {moving + 3} " in captured.out
    assert "command was" in captured.out
    assert "diverges from the recording" in captured.err


def test_a_run_from_an_older_config_replays_with_its_own(
        clip: list[np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    older = config_from_mapping({"supervisor": {"engage_confident_frames": 3,
                                                "follow_speed_m_s": 0.12}})
    folder = tmp_path / "run"
    records = record_run(folder, clip, older)
    first_follow = next(k for k, r in enumerate(records) if r.state == "FOLLOW")
    replay, divergences = replayed(folder)
    assert divergences == []
    assert [r.as_json() for r in replay] == [r.as_json() for r in records]
    defaults = tmp_path / "defaults.yaml"
    defaults.write_text("{}\n")
    _, divergences = replayed(folder, str(defaults))
    assert divergences[0].step == first_follow
    assert (divergences[0].what, divergences[0].recorded) == ("state", "FOLLOW")


def test_a_lossy_or_incomplete_recording_is_not_exact(clip: list[np.ndarray],
                                                      tmp_path: Path) -> None:
    folder = tmp_path / "run"
    record_run(folder, clip[:20], LanewardenConfig(), lossy=True)
    assert len(list((folder / "frames").glob("*.jpg"))) == 20
    records, divergences = replayed(folder)
    source = open_replay_source(str(folder), 30.0)
    assert replay_metrics(source, records, divergences, 0.0)["exact_input"] is False
    lossless = tmp_path / "lossless"
    record_run(lossless, clip[:20], LanewardenConfig())
    (lossless / "frames" / "000004.png").unlink()  # as if the writer had dropped it
    source = open_replay_source(str(lossless), 30.0)
    metrics = replay_metrics(source, records, divergences, 0.0)
    assert (metrics["exact_input"], metrics["frames_missing"]) == (False, 1)


def test_a_full_queue_drops_frames_instead_of_waiting(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """The disk stalls: the recorder keeps returning at once and counts what it dropped."""
    import lanewarden.recording as recording

    release, writing = threading.Event(), threading.Event()
    real_imwrite = recording.cv2.imwrite

    def stalled_imwrite(*args: object, **kwargs: object) -> bool:
        writing.set()
        release.wait(10.0)
        return bool(real_imwrite(*args, **kwargs))  # type: ignore[arg-type]

    monkeypatch.setattr(recording.cv2, "imwrite", stalled_imwrite)
    monkeypatch.setattr(recording, "FRAME_QUEUE_FRAMES", 4)
    folder = create_run_folder(tmp_path / "run")
    recorder = RunRecorder(folder)
    image = np.zeros((8, 8, 3), np.uint8)
    record = StepRecord(None, 0.0, None, None, None, "HALT", (), recording.VelocityCommand(),
                        None)
    from lanewarden.run_record import StepInput

    recorder.record(record, StepInput(t=0.0), Frame(image, 0, 0.0))
    assert writing.wait(10.0)
    for i in range(1, 20):
        recorder.record(record, StepInput(t=float(i)), Frame(image, i, float(i)))
    release.set()
    summary = recorder.close()
    # one in the writer's hands, 4 queued, the other 15 dropped
    assert summary.frames_written == 5
    assert summary.frames_dropped == list(range(5, 20))
    assert not summary.complete
    assert json.loads((folder / "summary.json").read_text())["frames_dropped"] == 15
    assert len((folder / "run.jsonl").read_text().splitlines()) == 20


def test_run_folders_are_never_overwritten(tmp_path: Path) -> None:
    import datetime as dt

    when = dt.datetime(2026, 11, 5, 14, 3, 12, tzinfo=dt.UTC)
    first = default_run_folder(tmp_path, when)
    assert first == tmp_path / "2026-11-05T14-03-12Z"
    create_run_folder(first)
    assert default_run_folder(tmp_path, when) == tmp_path / "2026-11-05T14-03-12Z-2"
    with pytest.raises(UsageError, match="never overwritten"):
        create_run_folder(first)
