"""Recording a run and replaying it: the recording taps change nothing, a recorded run replays
step for step (states, events, commands) from its run.mcap (and from a format-1 folder), a
changed step is found, a run recorded with another config replays with its own, and the writer
never blocks the loop (drops, counts and says so instead).

The recorded runs here are made on a fake clock (tests/operator/recordings.py; the runner's
real-time run is in test_run_end_to_end.py): the same ControlLoop, a rendered clip, a SimBase."""

from __future__ import annotations

import json
import threading
from pathlib import Path
from typing import Any, cast

import cv2
import numpy as np
import pytest

from lanewarden.actuation.sim_base import SimBase
from lanewarden.assembly import build_stack
from lanewarden.cli import main
from lanewarden.config import LanewardenConfig, config_from_mapping
from lanewarden.errors import UsageError
from lanewarden.perception.calibration import save_calibration
from lanewarden.perception.detector import LaneDetector
from lanewarden.recording import InputTap, RunRecorder, create_run_folder, default_run_folder
from lanewarden.replay import (
    Divergence,
    ReplaySource,
    open_replay_source,
    replay_config,
    replay_steps,
)
from lanewarden.replay_outputs import replay_metrics
from lanewarden.ros_bag import McapFile, decode
from lanewarden.run_mcap import CAMERA_GRAY, CAMERA_JPEG, PERCEPTION_INPUT
from lanewarden.run_record import StepInput
from lanewarden.scenarios.camera import CameraModel
from lanewarden.supervisor.loop import ControlLoop, Frame, StepRecord
from lanewarden.supervisor.watchdog import frame_fingerprint
from lanewarden.survey_run import CheckedFrames, camera_steps
from tests.operator.clips import lane_end_frames
from tests.operator.recordings import (
    DT,
    ClipFrames,
    as_format_1,
    as_format_2,
    change_step,
    record_run,
    rewrite_mcap,
)


@pytest.fixture(scope="module")
def clip() -> list[np.ndarray]:
    return lane_end_frames(start_m=2.2, end_m=3.4, speed_m_s=0.6)


def replayed(source_path: Path, config_path: str | None = None
             ) -> tuple[list[StepRecord], list[Divergence]]:
    """The replay's core (no video, plot or report): every step and every divergence."""
    source = open_replay_source(str(source_path), 30.0)
    config = replay_config(source, config_path)
    records, divergences = [], []
    for step in replay_steps(source, config, source.calibration, "supervised"):
        records.append(step.record)
        if step.divergence is not None:
            divergences.append(step.divergence)
    return records, divergences


def recorded_frames(run: Path) -> dict[int, np.ndarray]:
    path = run / "run.mcap"
    return {m.sequence: cv2.imdecode(np.frombuffer(decode(m, "").data, np.uint8),
                                     cv2.IMREAD_UNCHANGED)
            for m in McapFile(path).messages(lambda t: t.name.endswith("/compressed"))}


def replayed_inputs(path: Path) -> list[dict[str, object]]:
    """The `input` of every recorded step in run.mcap."""
    return [json.loads(decode(m, "").record)["input"]
            for m in McapFile(path).messages(lambda t: t.name == "/lanewarden/step")]


def test_the_taps_change_nothing(clip: list[np.ndarray]) -> None:
    """The same run with and without the recording taps gives the same steps."""
    config = LanewardenConfig()
    t0 = 50.0
    plain = build_stack(config).connect(ClipFrames(clip, t0), SimBase())
    tap = InputTap()
    stack = build_stack(config)
    tapped = ControlLoop(tap.frames(ClipFrames(clip, t0)), stack.detector,
                         tap.gate(stack.gate), tap.base(SimBase()),
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
    assert sorted(p.name for p in folder.iterdir()) == [
        "config.yaml", "meta.json", "run.mcap", "summary.json"]
    frames = recorded_frames(folder)
    assert sorted(frames) == list(range(len(clip)))
    assert np.array_equal(frames[7], LaneDetector(LanewardenConfig().perception).prepare(
        clip[7])), "lossless: the recorded frame is what perception consumed, bit for bit"

    code = main(["replay", str(folder), "--check", "--no-video", "--out", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert code == 0, out
    assert f"reproduced: all {len(records)} steps match the recording" in out
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert metrics["reproduced"] is True and metrics["divergent_steps"] == 0
    assert (metrics["exact_input"], metrics["incomplete"]) == (True, [])
    # the operator's stop is no safety stop: nothing "before the halt", as run's summary (a
    # replay of space, r, Ctrl-C had printed it)
    assert metrics["first_halt_reason"].startswith("OPERATOR_STOP")
    assert metrics["before_halt"] is None and "before the halt" not in out
    replayed_lines = [json.loads(line) for line in
                      (tmp_path / "out" / "run.jsonl").read_text().splitlines()]
    assert [r["state"] for r in replayed_lines] == states
    assert (tmp_path / "out" / "report.html").exists()
    assert (tmp_path / "out" / "plot.png").exists()
    # run.mcap on its own is the whole recording (its meta, config and summary inside)
    code = main(["replay", str(folder / "run.mcap"), "--check", "--no-video", "--out",
                 str(tmp_path / "out2")])
    assert code == 0, capsys.readouterr().out


def test_a_replay_describes_the_halt_that_ended_the_run(clip: list[np.ndarray], tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    """Stopped from the page, resumed, then halted for good: the replay's 'before the halt',
    halt time and plot are of the halt that ended the run, as `run`'s summary is (an
    instructor's review: they had described the operator's stop, and 'before the halt' was
    missing)."""
    folder = tmp_path / "run"
    records = record_run(folder, clip, LanewardenConfig(), stop_at_step=20, resume_at_step=23)
    states = [r.state for r in records]
    stopped = states.index("HALT", states.index("FOLLOW"))  # the operator's stop
    again = states.index("FOLLOW", stopped)  # engaged again after the resume
    last = max(i for i in range(again, len(states)) if states[i - 1] != "HALT"
               and states[i] == "HALT")
    assert "OPERATOR_STOP" in records[stopped].events and states[-1] == "HALT"
    assert all(state == "HALT" for state in states[last:])
    code = main(["replay", str(folder), "--check", "--no-video", "--out", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert code == 0, out
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    first_time = records[0].time_s
    assert metrics["first_halt_reason"].startswith("OPERATOR_STOP")
    assert metrics["first_halt_time_s"] == round(records[stopped].time_s - first_time, 4)
    assert metrics["halt_time_s"] == round(records[last].time_s - first_time, 4)
    assert metrics["halt_reason"] == records[last].halt_reason != records[stopped].halt_reason
    assert metrics["before_halt"] is not None and "  before the halt: " in out
    assert metrics["before_halt"]["frames"] >= 1


def test_a_format_1_folder_still_replays(clip: list[np.ndarray], tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    """Folders recorded before run.mcap (run.jsonl + frames/) replay and check the same."""
    run = tmp_path / "run"
    records = record_run(run, clip[:24], LanewardenConfig(), stop_at_step=12,
                         image_kind=CAMERA_GRAY)
    old = as_format_1(run, tmp_path / "old")
    assert main(["replay", str(old), "--check", "--no-video", "--out", str(tmp_path / "o")]) == 0
    assert f"reproduced: all {len(records)} steps" in capsys.readouterr().out


def test_a_format_2_recording_still_replays(clip: list[np.ndarray], tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    """run.mcap as format 2 wrote it (the camera's gray frames, no fingerprints) replays and
    checks the same."""
    run = tmp_path / "run"
    records = record_run(run, clip[:24], LanewardenConfig(), stop_at_step=12,
                         image_kind=CAMERA_GRAY)
    old = as_format_2(run, tmp_path / "old")
    assert "frame_fingerprint" not in json.dumps(replayed_inputs(old / "run.mcap"))
    assert main(["replay", str(old), "--check", "--no-video", "--out", str(tmp_path / "o")]) == 0
    assert f"reproduced: all {len(records)} steps" in capsys.readouterr().out


def test_a_changed_step_is_the_first_divergence(clip: list[np.ndarray], tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "run"
    records = record_run(folder, clip, LanewardenConfig())
    moving = next(k for k, r in enumerate(records) if r.command.linear_m_s > 0)
    changed = tmp_path / "changed.mcap"

    def nudge(record: dict[str, object]) -> None:
        command = cast(dict[str, list[float]], record["input"])["command"]
        command[1] += 1e-12  # the smallest change still counts

    rewrite_mcap(folder / "run.mcap", changed, change_step(moving + 3 + 1, nudge))
    code = main(["replay", str(changed), "--check", "--no-video", "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    assert code == 2
    # dated from the run's first step, not by the robot's monotonic clock (T0 + ...)
    assert f"DIVERGES at step {moving + 3} (t = {(moving + 3) * DT:.3f} s)" in captured.out
    assert "command was" in captured.out
    assert "diverges from the recording" in captured.err


def test_a_run_from_an_older_config_replays_with_its_own(
        clip: list[np.ndarray], tmp_path: Path) -> None:
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
    record_run(folder, clip[:20], LanewardenConfig(), image_kind=CAMERA_JPEG)
    frames = recorded_frames(folder)
    assert len(frames) == 20 and frames[0].shape == clip[0].shape, "lossy: colour JPEG"
    records, divergences = replayed(folder)
    source = open_replay_source(str(folder), 30.0)
    assert replay_metrics(source, records, divergences, 0.0)["exact_input"] is False
    lossless = tmp_path / "lossless"
    record_run(lossless, clip[:20], LanewardenConfig())
    without = tmp_path / "without-4.mcap"
    rewrite_mcap(lossless / "run.mcap", without,  # as if the writer had dropped frame 4
                 lambda topic, n, m: None if topic.endswith("/compressed") and n == 5 else m)
    source = open_replay_source(str(without), 30.0)
    metrics = replay_metrics(source, records, divergences, 0.0)
    assert (metrics["exact_input"], metrics["frames_missing"]) == (False, 1)


def test_a_full_queue_drops_frames_instead_of_waiting(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """The writer stalls: the recorder keeps returning at once, records every step, counts the
    frames it dropped and says so."""
    import lanewarden.recording as recording

    release, writing = threading.Event(), threading.Event()
    real_encode = recording.gray_png

    def stalled_encode(image: np.ndarray, png_filter: int) -> bytes:
        writing.set()
        release.wait(10.0)
        return real_encode(image, png_filter)

    monkeypatch.setattr(recording, "gray_png", stalled_encode)
    monkeypatch.setattr(recording, "FRAME_QUEUE_FRAMES", 4)
    folder = create_run_folder(tmp_path / "run")
    recorder = RunRecorder(folder, image_kind=CAMERA_GRAY)  # 8x8 frames: too small to prepare
    image = np.zeros((8, 8, 3), np.uint8)
    record = StepRecord(None, 0.0, None, None, None, "HALT", (), recording.VelocityCommand(),
                        None)

    recorder.record(record, StepInput(t=0.0), Frame(image, 0, 0.0))
    assert writing.wait(10.0)
    for i in range(1, 20):
        recorder.record(record, StepInput(t=float(i)), Frame(image, i, float(i)))
    assert recorder.summary.frames_dropped == list(range(4, 20))
    release.set()
    summary = recorder.close()
    # one in the writer's hands, 3 more waiting, the other 16 dropped; every step recorded
    assert summary.frames_written == 4
    assert summary.frames_dropped == list(range(4, 20))
    assert not summary.complete
    assert json.loads((folder / "summary.json").read_text())["frames_dropped"] == 16
    assert summary.steps_written == 20


def test_run_folders_are_never_overwritten(tmp_path: Path) -> None:
    import datetime as dt

    when = dt.datetime(2026, 11, 5, 14, 3, 12, tzinfo=dt.UTC)
    first = default_run_folder(tmp_path, when)
    assert first == tmp_path / "2026-11-05T14-03-12Z"
    create_run_folder(first)
    (first / "run.mcap").touch()
    assert default_run_folder(tmp_path, when) == tmp_path / "2026-11-05T14-03-12Z-2"
    with pytest.raises(UsageError, match="never overwritten"):
        create_run_folder(first)


def test_a_run_folder_that_is_not_a_folder_is_said_as_such(tmp_path: Path) -> None:
    """A FIFO or a device was 'already exists and is not empty', a link to a missing place
    'cannot create the folder (File exists)' (exit 1)."""
    import os

    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for path in (fifo, Path("/dev/null")):
        with pytest.raises(UsageError) as refused:
            create_run_folder(path)
        assert str(refused.value) == (f"--record {path}: already exists and is not a folder; "
                                      "choose a new folder")
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "missing" / "run")
    with pytest.raises(UsageError) as refused:
        create_run_folder(link)
    assert str(refused.value) == (f"--record {link}: a link to '{tmp_path}/missing/run', which "
                                  "does not exist; choose a new folder")


# ---- perception's prepared input: what the recording keeps by default ------------------------
def _without_fingerprints(topic: str, number: int, message: dict[str, Any]) -> dict[str, Any]:
    if topic == "/lanewarden/step":
        record = json.loads(message["record"])
        record["input"].pop("frame_fingerprint", None)
        message["record"] = json.dumps(record)
    return message


def test_the_recorded_fingerprints_decide_repeated_images_as_on_the_run(
        clip: list[np.ndarray], tmp_path: Path) -> None:
    """Two camera frames that differ in one byte (the supervisor's fingerprint tells them apart:
    the second is new evidence) but blur to the same prepared image: the replay decides as the
    run did because it compares the recorded fingerprints; without them it would take the
    second frame for a repeated image and engage a step later."""
    detector = LaneDetector(LanewardenConfig().perception)
    changed = clip[1].copy()
    changed[100, 100, 0] ^= 1  # a pixel the fingerprint samples (every 4th row and column)
    assert frame_fingerprint(changed) != frame_fingerprint(clip[1])
    assert np.array_equal(detector.prepare(changed), detector.prepare(clip[1]))
    frames = [clip[0], clip[1], changed, *clip[2:20]]
    folder = tmp_path / "run"
    records = record_run(folder, frames, LanewardenConfig())
    first_follow = next(k for k, r in enumerate(records) if r.state == "FOLLOW")
    inputs = replayed_inputs(folder / "run.mcap")
    assert inputs[2]["frame_fingerprint"] == frame_fingerprint(changed).hex()
    replay, divergences = replayed(folder)
    assert divergences == []
    assert [r.as_json() for r in replay] == [r.as_json() for r in records]
    stripped = tmp_path / "stripped.mcap"
    rewrite_mcap(folder / "run.mcap", stripped, _without_fingerprints)
    _, divergences = replayed(stripped)
    assert (divergences[0].step, divergences[0].what, divergences[0].recorded,
            divergences[0].replayed) == (first_follow, "state", "FOLLOW", "HALT")


def test_a_frame_perception_refused_replays_as_refused(clip: list[np.ndarray], tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    """A frame the detector cannot take (here 16-bit) has no prepared image: the recording notes
    perception's refusal, and the replay raises the same (the same PERCEPTION_ERROR, exact)."""
    frames = [*clip[:6], clip[6].astype(np.uint16), *clip[7:12]]
    folder = tmp_path / "run"
    records = record_run(folder, frames, LanewardenConfig())
    assert "PERCEPTION_ERROR" in records[6].events
    assert sorted(recorded_frames(folder)) == [0, 1, 2, 3, 4, 5, 7, 8, 9, 10, 11]
    assert replayed_inputs(folder / "run.mcap")[6]["frame_refused"] == [
        "PerceptionError", "frame: expected dtype uint8, got uint16"]
    assert json.loads((folder / "summary.json").read_text())["frames_refused"] == 1
    code = main(["replay", str(folder), "--check", "--no-video", "--out", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert code == 0, out
    assert f"reproduced: all {len(records)} steps" in out


def test_another_blur_is_refused_for_prepared_frames_not_for_camera_frames(
        clip: list[np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blur = tmp_path / "blur7.yaml"
    blur.write_text("perception:\n  blur:\n    kernel_px: 7\n")
    prepared, camera = tmp_path / "prepared", tmp_path / "camera"
    record_run(prepared, clip[:12], LanewardenConfig())
    record_run(camera, clip[:12], LanewardenConfig(), image_kind=CAMERA_GRAY)
    code = main(["replay", str(prepared), "--config", str(blur), "--no-video", "--out",
                 str(tmp_path / "out1")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert err == (f"lanewarden: error: --config '{blur}': perception.blur {{'kernel_px': 7, "
                   "'sigma_px': 0.0}, but prepared was recorded as perception's input, its "
                   "frames blurred on the run with {'kernel_px': 5, 'sigma_px': 0.0}; expected "
                   "the recorded blur, to replay it as recorded (record with --record-gray to "
                   "try others)\n")
    assert not (tmp_path / "out1").exists(), "refused before any output"
    assert main(["replay", str(camera), "--config", str(blur), "--no-video", "--out",
                 str(tmp_path / "out2")]) == 0


def _yellowed(frames: list[np.ndarray]) -> list[np.ndarray]:
    """The frames with half their blue taken out: colours the yellow boost reads apart."""
    out = []
    for frame in frames:
        tinted = frame.copy()
        tinted[:, :, 0] //= 2
        out.append(tinted)
    return out


def test_a_run_with_the_yellow_boost_recorded_gray_replays_exactly(
        clip: list[np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`--record-gray` keeps perception's gray, the boost's included: the replay reproduces every
    step. (It kept BGR2GRAY, and the replay of a boosted run diverged at its third step.)"""
    boosted = config_from_mapping({"perception": {"gray": {"yellow_boost": 0.8}}})
    folder = tmp_path / "gray"
    records = record_run(folder, _yellowed(clip[:20]), boosted, image_kind=CAMERA_GRAY)
    code = main(["replay", str(folder), "--check", "--no-video", "--out", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert code == 0, out
    assert f"reproduced: all {len(records)} steps" in out


@pytest.mark.parametrize(("image_kind", "kept"), [(PERCEPTION_INPUT, "perception's input"),
                                                  (CAMERA_GRAY, "the camera's gray")])
def test_another_yellow_boost_is_refused_for_gray_frames_not_for_colour_frames(
        clip: list[np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str],
        image_kind: str, kept: str) -> None:
    """Frames recorded gray were made gray with the run's `perception.gray`: another one cannot
    be applied to them, and replaying or surveying them with it would show the run's gray under
    the other's name (it did, silently). Colour (JPEG) frames take any."""
    boost = tmp_path / "boost.yaml"
    boost.write_text("perception:\n  gray: {yellow_boost: 0.8}\n")
    gray, colour = tmp_path / "gray", tmp_path / "colour"
    frames = _yellowed(clip[:12])
    record_run(gray, frames, LanewardenConfig(), image_kind=image_kind)
    record_run(colour, frames, LanewardenConfig(), image_kind=CAMERA_JPEG)
    why = (f"--config '{boost}': perception.gray {{'yellow_boost': 0.8}}, but gray was recorded "
           f"as {kept}, its colour frames made gray on the run with {{'yellow_boost': 0.0}}; "
           "expected the recorded perception.gray")
    hint = "(record with --record-lossy, colour JPEG, to try others)"
    labels = tmp_path / "labels.csv"
    labels.write_text("frames,expect\n0-11,lane\n")
    for command, extra in (("replay", ["--no-video"]), ("survey", ["--labels", str(labels)])):
        out = tmp_path / f"out-{command}"
        code = main([command, str(gray), "--config", str(boost), *extra, "--out", str(out)])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1, err
        assert err == f"lanewarden: error: {why}, to {command} it as recorded {hint}\n"
        assert not out.exists(), "refused before any output"
    assert main(["replay", str(colour), "--config", str(boost), "--no-video", "--out",
                 str(tmp_path / "out-colour")]) == 0


def test_survey_refuses_what_replay_refuses_for_prepared_frames(
        clip: list[np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A run folder holds perception's prepared input: surveyed with another blur or another
    calibration, its figures would be the recording camera's, not the one named (they were,
    with the named file in survey.json): refused in one line, before any output."""
    blur = tmp_path / "blur7.yaml"
    blur.write_text("perception:\n  blur:\n    kernel_px: 7\n")
    labels = tmp_path / "labels.csv"
    labels.write_text("frames,expect\n0-11,lane\n")
    lens = tmp_path / "lens.yaml"
    save_calibration(CameraModel(width_px=640, height_px=480).calibration(), lens)
    run = tmp_path / "prepared"
    record_run(run, clip[:12], LanewardenConfig())
    # the error names the flag and the file given, the recording and what was expected (it had
    # named neither flag nor file)
    for flag, file, why in (
            ("--config", blur, f"--config '{blur}': perception.blur {{'kernel_px': 7, "
                               "'sigma_px': 0.0}, but prepared was recorded as perception's "
                               "input, its frames blurred on the run with {'kernel_px': 5, "
                               "'sigma_px': 0.0}; expected the recorded blur"),
            ("--calibration", lens, f"--calibration '{lens}' (for 640x480 images): prepared was "
                                    "recorded as perception's input without a calibration (its "
                                    "frames were not undistorted); expected no --calibration")):
        out = tmp_path / f"out{flag}"
        code = main(["survey", str(run), "--labels", str(labels), flag, str(file), "--out",
                     str(out)])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1, err
        assert err == (f"lanewarden: error: {why}, to survey it as recorded (record with "
                       "--record-gray to try others)\n")
        assert not out.exists(), "refused before any output"


def test_survey_of_a_run_names_the_recordings_calibration_in_its_ground_model_line(
        clip: list[np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A run recorded with a calibration is surveyed through it: the first line says whose
    ground model that is, as `replay` says it. It had read "ground model: ground calibration:
    h 0.400 m, ..." (no source named) in the survey and "... from the recording's calibration"
    in the replay of the same run."""
    lens = tmp_path / "lens.yaml"
    calibration = CameraModel(width_px=320, height_px=240).calibration()  # the clip's size
    save_calibration(calibration, lens)
    run = tmp_path / "calibrated"
    record_run(run, clip[:12], LanewardenConfig(), calibration=lens,
               loaded_calibration=calibration)
    labels = tmp_path / "labels.csv"
    labels.write_text("frames,expect\n0-5,lane\n6-11,none\n")
    code = main(["survey", str(run), "--labels", str(labels), "--out", str(tmp_path / "out")])
    captured = capsys.readouterr()
    first = captured.out.splitlines()[0]
    assert code in (0, 3), captured.err
    assert first.startswith("ground model: ground calibration from the recording's calibration: "
                            "h 0.400 m, pitch 35.0°, "), first


def test_a_run_labelled_by_file_is_told_to_label_its_frames_by_number(
        clip: list[np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The README's photo labels (file,expect,note) given for a recorded run, whose frames are
    inside run.mcap: one line saying the run wants frame numbers. It had read "0-11: no such
    file (paths are relative to ...)", as if the run folder were a folder of photos."""
    run = tmp_path / "run"
    record_run(run, clip[:12], LanewardenConfig())
    labels = tmp_path / "labels.csv"
    labels.write_text("file,expect,note\n0-5,lane,\n6-11,none,\n")
    code = main(["survey", str(run), "--labels", str(labels), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert err == (f"lanewarden: error: FOLDER '{run}': a recorded run, but {labels} labels "
                   "image files (file,expect); expected its frames by number: "
                   "frames,expect[,note] (e.g. 0-120,lane)\n")
    assert not (tmp_path / "out").exists()


def test_record_gray_and_record_lossy_are_one_choice(tmp_path: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", "--camera", str(tmp_path / "clip.mp4"), "--base", "none",
                 "--record-gray", "--record-lossy"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "--record-gray and --record-lossy: choose one" in err


def test_prepared_frames_reach_the_detector_prepared_through_any_frame_store(
        clip: list[np.ndarray], tmp_path: Path) -> None:
    """`survey` replays a run folder's frames through its own FrameStore wrapper
    (survey_run.CheckedFrames) and steps: the recorded images themselves say they are prepared
    (PreparedImage), so they are not blurred twice, and every observation is the one the
    camera's gray frames give, to the last bit."""
    observations = []
    for name, image_kind in (("prepared", PERCEPTION_INPUT), ("camera", CAMERA_GRAY)):
        record_run(tmp_path / name, clip[:21], LanewardenConfig(), image_kind=image_kind)
        source = open_replay_source(str(tmp_path / name), 30.0)
        span = ReplaySource(kind="run", name=name, steps=camera_steps(
            (k, k / 30.0) for k in range(21)), frames=CheckedFrames(source.frames, 10**7, None))
        observations.append([step.record.observation for step in replay_steps(
            span, LanewardenConfig(), None, "supervised")])
    assert all(o is not None for o in observations[0]) and len(observations[0]) == 21
    assert observations[0] == observations[1]
