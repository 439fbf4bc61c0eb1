"""`lanewarden run` end to end with no hardware (a rendered clip, `--base sim` and `--base none`)
and over the pty Kobuki stand-in (the real protocol, the real dead-man process).

These run in real time (the runner is the one real-time part): each lasts a few seconds of clip.
Ordering ("stop on the wire, nothing non-zero after") is asserted from the stand-in's packet log;
latencies are measured in benchmarks/, never asserted here."""

from __future__ import annotations

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
    start_run,
    steps,
)
from tests.perception import synthetic as syn


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
        clip: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "run"
    code = main(["run", "--camera", str(clip), "--base", "sim", "--record", str(record)])
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
        clip: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "run"
    code = main(["run", "--camera", str(clip), "--base", "none", "--record", str(record)])
    captured = capsys.readouterr()
    assert code == 3, captured.err
    assert "(base none: nothing sent)" in captured.out, "plain status lines name what is sent"
    assert "FOLLOW" in captured.out
    records = steps(record)
    assert_followed_then_halted_at_the_end(records)
    assert json.loads((record / "summary.json").read_text())["distance_m"] == 0.0


# ---- over the Kobuki stand-in -------------------------------------------------------------------
def test_kobuki_steady_stream_then_stop_after_halt(
        clip: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "run"
    with KobukiStandIn() as kobuki:
        code = main(["run", "--camera", str(clip), "--port", kobuki.port, "--record",
                     str(record)])
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
        process = start_run(["--camera", str(long_lane), "--port", kobuki.port, "--record",
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
        process = start_run(["--camera", str(long_lane), "--port", kobuki.port, "--record",
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
    assert re.search(rf"  halted: by the end of the run \(operator stop \({sig.name}\)\) while "
                     r"(FOLLOW|TURN_LEFT|TURN_RIGHT|DEGRADED)\n", out), out
    assert controls[-1][1] == (0, 0), "stop is the last command on the wire"
    assert steps(record)[-1]["state"] == "HALT"


def test_base_vanishing_mid_run_is_a_clean_one_line_safety_stop(
        long_lane: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    record = tmp_path / "run"
    with KobukiStandIn(unplug_on_motion=True) as kobuki:
        code = main(["run", "--camera", str(long_lane), "--port", kobuki.port, "--record",
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
                 "--record", str(tmp_path / "run")])
    assert code == 1
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert (summary["steps"], summary["exit_code"]) == (0, None)


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
