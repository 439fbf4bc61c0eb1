"""A camera clip from the simulator (`sim --camera-out`) played back by `run --camera`, and a run
video (sim's composite video.mp4) refused as a camera, within seconds."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from lanewarden.actuation.base import STOP
from lanewarden.cli import main
from lanewarden.perception.calibration import CameraCalibration, load_calibration
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.camera_clip import CameraClipWriter, check_clip_target
from lanewarden.scenarios.encoder_pipe import mp4_problem
from lanewarden.scenarios.errors import ScenarioError
from lanewarden.scenarios.texture import paint_ground
from lanewarden.scenarios.video import MapView, VideoRecorder, run_video_layout
from lanewarden.scenarios.world import build_world
from lanewarden.supervisor.loop import StepRecord
from tests.operator.clips import lane_end_frames
from tests.scenarios.helpers import straight_spec

#: 3 s on a straight lane with a 320x240 camera; its `config:` makes the run's config differ
#: from the defaults, so the clip gets a config file beside it.
SHORT = """\
name: short
lane:
  segments:
    - straight_m: 4.0
run:
  max_time_s: 3
config:
  simulation: {width_px: 320, height_px: 240, texture_mm_per_px: 5.0}
"""


@pytest.fixture(scope="module")
def scenario(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("scenario") / "short.yaml"
    path.write_text(SHORT, encoding="utf-8")
    return path


def _sim(scenario: Path, out: Path, camera_out: Path) -> dict[str, object]:
    assert main(["sim", "--scenario", str(scenario), "--no-video", "--quiet", "--out", str(out),
                 "--camera-out", str(camera_out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    clip = metrics["camera_clip"]
    assert isinstance(clip, dict)
    return clip


def test_a_video_clip_is_the_cameras_view_at_its_size_and_rate_and_plays_in_run(
        scenario: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / "clips" / "clip.mp4"  # a missing folder is created
    clip = _sim(scenario, tmp_path / "sim", target)
    out = capsys.readouterr().out
    frames = 91  # 3 s at 30 fps, from t = 0
    assert (clip["frames"], clip["size"], clip["fps"]) == (frames, [320, 240], 30.0)
    assert clip["calibration"] == str(tmp_path / "clips" / "clip.calibration.yaml")
    assert clip["config"] == str(tmp_path / "clips" / "clip.config.yaml")
    assert clip["run"] == (f"lanewarden run --camera {target} --calibration "
                           f"{tmp_path / 'clips' / 'clip.calibration.yaml'} --config "
                           f"{tmp_path / 'clips' / 'clip.config.yaml'} --base sim")
    assert f"  play it through the whole loop: {clip['run']}" in out
    capture = cv2.VideoCapture(str(target))
    assert (capture.get(cv2.CAP_PROP_FRAME_WIDTH), capture.get(cv2.CAP_PROP_FRAME_HEIGHT),
            capture.get(cv2.CAP_PROP_FPS), capture.get(cv2.CAP_PROP_FRAME_COUNT)) == (
                320, 240, 30.0, frames)
    ok, first = capture.read()
    capture.release()
    assert ok and run_video_layout(first) is None, "the raw view: no caption band, no map"
    calibration = load_calibration(str(clip["calibration"]))
    assert calibration.image_size == (320, 240)
    assert calibration.ground is not None, "with its pose over the floor"
    assert np.allclose(calibration.dist_coeffs, CameraModel().dist_coeffs), "through the lens"

    record = tmp_path / "run"
    code = main([*str(clip["run"]).split()[1:], "--record", str(record)])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    summary = json.loads((record / "summary.json").read_text())
    assert summary["end_reason"] == "end of the clip"
    assert "FOLLOW" in summary["states_visited"], "it engaged on the simulator's camera view"


def test_a_folder_clip_is_png_frames(scenario: Path, tmp_path: Path) -> None:
    target = tmp_path / "frames"
    target.mkdir()
    (target / "frame_000999.png").write_bytes(b"an earlier clip's frame: replaced")
    clip = _sim(scenario, tmp_path / "sim", target)
    names = sorted(p.name for p in target.iterdir())
    assert names == [f"frame_{i:06d}.png" for i in range(91)]
    assert clip["calibration"] == str(tmp_path / "frames.calibration.yaml")
    image = cv2.imread(str(target / "frame_000000.png"), cv2.IMREAD_UNCHANGED)
    assert image.shape == (240, 320), "the simulated camera is gray by default"


def _folder_with_notes(path: Path) -> None:
    path.mkdir()
    (path / "notes.txt").write_text("mine")


def _a_file(path: Path) -> None:
    path.write_text("a file")


@pytest.mark.parametrize(("make", "expected"), [
    (_folder_with_notes, "the folder holds other files (notes.txt): expected a new or empty "
                         "folder, or one with an earlier clip's frame_NNNNNN.png only"),
    (_a_file, "exists and is not a folder (a name without a video suffix is a folder of PNG "
              "frames; for a video end it in .mp4, .mkv, .avi, .mov)"),
])
def test_a_clip_never_overwrites_what_is_not_its_own(
        make: Callable[[Path], None], expected: str, scenario: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    target = tmp_path / "frames"
    make(target)
    assert main(["sim", "--scenario", str(scenario), "--no-video", "--quiet", "--out",
                 str(tmp_path / "sim"), "--camera-out", str(target)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"lanewarden: error: --camera-out {target}: {expected}"]
    assert not (tmp_path / "sim" / "metrics.json").exists(), "refused before the run"


#: An earlier run's outputs in --out (what `sim` deletes when it prepares the folder).
EARLIER = {"metrics.json": "{}\n", "run.jsonl": "an earlier run's log\n",
           "plot.png": "an earlier plot", "report.html": "an earlier report"}


def _no_folder(path: Path) -> None:
    pass


@pytest.mark.parametrize(("make", "name"), [
    (_folder_with_notes, "frames"), (_a_file, "frames"),
    (_no_folder, "/proc/clip.mp4"),  # a folder that takes no file (bug 2's case)
], ids=["folder-with-notes", "a-file", "unwritable-folder"])
def test_a_refused_clip_leaves_the_earlier_runs_outputs(
        make: Callable[[Path], None], name: str, scenario: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """--camera-out was checked once the run had prepared --out: a refused one had deleted the
    earlier run's outputs there, leaving only PARTIAL. Every check runs first now."""
    target = tmp_path / name  # (an absolute name stays itself)
    make(target)
    out = tmp_path / "sim"
    out.mkdir()
    for file, text in EARLIER.items():
        (out / file).write_text(text)
    assert main(["sim", "--scenario", str(scenario), "--no-video", "--quiet", "--out", str(out),
                 "--camera-out", str(target)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"lanewarden: error: --camera-out {target}: ")
    assert {p.name: p.read_text() for p in out.iterdir()} == EARLIER, "as they were, no PARTIAL"


@pytest.mark.parametrize("target", ["/proc/clip.mp4", "/proc/clip", "/proc/none/clip.mp4"],
                         ids=["video", "frames", "missing-folder"])
def test_a_clip_where_nothing_can_be_written_is_refused_before_the_run_in_one_line(
        target: str, scenario: Path, tmp_path: Path,
        capfd: pytest.CaptureFixture[str]) -> None:
    """/proc takes no file (not even root's): ffmpeg had found it at the first frames, the run
    under way, and printed two lines of its own ("Error opening output files: ...") before ours
    (exit 1); a frames folder there was one line, but as late. Found before the run now: one
    line, exit 2 (capfd: ffmpeg writes to the process's stderr itself)."""
    out = tmp_path / "sim"
    assert main(["sim", "--scenario", str(scenario), "--no-video", "--quiet", "--out", str(out),
                 "--camera-out", target]) == 2
    captured = capfd.readouterr()
    # the reason is the system's: ENOENT for root, EACCES for anyone else
    assert re.fullmatch(rf"lanewarden: error: --camera-out {re.escape(target)}: cannot write "
                        r"there \(cannot create a file in /proc: [^()\n]+\)\n",
                        captured.err), captured.err
    assert not (out / "run.jsonl").exists(), "refused before the run"


def _a_file_on_the_way(tmp_path: Path) -> tuple[Path, str]:
    (tmp_path / "notes").write_text("mine")
    return tmp_path / "notes" / "clip.mp4", f"a part of this path exists and is not a folder " \
                                           f"({tmp_path / 'notes'})"


def _a_folder_for_the_calibration(tmp_path: Path) -> tuple[Path, str]:
    (tmp_path / "clip.calibration.yaml").mkdir()
    return tmp_path / "clip.mp4", f"{tmp_path / 'clip.calibration.yaml'} exists and is not a file"


def _a_link_to_nothing(tmp_path: Path) -> tuple[Path, str]:
    (tmp_path / "clip.mp4").symlink_to(tmp_path / "gone" / "clip.mp4")
    return tmp_path / "clip.mp4", (f"a link to '{tmp_path / 'gone' / 'clip.mp4'}', which does "
                                   "not exist; expected a new file name")


@pytest.mark.parametrize("make", [_a_file_on_the_way, _a_folder_for_the_calibration,
                                  _a_link_to_nothing])
def test_a_clip_its_files_cannot_be_written_for_is_refused_up_front(
        make: Callable[[Path], tuple[Path, str]], tmp_path: Path) -> None:
    """Each had been found only with the run under way: by ffmpeg opening the clip (a file on
    its path, a link into a missing folder) or at the end, writing the calibration."""
    target, expected = make(tmp_path)
    with pytest.raises(ScenarioError) as raised:
        check_clip_target(target)
    assert str(raised.value) == f"--camera-out {target}: {expected}"


@pytest.mark.parametrize("name", ["a:b.mp4", "file:c.mp4", "-x.mp4"])
def test_a_clip_name_is_a_file_name_to_ffmpeg(name: str, tmp_path: Path,
                                              monkeypatch: pytest.MonkeyPatch,
                                              capfd: pytest.CaptureFixture[str]) -> None:
    """ffmpeg read `a:b.mp4` as a protocol ("Protocol not found"), wrote `file:c.mp4` to c.mp4,
    and took `-x.mp4` (`./-x.mp4` to pathlib) for an option, each in lines of its own; the clip
    is the file named now, and stderr stays empty."""
    monkeypatch.chdir(tmp_path)
    writer = CameraClipWriter(check_clip_target(Path(name)), (64, 48), 30.0, "ultrafast",
                              gray=True)
    for i in range(3):
        writer.add(np.zeros((48, 64), np.uint8), i / 30)
    writer.close(CameraCalibration(np.array([[50.0, 0, 32], [0, 50.0, 24], [0, 0, 1]]),
                                   np.zeros(5), (64, 48)), {})
    assert capfd.readouterr().err == ""
    assert mp4_problem(tmp_path / name) is None
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [name, name.removesuffix(".mp4") + ".calibration.yaml"])


# ---- a run video is not a camera -----------------------------------------------------------------
def _run_video(path: Path, camera_size: tuple[int, int], map_px: int) -> Path:
    """A few frames of a run video (sim's video.mp4 layout) around a rendered lane view."""
    world = build_world(straight_spec(2.0), margin_m=1.0)
    recorder = VideoRecorder(path, camera_size, MapView(world, paint_ground(world, 0.02, 0),
                                                        map_px), fps=15.0, crf=28,
                             preset="ultrafast", title="scenario short")
    views = lane_end_frames(start_m=1.0, end_m=1.2, size=camera_size)
    for i, view in enumerate(views[:4]):
        record = StepRecord(frame_index=i, time_s=i / 15, observation=None,
                            filtered_slope_sum=None, slope_sum_variance=None, state="FOLLOW",
                            events=(), command=STOP, halt_reason=None)
        recorder.step(world.start_pose, record)
        recorder.add(view, world.start_pose, i / 15, record, None)
    recorder.close()
    return path


def test_sims_composite_video_is_refused_as_a_camera(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    video = _run_video(tmp_path / "video.mp4", (640, 480), 480)
    record = tmp_path / "run"
    code = main(["run", "--camera", str(video), "--base", "sim", "--record", str(record)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert err == [f"lanewarden: error: --camera {video}: a run video (1120x590: captions above "
                   "a 640-pixel-wide camera panel and a 480-pixel map), not a camera's view "
                   "(expected the camera's own frames: `lanewarden sim --scenario NAME "
                   "--camera-out clip.mp4` writes them)"]
    assert not record.exists(), "refused before anything was recorded or opened"


def test_sims_composite_video_is_refused_as_a_replay_source(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`replay` refuses it as `run` does (it used to play the captions and the map)."""
    video = _run_video(tmp_path / "video.mp4", (640, 480), 480)
    code = main(["replay", str(video), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert err == [f"lanewarden: error: SOURCE '{video}': a run video (1120x590: captions above "
                   "a 640-pixel-wide camera panel and a 480-pixel map), not a camera's view "
                   "(expected the camera's own frames: `lanewarden sim --scenario NAME "
                   "--camera-out clip.mp4` writes them)"]
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("camera_size", "map_px"), [((320, 240), 160), ((160, 120), 480)])
def test_every_run_video_layout_is_recognised(camera_size: tuple[int, int], map_px: int,
                                              tmp_path: Path) -> None:
    capture = cv2.VideoCapture(str(_run_video(tmp_path / "v.mp4", camera_size, map_px)))
    ok, frame = capture.read()
    capture.release()
    assert ok
    panel_w = round(camera_size[0] * map_px / camera_size[1] / 2) * 2
    assert run_video_layout(frame) == (panel_w, map_px)


def test_camera_frames_are_not_taken_for_a_run_video() -> None:
    rng = np.random.default_rng(3)
    for size in ((320, 240), (640, 480), (1120, 590)):
        view = lane_end_frames(start_m=1.0, end_m=1.0, size=size)[0]
        assert run_video_layout(view) is None
        noise = rng.integers(0, 256, (size[1], size[0], 3), dtype=np.uint8)
        assert run_video_layout(noise) is None
    dark = np.full((590, 1120, 3), 32, np.uint8)  # a caption-coloured band, but no dark divider
    assert run_video_layout(dark) is None
