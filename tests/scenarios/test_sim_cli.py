"""`lanewarden sim` and `lanewarden demo` as a user runs them."""

from __future__ import annotations

import errno
import json
from pathlib import Path

import cv2
import pytest

from lanewarden.cli import main
from tests.processes import interrupted

SHORT = """\
name: short
lane:
  segments:
    - straight_m: 3.0
run:
  max_time_s: 3
config:
  simulation: {width_px: 320, height_px: 240, texture_mm_per_px: 5.0}
expect:
  supervised:
    halted: false
"""


def video_info(path: Path) -> dict[str, object]:
    import imageio_ffmpeg

    frames = imageio_ffmpeg.read_frames(str(path))
    info = dict(next(frames))
    frames.close()
    return info


def test_unknown_scenario_is_one_line_listing_the_names(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "--scenario", "nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("lanewarden: error: --scenario: unknown scenario 'nope' (expected")
    assert "lecture" in err[0] and "fault-bumper" in err[0]


def test_a_mistyped_scenario_or_command_gets_a_did_you_mean(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", "--scenario", "lane-end"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("lanewarden: error: --scenario: unknown scenario 'lane-end'; did "
                             "you mean 'lane-ends'? (expected a YAML file or one of: ")
    assert main(["smi", "--scenario", "lecture"]) == 2
    assert capsys.readouterr().err == (
        "lanewarden: error: No such command 'smi'; did you mean 'sim'?\n")  # said once
    assert main(["base", "inf"]) == 2
    assert capsys.readouterr().err == (  # a group's commands: the group is named
        "lanewarden: error: lanewarden base: No such command 'inf'; did you mean 'info'?\n")
    assert main(["xyzzy"]) == 2
    assert "No such command 'xyzzy' (expected one of: " in capsys.readouterr().err


@pytest.mark.parametrize("width", [60, 80, 120])
def test_help_never_splits_a_scenario_name(width: int) -> None:
    from click.testing import CliRunner

    from lanewarden.cli import cli
    from lanewarden.scenarios.library import library_names

    result = CliRunner().invoke(cli, ["sim", "--help"], terminal_width=width)
    assert result.exit_code == 0
    words = set(result.output.replace(",", " ").split())
    for name in library_names():
        assert name in words, f"{name} split or missing in sim --help at width {width}"


def test_a_run_replaces_the_old_outputs_and_keeps_other_files(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = tmp_path / "short.yaml"
    scenario.write_text(SHORT.replace("max_time_s: 3", "max_time_s: 0.5"), encoding="utf-8")
    out = tmp_path / "missing" / "run"
    out.mkdir(parents=True)
    for stale in ("video.mp4", "poster.jpg", "metrics.json", "PARTIAL"):
        (out / stale).write_text("from an older run")
    (out / "notes.txt").write_text("mine")
    assert main(["sim", "--scenario", str(scenario), "--out", str(out), "--quiet",
                 "--no-video"]) == 0, capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == [
        "metrics.json", "notes.txt", "plot.png", "report.html", "run.jsonl"]
    assert json.loads((out / "metrics.json").read_text())["outputs"] == [
        "metrics.json", "plot.png", "report.html", "run.jsonl"]
    assert (out / "notes.txt").read_text() == "mine"


def test_an_output_folder_that_is_a_file_is_bad_input(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "taken").write_text("a file")
    assert main(["sim", "--scenario", "straight", "--out", str(tmp_path / "taken")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Invalid value for '--out'" in err and "is a file" in err


def test_an_output_folder_that_cannot_be_written_is_a_runtime_failure(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """An existing --out on a read-only file system: the first write (the PARTIAL marker) gets
    the operating system's answer, given here in place of the write (it had exited 2, bad
    input; the scenario was fine, so 1, as calibrate and detect say of an unwritable output)."""
    out = tmp_path / "mounted"
    out.mkdir()

    def read_only(self: Path, *args: object, **kwargs: object) -> int:
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(Path, "write_text", read_only)
    assert main(["sim", "--scenario", "straight", "--out", str(out), "--quiet"]) == 1
    assert capsys.readouterr().err.splitlines() == [
        f"lanewarden: error: {out}: cannot prepare the output folder ([Errno 30] Read-only file "
        "system)"]


def test_an_interrupted_run_says_which_files_are_partial(tmp_path: Path) -> None:
    scenario = tmp_path / "long.yaml"
    scenario.write_text(SHORT.replace("max_time_s: 3", "max_time_s: 60")
                        .replace("straight_m: 3.0", "straight_m: 30.0"), encoding="utf-8")
    out = tmp_path / "run"
    log = out / "run.jsonl"
    # Interrupted once the run is under way: steps are being recorded.
    code, err = interrupted(
        ["sim", "--scenario", str(scenario), "--out", str(out), "--quiet"],
        lambda: log.exists() and log.stat().st_size > 0, whole_group=False)
    assert code == 130
    assert err.splitlines() == [
        f"lanewarden: error: interrupted: {out / 'PARTIAL'} lists the outputs left incomplete"]
    marker = (out / "PARTIAL").read_text().splitlines()
    assert marker[0].startswith("This folder's outputs are incomplete")
    assert marker[2:] == ["  metrics.json", "  run.jsonl", "  video.mp4", "  poster.jpg",
                          "  plot.png", "  report.html"]
    assert not (out / "metrics.json").exists()


def test_an_interrupted_camera_clip_is_moved_aside_and_listed(tmp_path: Path) -> None:
    """`--camera-out clip.mp4` cut short: the clip had kept its name, without its calibration
    and unlisted in PARTIAL, and `run --camera clip.mp4` played it as a whole clip. Now it is
    clip.partial.mp4, named in PARTIAL; an earlier clip's calibration beside it is gone."""
    scenario = tmp_path / "long.yaml"
    scenario.write_text(SHORT.replace("max_time_s: 3", "max_time_s: 60")
                        .replace("straight_m: 3.0", "straight_m: 30.0"), encoding="utf-8")
    out, clip = tmp_path / "run", tmp_path / "clip.mp4"
    (tmp_path / "clip.calibration.yaml").write_text("# an earlier clip's\n", encoding="utf-8")
    log = out / "run.jsonl"
    code, _ = interrupted(
        ["sim", "--scenario", str(scenario), "--out", str(out), "--quiet", "--no-video",
         "--camera-out", str(clip)],
        lambda: log.exists() and log.stat().st_size > 0, whole_group=False)
    assert code == 130
    partial = tmp_path / "clip.partial.mp4"
    assert partial.is_file() and not clip.exists()
    assert not (tmp_path / "clip.calibration.yaml").exists()
    last = (out / "PARTIAL").read_text().splitlines()[-1]
    assert last.startswith(f"  {partial} (the camera clip, cut short after "), last
    assert last.endswith(" frames; no calibration beside it)"), last


def test_a_second_clip_cut_short_takes_the_next_partial_name(tmp_path: Path) -> None:
    """clip.partial is taken by an earlier cut-short clip: the new one had stayed under the
    clip's own name (a code review found it); it goes to clip.partial-2."""
    import numpy as np

    from lanewarden.scenarios.camera_clip import CameraClipWriter, ClipFiles

    (tmp_path / "clip.partial").mkdir()
    writer = CameraClipWriter(ClipFiles.for_target(tmp_path / "clip"), (32, 24), 30.0,
                              "veryfast", gray=True)
    writer.add(np.zeros((24, 32), np.uint8), 0.0)
    assert writer.abort() == tmp_path / "clip.partial-2"
    assert not (tmp_path / "clip").exists()
    assert (tmp_path / "clip.partial-2" / "frame_000000.png").is_file()


def test_ctrl_c_on_a_terminal_stops_the_demo_with_one_line(tmp_path: Path) -> None:
    """A terminal's Ctrl-C reaches the whole process group: the demo's two worker processes
    printed a KeyboardInterrupt traceback each (34-53 lines); they leave it to the demo now."""
    out = tmp_path / "demo"
    logs = [out / name / "run.jsonl" for name in ("lecture", "supervised")]
    # Interrupted while both runs are under way (steps being recorded in both). Not once one
    # has finished, as this test first did: the two runs end within 0.2 s of each other, and a
    # Ctrl-C after both could land while the demo writes its report or exits (one CI run in
    # three on 2026-12-04: exit -2).
    code, err = interrupted(["demo", "--out", str(out), "--quiet"],
                             lambda: all(log.exists() and log.stat().st_size > 0 for log in logs),
                             whole_group=True)
    assert code == 130
    assert err.splitlines() == [
        f"lanewarden: error: interrupted: {out / 'PARTIAL'} lists the outputs left incomplete"]


@pytest.mark.parametrize(("given", "expected"), [
    ("-3", "-3: expected a finite number with 0 < value <= 600"),
    # `max_time_s: yes` would run for 1 s
    ("yes", "true (YAML's reading of true, yes or on): expected a finite number with "
     "0 < value <= 600, not true/false"),
])
def test_bad_scenario_file_names_file_and_key(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                              given: str, expected: str) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(SHORT.replace("max_time_s: 3", f"max_time_s: {given}"), encoding="utf-8")
    assert main(["sim", "--scenario", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"lanewarden: error: {bad}: run.max_time_s = {expected}"]


@pytest.mark.parametrize(("section", "said"), [
    ("floor: {kind: tiles, grid_offset_m: [1.0e300, 0.0]}",
     "floor.grid_offset_m.0 = 1e+300: input should be less than or equal to 1000"),
    ("lighting:\n  ceiling: {offset_m: [0.0, -1.0e308]}",
     "lighting.ceiling.offset_m.1 = -1e+308: input should be greater than or equal to -1000"),
])
def test_an_offset_on_the_floor_is_bounded(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                           section: str, said: str) -> None:
    """A tile grid shifted by 1e300 m made the floor NaN, with NumPy's warnings and a robot that
    never engaged; ceiling lights shifted by 1e308 m were an OverflowError traceback."""
    bad = tmp_path / "bad.yaml"
    bad.write_text(f"{SHORT}{section}\n", encoding="utf-8")
    assert main(["sim", "--scenario", str(bad), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert capsys.readouterr().err.splitlines() == [f"lanewarden: error: {bad}: {said}"]


@pytest.mark.parametrize(("flag", "what"), [("--scenario", "scenario"),
                                            ("--case", "campaign case")])
def test_a_config_given_as_the_scenario_is_one_line_saying_so(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], flag: str, what: str) -> None:
    """`config show`'s file given to --scenario had said 'missing' of name and lane and
    'unknown key' of each of the config's six sections ('perception': did you mean
    'description'?): eight lines, none saying what the file is. Given to --case it said "not a
    campaign case": a config's `campaign:` section is also a case's key, and that had made it
    a case."""
    assert main(["config", "show"]) == 0
    config = tmp_path / "lw.yaml"
    config.write_text(capsys.readouterr().out, encoding="utf-8")
    out = tmp_path / "o"
    assert main(["sim", flag, str(config), "--out", str(out), "--quiet"]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"lanewarden: error: {config}: a lanewarden config (it has 'perception:'), not a "
        f"{what} (give this file to --config)"]
    assert not out.exists()


def test_a_world_too_large_names_the_scenario_file(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The world's own size check knew only the scenario's name ('geo: the lane ... covers');
    every other scenario problem names its file. Checked before any output is touched."""
    bad = tmp_path / "wide.yaml"
    bad.write_text("name: geo\nlane:\n  segments:\n    - straight_m: 2.0\n"
                   "    - {turn_deg: 180, arc_radius_m: 15.0}\nrun:\n  max_time_s: 3\n",
                   encoding="utf-8")
    out = tmp_path / "o"
    assert main(["sim", "--scenario", str(bad), "--out", str(out), "--quiet"]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"lanewarden: error: {bad}: the lane and its 2.5 m margins cover 22.6 x 35.6 m = 805 m^2 "
        "of floor, expected at most 300 m^2 (a more compact lane, or a smaller "
        "simulation.world_margin_m)"]
    assert not (out / "PARTIAL").exists()


def test_sim_writes_every_output(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scenario = tmp_path / "short.yaml"
    scenario.write_text(SHORT, encoding="utf-8")
    out = tmp_path / "run"
    code = main(["sim", "--scenario", str(scenario), "--seed", "3", "--out", str(out),
                 "--quiet", "--check"])
    assert code == 0, capsys.readouterr().err
    metrics = json.loads((out / "metrics.json").read_text())
    for key in ("scenario", "controller", "seed", "frames", "sim_time_s", "wall_time_s", "halted",
                "halt_reason", "final_state", "states_visited", "max_cross_track_error_m",
                "mean_cross_track_error_m", "distance_travelled_m", "distance_past_lane_end_m",
                "crossed_tape", "lane_loss_to_halt_s", "turns_completed"):
        assert key in metrics
    assert metrics["scenario"] == "short" and metrics["seed"] == 3
    assert metrics["controller"] == "supervised" and metrics["expectation_met"] is True
    assert metrics["frames"] == 91 and metrics["sim_time_s"] == pytest.approx(3.0)
    lines = (out / "run.jsonl").read_text().splitlines()
    assert len(lines) == metrics["frames"]
    first = json.loads(lines[0])
    assert first["state"] == "HALT" and "observation" in first and "command" in first
    assert (out / "plot.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    info = video_info(out / "video.mp4")
    assert info["codec"] == "h264" and str(info["pix_fmt"]).startswith("yuv420p")
    assert info["size"] == (640 + 480, 480 + 110)  # camera panel beside the map, under a caption
    assert sorted(metrics["outputs"]) == metrics["outputs"] == [
        "metrics.json", "plot.png", "poster.jpg", "report.html", "run.jsonl", "video.mp4"]
    assert metrics["video_poster"] == {"shows": "the last frame", "time_s": 3.0}
    poster = cv2.imread(str(out / "poster.jpg"))
    assert poster.shape == (480 + 110, 640 + 480, 3)
    assert not (out / "PARTIAL").exists()
    assert 'data-video="video.mp4"><img src="poster.jpg"' in (out / "report.html").read_text()
    stdout = capsys.readouterr().out
    assert "expected outcome: met" in stdout and str(out) in stdout


def test_check_flag_fails_an_unmet_expectation(tmp_path: Path) -> None:
    scenario = tmp_path / "short.yaml"
    scenario.write_text(SHORT.replace("halted: false", "halted: true"), encoding="utf-8")
    code = main(["sim", "--scenario", str(scenario), "--out", str(tmp_path / "o"), "--quiet",
                 "--no-video", "--check"])
    assert code == 2
    assert not (tmp_path / "o" / "video.mp4").exists()


def test_a_simulated_camera_whose_buffers_would_take_gigabytes_is_refused_first(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Each value within its bounds, together they took 7.5 GB without a word (an attacker's
    review): a 1920x1440 colour camera at 120 Hz keeps 604 frames to serve a 5 s late_frames
    latency, and 64 noise frames of float32."""
    scenario = tmp_path / "late.yaml"
    scenario.write_text("name: late\nlane:\n  segments:\n    - straight_m: 8.0\ncamera: "
                        "{width_px: 1920, height_px: 1440}\nrun:\n  max_time_s: 8\nfaults: "
                        "[{kind: late_frames, at_s: 0.0, latency_s: 5.0}]\n", encoding="utf-8")
    config = tmp_path / "fast.yaml"
    config.write_text("simulation: {camera_rate_hz: 120, perception_color: true, "
                      "noise_bank_frames: 64}\n"
                      f"supervisor: {{camera_period_s: {1 / 120!r}}}\n", encoding="utf-8")
    out = tmp_path / "o"
    assert main(["sim", "--scenario", str(scenario), "--config", str(config), "--out", str(out),
                 "--quiet", "--no-video"]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"lanewarden: error: {scenario}: the simulated camera's buffers would take 6.6 GB, more "
        "than 2 GB: 604 frames of 1920x1440 colour kept to serve late frames at "
        "simulation.camera_rate_hz 120, and 64 noise frames (simulation.noise_bank_frames); "
        "expected a smaller camera, a lower rate, a shorter late_frames latency or fewer noise "
        "frames"]
    assert not out.exists() or not any(out.iterdir())  # checked before anything is written


@pytest.mark.parametrize(("expect", "said"), [
    ("min_distance_travelled_m: 5.0, max_distance_travelled_m: 1.0",
     "expect.supervised: min_distance_travelled_m 5 is more than max_distance_travelled_m 1: no "
     "run can meet both"),
    ("halted: false, halt_reason_any_of: [BUMPER]",
     "expect.supervised: halted: false with halt_reason_any_of: a run that does not halt has no "
     "halt to check"),
    ("states_visited_include: [FOLLOW, HALT], states_visited_exclude: [FOLLOW]",
     "expect.supervised: states ['FOLLOW'] are both in states_visited_include and in "
     "states_visited_exclude"),
    ("turns_completed: [Z]",
     "expect.supervised.turns_completed: ['Z'] are not marks of the lane's segments (none)"),
])
def test_an_expectation_no_run_can_meet_is_refused_when_read(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], expect: str, said: str) -> None:
    """Each had run the whole scenario, then failed --check (an attacker's review)."""
    scenario = tmp_path / "contra.yaml"
    scenario.write_text("name: contra\nlane:\n  segments: [{straight_m: 3.0}]\nrun: "
                        f"{{max_time_s: 2}}\nexpect:\n  supervised: {{{expect}}}\n",
                        encoding="utf-8")
    assert main(["sim", "--scenario", str(scenario), "--out", str(tmp_path / "o"), "--quiet",
                 "--no-video"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(f"lanewarden: error: {scenario}: "), err
    assert err[0].endswith(said), err


def test_a_floor_region_in_view_but_a_few_pixels_large_is_called_that(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A 150 deg lens 2 m up on a 64x48 image sees the ROI in 36 pixels: it was called "not in
    the camera's view", beside a visible range (-4.13 m to 7.59 m) that holds it (an attacker's
    review)."""
    scenario = tmp_path / "steep.yaml"
    scenario.write_text("name: steep\nlane:\n  segments:\n    - straight_m: 3.0\ncamera: "
                        "{pitch_deg: 85, hfov_deg: 150, height_m: 2.0, width_px: 64, height_px: "
                        "48}\nrun:\n  max_time_s: 2\n", encoding="utf-8")
    assert main(["sim", "--scenario", str(scenario), "--out", str(tmp_path / "o"), "--quiet",
                 "--no-video"]) == 2
    assert capsys.readouterr().err.splitlines() == [
        "lanewarden: error: perception.roi (near_m 0, far_m 1.6, lateral_m 0.65): this floor "
        "covers only 36 of the 64x48 image's pixels; expected at least 64 (a larger image, a "
        "narrower lens or a lower camera)"]


#: A write to the base that blocks for good from 3 s: the supervisor halts (BASE_LINK_LOST), but
#: no command reaches the base any more, and the simulated base drives its last one (a Kobuki has
#: no command timeout).
WRITES_BLOCK = """\
name: writes-block
lane:
  segments:
    - straight_m: 8.0
faults: [{kind: write_blocks, at_s: 3.0}]
run:
  max_time_s: 6
config:
  simulation: {width_px: 320, height_px: 240, texture_mm_per_px: 5.0}
expect:
  supervised: {halted: true, halt_reason_any_of: [BASE_LINK_LOST]}
"""


def test_check_fails_a_halt_the_base_never_obeyed_and_every_output_says_so(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A safety reviewer's test (a helper's review): `sim --check` said 'expected outcome: met'
    (exit 0) for a run whose supervisor halted while the robot drove on to the time limit, and
    neither the terminal nor report.html said when the fault came or that the robot never
    stopped. HALT is the controller's state; the base must stop."""
    scenario = tmp_path / "writes-block.yaml"
    scenario.write_text(WRITES_BLOCK, encoding="utf-8")
    out = tmp_path / "o"
    code = main(["sim", "--scenario", str(scenario), "--out", str(out), "--quiet", "--no-video",
                 "--check"])
    stdout, err = capsys.readouterr()
    assert code == 2, err
    assert err == "lanewarden: error: scenario writes-block: expected outcome not met\n"
    moving = "still moving at 0.20 m/s 1.5 s or more after HALT"
    assert ("  expected outcome: NOT met: halted = True, but the robot did not stop: "
            f"{moving}\n") in stdout
    assert f"  NOT STOPPED after HALT: {moving} (the base kept driving: unsafe)\n" in stdout
    assert "  faults: write_blocks (fault 0) at 3.000 s\n" in stdout
    halt = json.loads((out / "metrics.json").read_text())
    assert halt["motion_after_halt"] == moving
    assert halt["fault_effects"] == [
        {"index": 0, "kind": "write_blocks", "frame_index": 90, "time_s": 3.0}]
    to_halt = halt["fault_to_halt"]
    assert to_halt["kind"] == "write_blocks" and to_halt["took_effect_s"] == 3.0
    assert to_halt["to_halt_s"] == pytest.approx(halt["halt_time_s"] - 3.0, abs=1e-4)
    assert (f"  HALT at {halt['halt_time_s']:.3f} s, {to_halt['to_halt_s']:.3f} s after "
            "write_blocks (fault 0) took effect\n") in stdout
    page = (out / "report.html").read_text()
    assert f"NOT STOPPED: {moving}" in page and "but the robot did not stop" in page
    assert "write_blocks (fault 0) at 3.000 s" in page


def test_check_without_an_expectation_is_refused_before_the_run(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """It had run the whole simulation first (a reviewer's `--controller lecture --check` on a
    scenario that states only the supervisor's outcome), then refused."""
    scenario = tmp_path / "short.yaml"
    scenario.write_text(SHORT, encoding="utf-8")
    out = tmp_path / "o"
    assert main(["sim", "--scenario", str(scenario), "--controller", "lecture", "--check",
                 "--out", str(out), "--quiet", "--no-video"]) == 2
    assert capsys.readouterr().err == (
        "lanewarden: error: --check: scenario short states no expected outcome for controller "
        "'lecture' (add an expect: block for it), nothing was checked\n")
    assert not out.exists()
