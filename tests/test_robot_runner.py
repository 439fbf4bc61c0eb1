"""`lanewarden run` end to end: a rendered image sequence as the camera, the Kobuki stand-in on a
pseudo-terminal as the base. Checks the wiring, the safety order of start-up and shutdown, why a
run ended (summary, exit code, the stderr line of a safety stop) and what terminal signals do, not
timing: the runner is the one real-time part, so waits are on conditions with generous deadlines.
"""

from __future__ import annotations

import os
import signal
import subprocess
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

from lanewarden.cli import main
from lanewarden.config import LanewardenConfig, config_from_mapping
from lanewarden.perception.calibration import CameraCalibration, save_calibration
from lanewarden.runner import start_warnings
from lanewarden.scenarios.camera import CameraModel
from lanewarden.supervisor.watchdog import RECENT_IMAGES, mark_capture
from tests.actuation.kobuki_standin import STOP_PACKET, KobukiStandIn
from tests.actuation.processes import (
    DEADLINE_S,
    assert_stop_held_since,
    deadman_of,
    is_motion,
    process_state,
    start_lanewarden,
    stderr_lines,
    wait_for_more_packets,
    wait_for_stop_after,
)
from tests.operator.runs import steps
from tests.perception.synthetic import STRAIGHT, render

FPS = 30
#: Camera, base-feedback and heartbeat timeouts relaxed for a loaded test machine: these tests
#: are about why a run ends, and a late frame or a slow step must not be taken for the cause under
#: test. (The defaults are exercised in tests/actuation and measured in benchmarks/.)
RELAXED = """\
actuation:
  heartbeat_timeout_s: 0.5
  feedback_timeout_s: 0.6
supervisor:
  frame_late_s: 0.3
  frame_stale_s: 0.6
  frame_frozen_s: 0.6
  base_feedback_late_s: 0.3
  base_link_timeout_s: 0.6
  loop_overrun_s: 0.3
"""


#: A calibration with its ground pose (the simulator's default camera's, as `sim --camera-out`
#: writes it): nothing about the camera is assumed.
CALIBRATED = CameraModel().calibration()


def last_line(out: str) -> str:
    """The run's last stdout line (why it ended); the operator's status and summary come first."""
    return out.strip().splitlines()[-1]


@pytest.fixture(scope="module")
def scenes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[Path]]:
    """Frames of a straight taped lane and of bare floor, each with its own sensor noise (more of
    them than the watchdog remembers, so a clip cycling through them is never frozen). Rendered
    once: the renderer is slow."""
    folder = tmp_path_factory.mktemp("scenes")
    rng = np.random.default_rng(7)
    frames: dict[str, list[Path]] = {}
    for name, scene in (("lane", STRAIGHT), ("floor", STRAIGHT.__class__(tapes=()))):
        clean = render(scene, 640, 480).astype(np.int16)
        frames[name] = []
        for index in range(RECENT_IMAGES + 2):
            noisy = np.clip(clean + rng.normal(0.0, 2.0, clean.shape), 0, 255).astype(np.uint8)
            path = folder / f"{name}_{index}.png"
            cv2.imwrite(str(path), noisy)
            frames[name].append(path)
    return frames


def clip(folder: Path, scenes: dict[str, list[Path]], *parts: tuple[str, float]) -> str:
    """An image sequence (30 fps) of `parts`, e.g. ("lane", 2.0), ("floor", 1.0): the rendered
    frames, cycling through their noise, each also marked with its index (`mark_capture`), so
    that no image repeats one of the last few the watchdog remembers even where the loop, late
    on a loaded machine, skips frames."""
    folder.mkdir()
    index = 0
    loaded: dict[Path, np.ndarray] = {}
    for name, seconds in parts:
        for i in range(round(seconds * FPS)):
            path = scenes[name][i % len(scenes[name])]
            image = loaded.setdefault(path, cv2.imread(str(path)))
            cv2.imwrite(str(folder / f"frame_{index:04d}.png"), mark_capture(image.copy(), index),
                        [cv2.IMWRITE_PNG_COMPRESSION, 1])
            index += 1
    return str(folder / "frame_%04d.png")


@pytest.fixture
def relaxed_config(tmp_path: Path) -> str:
    path = tmp_path / "relaxed.yaml"
    path.write_text(RELAXED)
    return str(path)


def _run(camera: str, port: str, tmp_path: Path, config: str, *extra: str) -> list[str]:
    # (the frames are the simulator's default camera's: the camera --assume-camera assumes)
    return ["run", "--camera", camera, "--port", port, "--record", str(tmp_path / "run"),
            "--config", config, "--assume-camera", *extra]


def _safety_line(err: str) -> str:
    lines = stderr_lines(err)
    assert len(lines) == 1 and lines[0].startswith("lanewarden: safety stop: "), err
    return lines[0]


# ---- the wiring and the start-up order ----------------------------------------------------------
def test_run_engages_on_a_clean_lane_and_ends_with_stop(
    scenes: dict[str, list[Path]], tmp_path: Path, relaxed_config: str,
    capsys: pytest.CaptureFixture[str],
) -> None:
    camera = clip(tmp_path / "camera", scenes, ("lane", 4.0))
    with KobukiStandIn() as base:
        code = main(_run(camera, base.port, tmp_path, relaxed_config, "--duration", "1.0"))
        assert base.wait_for(lambda packets: any(p.packet == STOP_PACKET for p in packets), 5.0)
        controls = base.base_controls()
    out, err = capsys.readouterr()
    assert code == 0, err
    assert stderr_lines(err) == []
    assert controls, "the stand-in never received a base-control packet"
    assert controls[-1][1] == (0, 0), "the last command on the wire must be stop"
    records = steps(tmp_path / "run")
    assert records, "no per-frame record was written"
    assert records[-1]["state"] == "HALT"
    assert records[-1]["command"] == {"linear_m_s": 0.0, "angular_rad_s": 0.0}
    assert any(r["observation"] is not None for r in records), "perception never ran"
    moving = [r for r in records if r["command"]["linear_m_s"] > 0]
    assert moving and all(r["state"] != "HALT" for r in moving), "it never engaged on a clean lane"
    assert last_line(out).startswith("run ended: --duration 1 s reached; after ")
    assert "state before the final stop: FOLLOW;" in out
    # no --calibration: said at start-up, under the ground model's line, before anything moved
    lines = out.splitlines()
    warned = next(k for k, line in enumerate(lines) if line.startswith("warning: no --calibration"))
    assert lines[warned - 1].startswith("ground model: no ground calibration"), lines[warned - 1]


def test_run_warns_at_start_up_without_a_calibration_and_names_a_clips_own(
        tmp_path: Path) -> None:
    """A clip through a distorted lens run without its calibration drove to the clip's end at
    confidence 0.89 where with it the run halted at the tape's end (a new user's trial): `run`
    says so at start-up, and names the calibration `sim --camera-out` wrote beside the clip."""
    camera = tmp_path / "clip.mp4"
    camera.write_bytes(b"")
    (warning,) = start_warnings(str(camera), None, None, "supervised")
    assert warning.startswith("no --calibration: perception judges these frames as if from the "
                              "simulator's default camera"), warning
    assert "beside" not in warning
    beside = tmp_path / "clip.calibration.yaml"
    beside.write_text("not read\n")
    (warning,) = start_warnings(str(camera), None, None, "supervised")
    assert warning.endswith(f"; the clip's own calibration lies beside it: --calibration {beside}")
    assert start_warnings(str(camera), str(beside), CALIBRATED, "supervised") == []
    # a clip of frames (`sim --camera-out clip`), named as a folder or by a pattern
    (tmp_path / "frames").mkdir()
    frames_calibration = tmp_path / "frames.calibration.yaml"
    frames_calibration.write_text("not read\n")
    for named in ("frames", "frames/", "frames/*.png", "frames/frame_%06d.png"):
        (warning,) = start_warnings(str(tmp_path / named), None, None, "supervised")
        assert warning.endswith(f"--calibration {frames_calibration}"), (named, warning)
    assert start_warnings("0", None, None, "supervised")[0].endswith("calibrate ground)")


def _calibration_without_ground(path: Path) -> Path:
    """The simulator's default camera's intrinsics, as `lanewarden calibrate` writes them for
    640x480, with no ground pose (`calibrate ground` not run)."""
    k = np.array([[457.0, 0, 320], [0, 457.0, 240], [0, 0, 1]])
    save_calibration(CameraCalibration(k, np.zeros(5), (640, 480)), path)
    return path


@pytest.mark.parametrize("given", ["none", "no ground pose"])
def test_the_robot_does_not_drive_on_an_assumed_camera(
        given: str, scenes: dict[str, list[Path]], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """`--base kobuki` (the default) with no --calibration, or with one that has no ground pose,
    is refused before the base opens: tapes and seams would be measured in millimetres through
    the simulator's camera or mount. A new user's `lane-ends` clip, run so on the Kobuki
    stand-in, drove to the clip's end (858 non-zero packets) where with its calibration it
    halted at the tape's end. The port here does not exist: the refusal comes first."""
    camera = clip(tmp_path / "camera", scenes, ("lane", 1.0))
    flags = [] if given == "none" else [
        "--calibration", str(_calibration_without_ground(tmp_path / "intrinsics.yaml"))]
    code = main(["run", "--camera", camera, "--port", str(tmp_path / "no-port"), *flags,
                 "--duration", "1.0", "--record", str(tmp_path / "run")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2, err
    assert len(err) == 1, err
    if given == "none":
        assert err[0].startswith(
            "lanewarden: error: --base kobuki: no --calibration: perception judges these frames "
            "as if from the simulator's default camera (no lens distortion, h 0.400 m, pitch "
            "35.0°, 0.150 m ahead of the robot's centre)"), err[0]
        assert "expected --calibration FILE from `lanewarden calibrate`, then `lanewarden " \
               "calibrate ground`, or --assume-camera" in err[0], err[0]
    else:
        assert err[0].startswith(
            f"lanewarden: error: --base kobuki: --calibration {tmp_path / 'intrinsics.yaml'} "
            "has no ground pose (`lanewarden calibrate ground` was not run): perception assumes "
            "the simulator's mount (h 0.400 m, pitch 35.0°"), err[0]
        assert "expected its ground pose (`lanewarden calibrate ground --calibration" in err[0]
    assert not (tmp_path / "run").exists(), "refused before the recording opens"


def test_assume_camera_lets_the_robot_drive_and_the_bench_bases_only_warn(
        scenes: dict[str, list[Path]], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """With --assume-camera the Kobuki (the stand-in) drives as before, warned; `--base sim`
    and `--base none` are never refused, only warned, for a calibration without a ground pose
    too."""
    camera = clip(tmp_path / "camera", scenes, ("lane", 1.0))
    with KobukiStandIn() as base:
        code = main(["run", "--camera", camera, "--port", base.port, "--assume-camera",
                     "--duration", "0.5", "--record", str(tmp_path / "kobuki")])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "warning: no --calibration: perception judges these frames" in out
    intrinsics = _calibration_without_ground(tmp_path / "intrinsics.yaml")
    code = main(["run", "--camera", camera, "--base", "none", "--calibration", str(intrinsics),
                 "--duration", "0.5", "--record", str(tmp_path / "none")])
    out = capsys.readouterr().out
    assert code == 0, out
    assert (f"warning: --calibration {intrinsics} has no ground pose (`lanewarden calibrate "
            "ground` was not run): perception assumes the simulator's mount (h 0.400 m, pitch "
            "35.0°, 0.150 m ahead of the robot's centre); with another height or pitch it "
            "measures tapes and seams wrong and can see a lane where there is none (run "
            "lanewarden calibrate ground)") in out, out


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTSTP])
def test_a_stop_signal_ends_the_runs_wait_at_once(
        sig: signal.Signals, scenes: dict[str, list[Path]], tmp_path: Path,
        monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    """A signal at the start of a tick's wait (the tenth, while following the clip): the wait
    asks, and knows at once, instead of sleeping to the next frame. (SIGTSTP is asked for
    too; the real suspend is left out here: it would stop the test process, so it is replaced
    by a no-op and the run ends by --duration.)"""
    import lanewarden.runner as runner
    from tests.signal_probe import signalling_ticker

    seen: list[bool | None] = []
    monkeypatch.setattr(runner, "Ticker", signalling_ticker(sig, 10, seen))
    monkeypatch.setattr(runner, "suspend", lambda: None)
    camera = clip(tmp_path / "camera", scenes, ("lane", 2.0))
    code = main(["run", "--camera", camera, "--base", "none", "--duration", "1.0",
                 "--record", str(tmp_path / "run")])
    assert seen == [True]
    assert code == 0, capsys.readouterr().err


def test_assume_camera_says_when_it_changes_nothing() -> None:
    """On a bench base nothing is refused, and a calibration with its ground pose assumes
    nothing: the flag says so (it had been accepted without a word)."""
    from lanewarden.runner import assume_camera_note

    assert assume_camera_note("sim", None, None, True) == (
        "--assume-camera changes nothing with --base sim: only the robot (--base kobuki) is "
        "refused an assumed camera")
    assert assume_camera_note("kobuki", "camera.yaml", CALIBRATED, True) == (
        "--assume-camera changes nothing: --calibration camera.yaml has its lens and its ground "
        "pose, nothing is assumed")
    assert assume_camera_note("kobuki", None, None, True) is None  # it lets the robot drive
    assert assume_camera_note("kobuki", "camera.yaml", CALIBRATED, False) is None


def test_run_warns_of_a_lane_with_little_room_to_drift() -> None:
    """19 mm tapes 0.5 m apart (the README's example lane once) leave a Kobuki 45 mm either way
    before the departure rule (the defaults: 81 mm); a new user's sim of it halted on course in
    a 2 m-radius bend, with no word at start-up."""
    narrow = config_from_mapping(
        {"perception": {"tape": {"width_m": 0.019}, "lane": {"width_m": 0.5}}})
    (warning,) = start_warnings("0", "camera.yaml", CALIBRATED, "supervised", narrow)
    assert warning.startswith("perception.lane.width_m 0.5 leaves the robot 45 mm to drift "
                              "either way before the lane-departure rule halts it"), warning
    assert warning.endswith("the defaults leave 81 mm (a 0.6 m lane of 48 mm tape)"), warning
    assert start_warnings("0", "camera.yaml", CALIBRATED, "supervised", LanewardenConfig()) == []
    wider = config_from_mapping(
        {"perception": {"tape": {"width_m": 0.019}, "lane": {"width_m": 0.6}}})
    assert start_warnings("0", "camera.yaml", CALIBRATED, "supervised", wider) == []


def test_run_warns_that_the_lecture_controller_never_halts_on_lane_loss() -> None:
    (warning,) = start_warnings("0", "camera.yaml", CALIBRATED, "lecture")
    assert warning.startswith("--controller lecture: the lecture's baseline never halts on lane "
                              "loss"), warning
    assert start_warnings("0", "camera.yaml", CALIBRATED, "supervised") == []


def test_calibration_for_another_camera_refuses_before_the_base_is_touched(
    scenes: dict[str, list[Path]], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    camera = clip(tmp_path / "camera", scenes, ("lane", 1.0))
    calibration = tmp_path / "other-camera.yaml"
    k = np.array([[500.0, 0, 400], [0, 500.0, 300], [0, 0, 1]])
    save_calibration(CameraCalibration(k, np.zeros(5), (800, 600)), calibration)
    with KobukiStandIn() as base:
        code = main(["run", "--camera", camera, "--port", base.port,
                     "--calibration", str(calibration), "--duration", "1.0",
                     "--record", str(tmp_path / "run")])
        received = base.snapshot()
    err = capsys.readouterr().err
    assert code != 0
    assert "refusing to engage" in err and str(calibration) in err
    assert len(err.strip().splitlines()) == 1
    assert received == [], "nothing may reach the base when the calibration is refused"


def test_unopenable_camera_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "no-such-video.mp4"
    code = main(["run", "--camera", str(missing), "--port", str(tmp_path / "no-port"),
                 "--duration", "1.0"])
    err = capsys.readouterr().err
    assert code != 0
    assert str(missing) in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("broken", ["cut.jpg", "text.jpg"])
def test_one_photo_that_cannot_be_read_is_one_line(
        broken: str, scenes: dict[str, list[Path]], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """`run --camera PHOTO` reads the photo as `detect` does (a reviewer: OpenCV's video reader
    ran a cut JPEG as a 1-frame clip, exit 0, and said of a text file that the camera stopped
    delivering frames)."""
    photo = tmp_path / broken
    if broken == "cut.jpg":
        good = scenes["lane"][0]
        ok, data = cv2.imencode(".jpg", cv2.imread(str(good)))
        assert ok
        photo.write_bytes(data.tobytes()[:300])
    else:
        photo.write_text("not a picture\n")
    code = main(["run", "--camera", str(photo), "--base", "none", "--duration", "1.0",
                 "--record", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.splitlines() == [f"lanewarden: error: --camera '{photo}': not a readable image"]
    assert not (tmp_path / "run").exists(), "refused before the recording folder"


# ---- why a run ended: normal ends (0) and safety stops (3) --------------------------------------
def test_the_end_of_the_clip_is_a_normal_end(
    scenes: dict[str, list[Path]], tmp_path: Path, relaxed_config: str,
    capsys: pytest.CaptureFixture[str],
) -> None:
    camera = clip(tmp_path / "camera", scenes, ("lane", 1.5))
    with KobukiStandIn() as base:
        code = main(_run(camera, base.port, tmp_path, relaxed_config))
        assert base.wait_for(lambda pkts: pkts[-1].packet == STOP_PACKET, DEADLINE_S)
    out, err = capsys.readouterr()
    assert (code, stderr_lines(err)) == (0, [])
    assert last_line(out).startswith("run ended: end of the clip; after ")


def test_a_camera_cycling_through_two_old_images_never_moves_the_base(
    scenes: dict[str, list[Path]], tmp_path: Path, relaxed_config: str,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """The attacker's review: a clip alternating two lane images (A, B, A, B: a camera stuck on
    two old buffers) engaged and drove 1.84 m on `--base sim`, when only the previous image
    counted as a repeat. Every image after the second is one the camera showed before: no
    evidence to engage on, and the base gets no motion command at all."""
    camera = _ring_clip(tmp_path / "camera", scenes["lane"][:2], seconds=2.0)
    with KobukiStandIn() as base:
        code = main(_run(camera, base.port, tmp_path, relaxed_config))
        assert base.wait_for(lambda pkts: pkts[-1].packet == STOP_PACKET, DEADLINE_S)
        packets = base.snapshot()
    out, _ = capsys.readouterr()
    assert code == 0 and not any(map(is_motion, packets)), out
    assert "never engaged" in out


def test_a_camera_that_starts_cycling_old_images_while_following_halts_on_frozen(
    scenes: dict[str, list[Path]], tmp_path: Path, relaxed_config: str,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Following a lane, the camera starts re-delivering two old images: FRAME_FROZEN once they
    have run for frame_frozen_s, a safety stop (exit 3), the last packet a stop."""
    camera = clip(tmp_path / "camera", scenes, ("lane", 3.0))
    _ring_clip(tmp_path / "camera", scenes["lane"][:2], seconds=2.0, first=round(3.0 * FPS))
    _, line = _run_to_a_safety_stop(camera, tmp_path, relaxed_config, capsys)
    assert line.startswith("lanewarden: safety stop: FRAME_FROZEN")


def _run_to_a_safety_stop(camera: str, tmp_path: Path, config: str,
                          capsys: pytest.CaptureFixture[str]) -> tuple[str, str]:
    """`run` of `camera` on the stand-in, which must move the base and end in a safety stop
    (exit 3, the last packet a stop): its stdout and its one stderr line."""
    with KobukiStandIn() as base:
        code = main(_run(camera, base.port, tmp_path, config))
        assert base.wait_for(lambda pkts: pkts[-1].packet == STOP_PACKET, DEADLINE_S)
        moved = any(map(is_motion, base.snapshot()))
    out, err = capsys.readouterr()
    assert moved, "it never engaged on the lane part of the clip"
    assert code == 3
    return out, _safety_line(err)


def _ring_clip(folder: Path, images: list[Path], seconds: float, first: int = 0) -> str:
    """`seconds` of frames (30 fps) cycling through `images` (hard links), numbered from `first`
    in `folder` (made when missing): a camera stuck on old buffers."""
    folder.mkdir(exist_ok=True)
    for i in range(round(seconds * FPS)):
        os.link(images[i % len(images)], folder / f"frame_{first + i:04d}.png")
    return str(folder / "frame_%04d.png")


def test_lane_lost_is_a_safety_stop(
    scenes: dict[str, list[Path]], tmp_path: Path, relaxed_config: str,
    capsys: pytest.CaptureFixture[str],
) -> None:
    camera = clip(tmp_path / "camera", scenes, ("lane", 3.0), ("floor", 1.0))
    out, line = _run_to_a_safety_stop(camera, tmp_path, relaxed_config, capsys)
    assert line.startswith("lanewarden: safety stop: LANE_LOST: no usable lane")
    assert last_line(out).startswith("run ended by a safety stop: LANE_LOST: no usable lane")


def test_a_lost_base_link_is_a_safety_stop(
    scenes: dict[str, list[Path]], tmp_path: Path, relaxed_config: str,
    capsys: pytest.CaptureFixture[str],
) -> None:
    camera = clip(tmp_path / "camera", scenes, ("lane", 4.0))
    with KobukiStandIn(unplug_on_motion=True) as base:
        code = main(_run(camera, base.port, tmp_path, relaxed_config))
    out, err = capsys.readouterr()
    assert code == 3
    line = _safety_line(err)
    assert line.startswith(f"lanewarden: safety stop: BASE_LINK_LOST: {base.port}: serial link "
                           "lost")
    # the port was tried again for the stop; the device never came back, and the line says so
    # (it had said only "halted", while the firmware drives its last command)
    assert line.endswith("; could not write a stop to the port "
                         f"({base.port}: no such device: plug in and switch on the base, check "
                         "--port, or install the Kobuki udev rule (it creates /dev/kobuki and "
                         "sets the FTDI latency timer to 1 ms), tried for 2 s): the base may "
                         "still be driving its last command: switch it off"), line
    assert last_line(out).startswith("run ended by a safety stop: BASE_LINK_LOST: ")


def test_a_live_camera_that_stops_delivering_is_a_safety_stop(
    scenes: dict[str, list[Path]], tmp_path: Path, relaxed_config: str,
    capsys: pytest.CaptureFixture[str],
) -> None:
    # a URL is a live source (not paced): its frames come at once, then nothing, like a network
    # camera that drops out
    camera = "file://" + clip(tmp_path / "camera", scenes, ("lane", 0.2))
    with KobukiStandIn() as base:
        code = main(_run(camera, base.port, tmp_path, relaxed_config))
        assert base.wait_for(lambda pkts: pkts[-1].packet == STOP_PACKET, DEADLINE_S)
    out, err = capsys.readouterr()
    assert code == 3
    line = _safety_line(err)
    assert line == (f"lanewarden: safety stop: CAMERA_LOST: --camera {camera}: the camera "
                    "stopped delivering frames")
    assert last_line(out).startswith("run ended by a safety stop: CAMERA_LOST: ")


@pytest.mark.parametrize(("how", "said"), [
    (signal.SIGKILL, "the dead-man process was killed (SIGKILL); a stop was written"),
    (signal.SIGSTOP, "the dead-man process stopped answering (no report for 0.5 s): killed it; "
                     "a stop was written"),
])
def test_a_deadman_killed_or_frozen_under_run_is_a_safety_stop(
    scenes: dict[str, list[Path]], tmp_path: Path, relaxed_config: str,
    capsys: pytest.CaptureFixture[str], how: signal.Signals, said: str,
) -> None:
    camera = clip(tmp_path / "camera", scenes, ("lane", 6.0))
    signalled: list[float] = []
    with KobukiStandIn() as base:
        def strike() -> None:
            deadman = deadman_of(os.getpid(), base)
            if base.wait_for(lambda pkts: any(map(is_motion, pkts)), 3 * DEADLINE_S):
                signalled.append(time.monotonic())
                os.kill(deadman, how)

        threading.Thread(target=strike, daemon=True).start()
        code = main(_run(camera, base.port, tmp_path, relaxed_config))
        assert signalled, "it never moved"
        assert_stop_held_since(base, signalled[0])
    out, err = capsys.readouterr()
    assert code == 3
    line = _safety_line(err)
    assert line.startswith(f"lanewarden: safety stop: BASE_LINK_LOST: {base.port}: ")
    assert said in line


# ---- terminal signals to the whole process group ------------------------------------------------
@pytest.fixture
def running(scenes: dict[str, list[Path]], tmp_path: Path, relaxed_config: str
            ) -> Iterator[tuple[subprocess.Popen[str], KobukiStandIn]]:
    """`lanewarden run` in its own process group, engaged and moving on a long clip."""
    camera = clip(tmp_path / "camera", scenes, ("lane", 20.0))
    with KobukiStandIn() as base:
        run = start_lanewarden(*_run(camera, base.port, tmp_path, relaxed_config))
        try:
            assert base.wait_for(lambda pkts: any(map(is_motion, pkts)), 6 * DEADLINE_S), \
                "it never moved"
            yield run, base
        finally:
            run.kill()
            run.wait()


def test_ctrl_z_stops_run_first_then_it_stays_halted_after_sigcont(
    running: tuple[subprocess.Popen[str], KobukiStandIn],
) -> None:
    run, base = running
    signalled_at = time.monotonic()
    os.killpg(run.pid, signal.SIGTSTP)
    wait_for_stop_after(base, signalled_at)
    # re-checked at every packet: the dead-man keeps writing stop while run is suspended
    assert base.wait_for(lambda _: process_state(run.pid) == "T", DEADLINE_S)
    wait_for_more_packets(base, 40)  # 0.8 s suspended: longer than the heartbeat timeout
    os.killpg(run.pid, signal.SIGCONT)
    assert base.wait_for(lambda _: process_state(run.pid) not in ("T", ""), DEADLINE_S)
    wait_for_more_packets(base, 25)  # it runs again, halted: still nothing but stop
    os.killpg(run.pid, signal.SIGTERM)
    out, err = run.communicate(timeout=3 * DEADLINE_S)
    assert (run.returncode, stderr_lines(err)) == (0, [])
    assert last_line(out).startswith("run ended: operator stop (SIGTERM); after ")
    assert "state before the final stop: HALT (OPERATOR_STOP: operator stop)" in out
    assert_stop_held_since(base, signalled_at)


def test_ctrl_backslash_ends_run_like_sigterm(
    running: tuple[subprocess.Popen[str], KobukiStandIn],
) -> None:
    run, base = running
    signalled_at = time.monotonic()
    os.killpg(run.pid, signal.SIGQUIT)
    out, err = run.communicate(timeout=3 * DEADLINE_S)
    assert (run.returncode, stderr_lines(err)) == (0, [])
    assert last_line(out).startswith("run ended: operator stop (SIGQUIT); after ")
    assert_stop_held_since(base, signalled_at)


def test_a_frozen_run_trips_the_deadman_and_ends_as_a_safety_stop(
    running: tuple[subprocess.Popen[str], KobukiStandIn],
) -> None:
    run, base = running
    frozen_at = time.monotonic()
    os.kill(run.pid, signal.SIGSTOP)  # not a terminal signal: nothing in run sees it coming
    wait_for_stop_after(base, frozen_at)  # the dead-man's heartbeat timeout
    os.kill(run.pid, signal.SIGCONT)
    out, err = run.communicate(timeout=3 * DEADLINE_S)
    assert run.returncode == 3
    line = _safety_line(err)
    assert line.startswith("lanewarden: safety stop: DEADMAN_TRIPPED: the dead-man stopped the "
                           "base (no heartbeat for ")
    assert last_line(out).startswith("run ended by a safety stop: DEADMAN_TRIPPED: ")
    assert_stop_held_since(base, frozen_at)
