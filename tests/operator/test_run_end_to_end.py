"""`lanewarden run` end to end with no hardware (a rendered clip, `--base sim` and `--base none`)
and over the pty Kobuki stand-in (the real protocol, the real dead-man process).

These run in real time (the runner is the one real-time part): each lasts a few seconds of clip.
Ordering ("stop on the wire, nothing non-zero after") is asserted from the stand-in's packet log;
latencies are measured in benchmarks/, never asserted here."""

from __future__ import annotations

import html
import json
import os
import re
import signal
from pathlib import Path

import cv2
import pytest

from lanewarden.cli import main
from tests.actuation.kobuki_standin import KobukiStandIn
from tests.operator.runs import (
    lane_then_end_video,
    long_lane_images,
    moving,
    run_beside,
    start_run,
    steps,
    wait_until,
)
from tests.perception import synthetic as syn
from tests.test_robot_runner import RELAXED


@pytest.fixture(scope="module")
def clip(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return lane_then_end_video(tmp_path_factory.mktemp("clip"))


@pytest.fixture(scope="module")
def long_lane(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return long_lane_images(tmp_path_factory.mktemp("long"))


def _first(records: list[dict], predicate) -> int:  # type: ignore[no-untyped-def,type-arg]
    return next(k for k, r in enumerate(records) if predicate(r))


def assert_followed_then_halted_at_the_end(records: list[dict]) -> int:  # type: ignore[type-arg]
    """Engaged, followed, halted (lane lost) with zero commands from then on; returns the step
    of the halt."""
    states = [r["state"] for r in records]
    assert "FOLLOW" in states, states
    engaged = _first(records, lambda r: r["state"] != "HALT")
    halt = engaged + _first(records[engaged:], lambda r: r["state"] == "HALT")
    assert records[halt]["halt_reason"].startswith(("LANE_LOST", "DEGRADED_BUDGET_EXHAUSTED"))
    assert all(r["state"] == "HALT" for r in records[halt:])
    assert all(r["command"] == {"linear_m_s": 0.0, "angular_rad_s": 0.0}
               for r in records[halt:]), "nothing non-zero after HALT"
    return halt


def test_clip_on_the_simulated_base_then_replay_reproduces_it(
        clip: Path, tmp_path: Path, relaxed: list[str],
        capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "run"  # relaxed: a starved CPU's late frame must not halt it early
    code = main(["run", "--camera", str(clip), "--base", "sim", "--record", str(record),
                 *relaxed])
    captured = capsys.readouterr()
    # the lane ended under the robot: a safety stop that still held when the clip ended
    assert code == 3, captured.err
    assert captured.err.startswith("lanewarden: safety stop: ")
    assert len(captured.err.strip().splitlines()) == 1
    assert "run ended by a safety stop: " in captured.out.strip().splitlines()[-1]
    assert "halted: LANE_LOST" in captured.out or "halted: DEGRADED" in captured.out
    records = steps(record)
    assert_followed_then_halted_at_the_end(records)
    assert "OPERATOR_STOP" in records[-1]["events"], "the runner's own last stop is recorded"
    summary = json.loads((record / "summary.json").read_text())
    assert summary["complete"] is True and summary["exit_code"] == 3
    # the terminal's count is the steps before the closing stop, and says so (a new user saw
    # 528 there and 529 in summary.json and in replay)
    assert (f"and {summary['ended_by']['steps']} steps before the closing stop;"
            in captured.out.strip().splitlines()[-1])
    assert summary["steps"] == summary["ended_by"]["steps"] + 1 == len(records)
    assert summary["distance_m"] > 0.05, "the simulated base moved"
    meta = json.loads((record / "meta.json").read_text())
    assert meta["base"] == "sim" and meta["camera"] == str(clip)
    assert meta["software"]["packages"]["numpy"]

    code = main(["replay", str(record), "--check", "--out", str(tmp_path / "replay")])
    out = capsys.readouterr().out
    assert code == 0, out
    assert f"reproduced: all {len(records)} steps match the recording" in out
    for name in ("video.mp4", "plot.png", "metrics.json", "run.jsonl"):
        assert (tmp_path / "replay" / name).stat().st_size > 0
    assert (tmp_path / "replay" / "report.html").exists()


def test_clip_with_no_base_reports_what_would_be_sent(
        clip: Path, tmp_path: Path, relaxed: list[str],
        capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "run"
    code = main(["run", "--camera", str(clip), "--base", "none", "--record", str(record),
                 *relaxed])
    captured = capsys.readouterr()
    assert code == 3, captured.err
    assert "(base none: nothing sent)" in captured.out, "plain status lines name what is sent"
    assert "FOLLOW" in captured.out
    records = steps(record)
    assert_followed_then_halted_at_the_end(records)
    assert json.loads((record / "summary.json").read_text())["distance_m"] == 0.0


# ---- over the Kobuki stand-in -------------------------------------------------------------------
def test_kobuki_steady_stream_then_stop_after_halt(
        clip: Path, tmp_path: Path, relaxed: list[str],
        capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "run"  # relaxed: a starved CPU's 0.27 s stall had tripped the dead-man
    with KobukiStandIn() as kobuki:
        code = main(["run", "--camera", str(clip), "--port", kobuki.port,
                     "--assume-camera", "--record",
                     str(record), *relaxed])
        controls = kobuki.base_controls()
    assert code == 3, capsys.readouterr().err
    records = steps(record)
    halt = assert_followed_then_halted_at_the_end(records)
    moving_steps = sum(r["command"]["linear_m_s"] > 0 for r in records)
    wire = [control for _, control in controls]
    first_motion = _first(wire, lambda c: c != (0, 0))  # type: ignore[arg-type]
    stop = first_motion + _first(wire[first_motion:], lambda c: c == (0, 0))  # type: ignore
    assert sum(c != (0, 0) for c in wire) >= moving_steps, "a steady stream while moving"
    assert all(c == (0, 0) for c in wire[stop:]), "nothing non-zero on the wire after the stop"
    assert wire[-1] == (0, 0)
    assert records[halt - 1]["command"]["linear_m_s"] > 0


def test_sigstop_of_the_runner_stops_the_base_through_the_deadman(
        long_lane: Path, tmp_path: Path) -> None:
    record = tmp_path / "run"
    with KobukiStandIn() as kobuki:
        process = start_run(["--camera", str(long_lane), "--port", kobuki.port,
                             "--assume-camera", "--record",
                             str(record)], stdout=open(os.devnull, "w"))
        try:
            assert kobuki.wait_for(moving, 30.0), "it never moved"
            frozen_at = len(kobuki.snapshot())
            os.kill(process.pid, signal.SIGSTOP)
            assert kobuki.wait_for(lambda ps: any(p.base_control == (0, 0)
                                                  for p in ps[frozen_at:]), 10.0)
            after = kobuki.snapshot()[frozen_at:]
            stop = _first(after, lambda p: p.base_control == (0, 0))  # type: ignore[arg-type]
            held = kobuki.wait_for(lambda ps: len(ps) >= frozen_at + stop + 10, 10.0)
            assert held, "the dead-man keeps sending stop"
            assert all(p.base_control in (None, (0, 0))
                       for p in kobuki.snapshot()[frozen_at + stop:]), "and only stop"
        finally:
            os.kill(process.pid, signal.SIGCONT)
            process.terminate()
            process.wait(20)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_sigint_and_sigterm_end_with_stop_and_the_summary(
        sig: signal.Signals, long_lane: Path, tmp_path: Path) -> None:
    record = tmp_path / "run"
    with KobukiStandIn() as kobuki:
        process = start_run(["--camera", str(long_lane), "--port", kobuki.port,
                             "--assume-camera", "--record",
                             str(record)], stdout=-1, stderr=-1)
        try:
            assert kobuki.wait_for(moving, 30.0), "it never moved"
            process.send_signal(sig)
            out, err = process.communicate(timeout=20)
        finally:
            if process.poll() is None:
                process.kill()
        controls = kobuki.base_controls()
    assert process.returncode == 0, err
    assert f"run ended: operator stop ({sig.name})" in out.strip().splitlines()[-1]
    assert "distance (odometry)" in out and "states visited: HALT, FOLLOW" in out
    # the runner's own closing stop is named as such, not as a bare OPERATOR_STOP
    assert re.search(rf"  stopped by the end of the run \(operator stop \({sig.name}\)\) "
                     r"while (FOLLOW|TURN_LEFT|TURN_RIGHT|DEGRADED)\n", out), out
    assert controls[-1][1] == (0, 0), "stop is the last command on the wire"
    assert steps(record)[-1]["state"] == "HALT"


def test_base_vanishing_mid_run_is_a_clean_one_line_safety_stop(
        long_lane: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "run"
    with KobukiStandIn(unplug_on_motion=True) as kobuki:
        code = main(["run", "--camera", str(long_lane), "--port", kobuki.port,
                     "--assume-camera", "--record",
                     str(record)])
    captured = capsys.readouterr()
    assert code == 3
    errors = captured.err.strip().splitlines()
    assert len(errors) == 1 and errors[0].startswith(
        "lanewarden: safety stop: BASE_LINK_LOST"), captured.err
    assert "Traceback" not in captured.err
    assert "run ended by a safety stop: BASE_LINK_LOST" in captured.out
    records = steps(record)
    assert any("BASE_LINK_LOST" in r["events"] for r in records)
    assert records[-1]["state"] == "HALT"
    assert json.loads((record / "summary.json").read_text())["exit_code"] == 3


def test_a_busy_view_port_is_one_line_before_anything_is_written(
        clip: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        code = main(["run", "--camera", str(clip), "--base", "sim", "--view", str(port),
                     "--record", str(tmp_path / "run")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and f"--view 127.0.0.1:{port}: cannot listen there" in err[0]
    assert not (tmp_path / "run").exists()


def test_a_missing_robot_leaves_a_closed_recording(
        clip: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", "--camera", str(clip), "--port", str(tmp_path / "no-such-port"),
                 "--assume-camera",
                 "--record", str(tmp_path / "run")])
    assert code == 1
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert (summary["steps"], summary["exit_code"]) == (0, None)
    # the recording says which error (it had said "an error"), and so does its replay
    assert summary["end_reason"].startswith(
        f"an error: {tmp_path / 'no-such-port'}: no such device"), summary["end_reason"]
    assert main(["replay", str(tmp_path / "run"), "--out", str(tmp_path / "o")]) == 2
    assert capsys.readouterr().err.strip().startswith(
        f"lanewarden: error: {tmp_path / 'run' / 'run.mcap'}: no recorded steps: the run ended "
        f"before its first step (an error: {tmp_path / 'no-such-port'}")


def test_a_camera_perception_cannot_use_is_refused_before_anything_moves(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """160x120 frames and no calibration: the default camera at that size cannot tell tape from
    seam at a 0.87 m look-ahead set in the config. `run` says so at start-up (exit 2, one line
    naming the key and the look-ahead that would work), never sits in HALT frame after frame.
    (With no look-ahead set, auto picks 0.47 m and says so.)"""
    folder = tmp_path / "small"
    folder.mkdir()
    for index in range(3):
        cv2.imwrite(str(folder / f"f_{index}.png"), syn.frame(syn.STRAIGHT, 160, 120))
    config = tmp_path / "far.yaml"
    config.write_text("perception:\n  edges: {look_ahead_m: 0.87}\n")
    code = main(["run", "--camera", str(folder / "f_%d.png"), "--base", "sim",
                 "--record", str(tmp_path / "run"), "--config", str(config)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1
    assert err[0].startswith("lanewarden: error: perception.edges.look_ahead_m = 0.87: at "
                             "160x120 one pixel covers 8.5 mm")
    assert "expected a look-ahead of 0.47 m or less" in err[0]


# ---- one end reason, everywhere -----------------------------------------------------------------
ENGAGED_STATES = ("FOLLOW", "TURN_LEFT", "TURN_RIGHT", "DEGRADED")


@pytest.fixture
def relaxed(tmp_path: Path) -> list[str]:
    """Watchdog limits relaxed for a loaded test machine (as in test_robot_runner.py): these
    runs are about why a run ended, and a late frame must not be taken for the cause."""
    path = tmp_path / "relaxed.yaml"
    path.write_text(RELAXED, encoding="utf-8")
    return ["--config", str(path)]


def assert_one_end_reason(out: str, err: str, record: Path, replay_out: Path) -> str:
    """The run's end reason is the same in every place that says it: the last status line, the
    summary (its first line and its last), stderr (a safety stop only), summary.json and the
    replay of the run folder (metrics.json, report.html). Returns it."""
    summary = json.loads((record / "summary.json").read_text())
    text = summary["end_reason"]
    end = summary["end"]
    assert end["text"] == text
    status_lines = [line for line in out.splitlines() if line.startswith("[")]
    assert status_lines[-1].split("] ", 1)[1].startswith(f"ENDED: {text}  "), status_lines[-1]
    stopped = (f"  halted: {end['halt_reason']}" if end["state"] == "HALT"
               else f"  halted: {end['safety_stop']} (while {end['state']})"
               if end["safety_stop"] is not None
               else f"  stopped by the end of the run ({end['ended_by']}) while {end['state']}")
    assert stopped + "\n" in out, out
    last = out.strip().splitlines()[-1]
    if end["safety_stop"] is not None:
        assert summary["exit_code"] == 3
        assert last.startswith(f"run ended by a {text}; after "), last
        assert err.strip().splitlines() == [f"lanewarden: {text}"]
        assert end["halt_reason"] in (None, end["safety_stop"])
    else:
        assert summary["exit_code"] == 0
        assert last.startswith(f"run ended: {text}; after "), last
        assert err.strip() == ""
    state = end["state"] if end["halt_reason"] is None else f"HALT ({end['halt_reason']})"
    assert f"; state before the final stop: {state}; log: " in last

    assert main(["replay", str(record), "--no-video", "--out", str(replay_out)]) == 0
    metrics = json.loads((replay_out / "metrics.json").read_text())
    assert summary["frames_dropped"] == 0, "a recording this small keeps every frame"
    assert metrics["reproduced"]
    assert (metrics["end_reason"], metrics["final_state"], metrics["halt_reason"]) == (
        text, end["state"], end["halt_reason"])
    # halted when the run ended halted: neither a clip's own end nor the runner's closing stop
    # is a halt (replay had said halted: true, reason null, for a clip that ended in FOLLOW)
    assert metrics["halted"] is (end["state"] == "HALT"), metrics
    assert f"the run ended: {html.escape(text)}." in (replay_out / "report.html").read_text()
    return str(text)


def test_a_clip_whose_lane_ends_ends_by_the_halt_that_held(
        clip: Path, tmp_path: Path, relaxed: list[str],
        capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "run"
    code = main(["run", "--camera", str(clip), "--base", "sim", "--record", str(record),
                 *relaxed])
    out, err = capsys.readouterr()
    text = assert_one_end_reason(out, err, record, tmp_path / "replay")
    assert code == 3
    assert text.startswith(("safety stop: LANE_LOST: ", "safety stop: DEGRADED_BUDGET")), text
    assert "CAMERA_ERROR" not in text and "OPERATOR_STOP" not in text


def test_a_clip_that_ends_while_following_ends_by_the_clip(
        tmp_path: Path, relaxed: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    camera = long_lane_images(tmp_path, seconds=3.0)
    record = tmp_path / "run"
    code = main(["run", "--camera", str(camera), "--base", "sim", "--record", str(record),
                 *relaxed])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert assert_one_end_reason(out, err, record, tmp_path / "replay") == "end of the clip"
    end = json.loads((record / "summary.json").read_text())["end"]
    assert end["state"] in ENGAGED_STATES, "the clip's end is the run's end, not a halt"
    assert "halted:" not in out


def test_ctrl_c_ends_the_run_as_the_operators_stop(
        long_lane: Path, tmp_path: Path, relaxed: list[str],
        capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "run"

    def operator() -> None:
        if wait_until(lambda: any(r["state"] in ENGAGED_STATES for r in steps(record))):
            os.kill(os.getpid(), signal.SIGINT)

    code = run_beside(operator, ["--camera", str(long_lane), "--base", "sim", "--record",
                                 str(record), *relaxed])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert assert_one_end_reason(out, err, record, tmp_path / "replay") == \
        "operator stop (SIGINT)"
    assert json.loads((record / "summary.json").read_text())["end"]["state"] in ENGAGED_STATES


def test_a_bumper_that_held_when_the_clip_ended_is_the_reason(
        tmp_path: Path, relaxed: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    camera = long_lane_images(tmp_path, seconds=4.0)
    record = tmp_path / "run"
    with KobukiStandIn() as kobuki:
        def operator() -> None:
            if kobuki.wait_for(moving, 30.0):
                kobuki.set_sensors(bumper=1)

        code = run_beside(operator, ["--camera", str(camera), "--port", kobuki.port,
                                     "--assume-camera",
                                     "--record", str(record), *relaxed])
    out, err = capsys.readouterr()
    assert code == 3, err
    text = assert_one_end_reason(out, err, record, tmp_path / "replay")
    # Two layers see the bumper: the gate (BUMPER, from the feedback's bits) and the dead-man,
    # which latches on the packet itself and says so (DEADMAN_LATCHED, naming the bumper); which
    # one the control process hears first depends on the link, but the reason names the bumper.
    assert (text.startswith("safety stop: BUMPER: bumper pressed")
            or (text.startswith("safety stop: DEADMAN_LATCHED:")
                and "bumper pressed" in text)), text


def test_a_frame_of_an_image_folder_that_fails_is_a_lost_camera_not_the_clips_end(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A later image over the pixel limit ended the run as 'end of the clip', exit 0, the
    reason only in summary.json."""
    from tests.operator.clips import lane_end_frames
    from tests.test_hostile_inputs import big_png

    folder = tmp_path / "shots"
    folder.mkdir()
    for i, frame in enumerate(lane_end_frames(start_m=1.0, end_m=3.5, speed_m_s=0.6)[:30]):
        cv2.imwrite(str(folder / f"f_{i:03d}.png"), frame)
    (folder / "f_020.png").write_bytes(big_png(20000, 20000))
    code = main(["run", "--camera", str(folder), "--base", "sim", "--record",
                 str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 3, err
    assert err.splitlines()[-1] == (
        f"lanewarden: safety stop: CAMERA_LOST: --camera {folder}: {folder / 'f_020.png'}: image "
        "has 400000000 pixels, more than perception.max_image_pixels (10000000)")
