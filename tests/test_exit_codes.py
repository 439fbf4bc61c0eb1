"""The one exit-code rule (README, "Exit codes"), one representative case per code per command
family: 0 the command did its job, 1 a runtime failure outside the user's input, 2 bad input or a
failed gate/check, 130 Ctrl-C. Every failure is one line on stderr. `run`'s safety stop (3) is
checked with the runner's stop causes (tests/test_robot_runner.py); `base drive`'s Ctrl-C (130)
in tests/actuation/test_kobuki_end_to_end.py.

The expected codes are written out here, not read from `lanewarden.errors`: a change of the rule
must change this table.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from lanewarden.cli import main
from lanewarden.perception.calibration import CameraCalibration, save_calibration
from tests.actuation.kobuki_standin import KobukiStandIn
from tests.conftest import PROJECT_ROOT
from tests.perception import synthetic as syn
from tests.processes import sigint_as_from_a_terminal

GOOD_K = [[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]]
NAN_K = [[float("nan"), 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]]
ZERO_FOCAL_K = [[0.0, 0.0, 320.0], [0.0, 0.0, 240.0], [0.0, 0.0, 1.0]]

TINY_SCENARIO = """\
name: tiny
lane:
  segments:
    - {straight_m: 1}
run: {max_time_s: 0.2}
config:
  simulation: {texture_mm_per_px: 10, width_px: 160, height_px: 120, world_margin_m: 1}
  perception: {edges: {look_ahead_m: 0.45}}  # what 160x120 resolves tape from seam at
"""

LONG_SCENARIO = """\
name: long
lane:
  segments:
    - {straight_m: 8}
run: {max_time_s: 600}
"""


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    folder = tmp_path_factory.mktemp("exit-codes")
    cv2.imwrite(str(folder / "lane.png"), syn.frame(syn.STRAIGHT))
    (folder / "notes.png").write_text("not an image\n")
    (folder / "fake.mp4").write_text("hello\n")  # a file, but no video
    for name, k in (("good", GOOD_K), ("nan", NAN_K), ("zero-focal", ZERO_FOCAL_K)):
        save_calibration(CameraCalibration(np.array(k), np.zeros(5), (640, 480)),
                         folder / f"{name}.yaml")
    # an output that cannot be written: a folder where the output file should go
    (folder / "blocked").mkdir()
    (folder / "blocked" / "lane_detect.png").mkdir()
    (folder / "blocked" / "lane_undistorted.png").mkdir()
    (folder / "a-file").write_text("")
    (folder / "tiny.yaml").write_text(TINY_SCENARIO)
    (folder / "long.yaml").write_text(LONG_SCENARIO)
    (folder / "sequence").mkdir()
    for index in range(3):
        cv2.imwrite(str(folder / "sequence" / f"f_{index}.png"), syn.frame(syn.STRAIGHT))
    names = ("lane.png", "notes.png", "fake.mp4", "good.yaml", "nan.yaml", "blocked", "a-file",
             "tiny.yaml", "long.yaml", "sequence")
    return {name.split(".")[0]: str(folder / name) for name in names} | {"folder": str(folder)}


#: (family, code, argv with {file} placeholders, text the one error line must contain)
CASES = [
    ("config", 0, ["config", "show"], ""),
    ("config", 2, ["config", "show", "--config", "{folder}/missing.yaml"],
     "Invalid value for '--config': Path '{folder}/missing.yaml' does not exist; expected a "
     "config file"),
    ("detect", 0, ["detect", "{lane}"], ""),
    ("detect", 1, ["detect", "{lane}", "--out", "{blocked}"], "cannot write image"),
    ("detect", 2, ["detect", "{lane}", "{notes}"], "not a readable image"),
    ("detect", 2, ["detect", "{lane}", "--calibration", "{folder}/missing.yaml"],
     "Invalid value for '--calibration': Path '{folder}/missing.yaml' does not exist; expected "
     "a calibration file"),
    ("undistort", 0, ["undistort", "{lane}", "--calibration", "{good}", "--out",
                      "{folder}/undistorted"], ""),
    ("undistort", 1, ["undistort", "{lane}", "--calibration", "{good}", "--out",
                      "{blocked}"], "cannot write image"),
    ("undistort", 2, ["undistort", "{notes}", "--calibration", "{good}", "--out",
                      "{folder}/undistorted"], "not a readable image"),
    ("calibrate", 1, ["calibrate", "capture", "--camera", "97", "--pattern", "9x6", "--out",
                      "{folder}/shots"], "cannot open it as a camera"),
    # a file OpenCV cannot read is bad input, said as replay says it, not a missing camera
    ("calibrate", 2, ["calibrate", "capture", "--camera", "{fake}", "--pattern", "9x6", "--out",
                      "{folder}/shots"], "--camera '{fake}': not a video OpenCV can read;"),
    ("calibrate", 2, ["calibrate", "--images", "{folder}/none-*.png", "--pattern", "9x6",
                      "--square", "0.025", "--out", "{folder}/cam.yaml"], "no files match"),
    ("base", 1, ["base", "info", "--port", "{folder}/no-such-port"], "no-such-port"),
    ("base", 2, ["base", "drive", "--linear", "5", "--duration", "1"], "'--linear'"),
    ("sim", 0, ["sim", "--scenario", "{tiny}", "--no-video", "--quiet", "--out",
                "{folder}/sim"], ""),
    ("sim", 1, ["sim", "--scenario", "{tiny}", "--no-video", "--quiet", "--out",
                "{a-file}/sim"], "cannot create the folder"),
    ("sim", 2, ["sim", "--scenario", "no-such-scenario"], "unknown scenario"),
    ("sim", 2, ["sim", "--scenario", "{tiny}", "--no-video", "--quiet", "--check", "--out",
                "{folder}/sim-check"], "states no expected outcome"),
    ("run", 1, ["run", "--camera", "97", "--port", "{folder}/no-port", "--duration", "1"],
     "cannot open it as a camera"),
    ("run", 1, ["run", "--camera", "/dev/null", "--port", "{folder}/no-port", "--duration", "1"],
     "cannot open it as a camera or video (is it plugged in"),
    # a camera device that is not there is unplugged (exit 1), not bad input (it said "no such
    # file", exit 2)
    ("run", 1, ["run", "--camera", "/dev/video-not-here", "--port", "{folder}/no-port",
                "--duration", "1"], "--camera '/dev/video-not-here': no such device (is the"),
    ("run", 2, ["run", "--camera", "{fake}", "--calibration", "{good}", "--port",
                "{folder}/no-port", "--duration", "1"],
     "--camera '{fake}': not a video OpenCV can read; expected a camera index"),
    ("replay", 2, ["replay", "{fake}", "--out", "{folder}/replay"],
     "SOURCE '{fake}': not a video OpenCV can read; expected"),
    ("run", 2, ["run", "--camera", "{sequence}/f_%d.png", "--calibration", "{nan}",
                "--port", "{folder}/no-port", "--duration", "1"], "refusing to engage"),
]


@pytest.mark.parametrize(("family", "code", "argv", "text"), CASES,
                         ids=[f"{c[0]}-{c[1]}-{i}" for i, c in enumerate(CASES)])
def test_exit_code(family: str, code: int, argv: list[str], text: str, files: dict[str, str],
                   capsys: pytest.CaptureFixture[str]) -> None:
    got = main([arg.format_map(files) for arg in argv])
    err = capsys.readouterr().err
    assert got == code, err
    if code == 0:
        assert err == ""
    else:
        lines = err.strip().splitlines()
        assert len(lines) == 1 and text.format_map(files) in lines[0], lines


def test_base_exit_0_with_the_standin(capsys: pytest.CaptureFixture[str]) -> None:
    with KobukiStandIn() as standin:
        assert main(["base", "info", "--port", standin.port, "--json"]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("command", ["detect", "undistort"])
@pytest.mark.parametrize(("calibration", "problem"), [
    ("nan.yaml", "camera_matrix has non-finite values"),
    ("zero-focal.yaml", "focal length fx=0, fy=0 px must be positive"),
])
def test_unusable_calibrations_are_refused_as_run_refuses_them(
    command: str, calibration: str, problem: str, files: dict[str, str],
    capsys: pytest.CaptureFixture[str],
) -> None:
    path = f"{files['folder']}/{calibration}"
    argv = [command, files["lane"], "--calibration", path]
    if command == "undistort":
        argv += ["--out", f"{files['folder']}/undistorted-refused"]
    assert main(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.strip().splitlines() == [
        f"lanewarden: error: --calibration {path}: not a usable calibration: {problem}"
    ]


def test_ctrl_c_exits_130_with_one_line(files: dict[str, str]) -> None:
    out = Path(files["folder"]) / "interrupted"
    sim = subprocess.Popen(
        [sys.executable, "-m", "lanewarden", "sim", "--scenario", files["long"],
         "--no-video", "--quiet", "--out", str(out)],
        cwd=PROJECT_ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=sigint_as_from_a_terminal)
    try:
        deadline = time.monotonic() + 120.0
        while not (out / "run.jsonl").exists() and sim.poll() is None:
            assert time.monotonic() < deadline, "the simulation never started"
            time.sleep(0.05)
        sim.send_signal(signal.SIGINT)
        _, err = sim.communicate(timeout=60)
    finally:
        sim.kill()
    assert sim.returncode == 130, err
    assert err.splitlines() == [
        f"lanewarden: error: interrupted: {out / 'PARTIAL'} lists the outputs left incomplete"]


def test_ctrl_c_while_the_command_starts_is_one_line() -> None:
    """The CLI takes seconds to import; a Ctrl-C then (here: the KeyboardInterrupt it raises,
    at the import of lanewarden.cli, without a race against a real signal) had printed Python's
    traceback and exited -2. The entry point says it in one line, exit 130."""
    done = _launched_after(
        "import builtins",
        "real = builtins.__import__",
        "def ctrl_c(name, *args, **kwargs):",
        "    if name == 'lanewarden.cli':",
        "        raise KeyboardInterrupt",
        "    return real(name, *args, **kwargs)",
        "builtins.__import__ = ctrl_c",
    )
    assert (done.returncode, done.stderr) == (130, "lanewarden: error: interrupted\n")


def _launched_after(*setup: str) -> subprocess.CompletedProcess[str]:
    """The entry point (`lanewarden.launcher.main`) run in a new interpreter after `setup`'s
    lines."""
    program = "\n".join([*setup, "from lanewarden.launcher import main",
                          "raise SystemExit(main())"])
    return subprocess.run([sys.executable, "-c", program], capture_output=True, text=True,
                          timeout=120)


def test_a_late_ctrl_c_keeps_the_exit_code_and_prints_nothing() -> None:
    """An attacker's review: a Ctrl-C right after a run's last line, while the interpreter shut
    down, printed a KeyboardInterrupt from an atexit callback, or the process died of the signal
    (-2) instead of exiting with the run's code. Here the command returns 3 and the Ctrl-C comes
    from an atexit callback (no race against a real signal)."""
    done = _launched_after("import atexit, os, signal", "import lanewarden.cli",
                           "lanewarden.cli.main = lambda: 3",
                           "atexit.register(lambda: os.kill(os.getpid(), signal.SIGINT))")
    assert (done.returncode, done.stderr) == (3, "")
