"""`lanewarden replay` on what is not a run folder: the Donkeycar tub (real frames, its recorded
timestamps), a video file and a folder of images each give the video, plot, metrics and report
that `sim` gives; a source that is none of these is one line and exit 2."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest

from lanewarden.cli import main
from lanewarden.perception.calibration import CameraCalibration, save_calibration
from lanewarden.scenarios.camera import CameraModel
from tests.conftest import shared_data
from tests.operator.clips import lane_end_frames, write_images, write_video

HERE = Path(__file__).resolve().parent
DONKEYCAR_CONFIG = HERE.parent / "perception" / "donkeycar_camera.yaml"
DONKEYCAR_CALIBRATION = HERE.parent / "perception" / "donkeycar_calibration.yaml"
OUTPUTS = ("video.mp4", "poster.jpg", "plot.png", "metrics.json", "run.jsonl", "report.html")


def _outputs_written(out: Path) -> dict[str, object]:
    for name in OUTPUTS:
        assert (out / name).stat().st_size > 0, name
    report = (out / "report.html").read_text()
    assert 'src="video.mp4"' in report and 'src="plot.png"' in report
    # a recording's time, not a simulation's (a reviewer read "simulated time" of a real run)
    assert "<th>recorded time replayed (s)</th>" in report and "simulated time" not in report
    assert not (out / "PARTIAL").exists()
    return json.loads((out / "metrics.json").read_text())


def test_the_donkeycar_tub(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    tub = shared_data("donkeycar-tub")
    code = main(["replay", str(tub), "--config", str(DONKEYCAR_CONFIG), "--calibration",
                 str(DONKEYCAR_CALIBRATION), "--out",
                 str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "donkeycar-tub (tub, config:" in out
    # the first line says which ground model, at the tub's own size
    assert out.splitlines()[0].startswith(
        f"ground model: ground calibration from {DONKEYCAR_CALIBRATION}: h 0.230 m, pitch 19.7°")
    assert "; 160x120: look-ahead 0.15 m" in out.splitlines()[0]
    assert "  ended: end of the clip (never engaged)" in out.splitlines()
    # a robot that never left HALT is said never to have engaged, with what held it (the line
    # had read "final state HALT (LANE_DEPARTURE: ...)", as if it had halted)
    held = next(line for line in out.splitlines() if line.startswith("  states visited:"))
    assert held.startswith("  states visited: HALT; never engaged"), held
    assert "final state" not in held
    metrics = _outputs_written(tmp_path / "out")
    assert (metrics["source_kind"], metrics["steps"], metrics["frames"]) == ("tub", 1000, 1000)
    # the tub's own timestamps: 1000 frames over 3.33 s
    assert metrics["sim_time_s"] == pytest.approx(3.33, abs=0.01)
    # At 160x120 through that lens perception can verify tape only 0.15 m ahead and is confident
    # on a few scattered frames (docs/perception.md), never on the run the supervisor needs to
    # engage: it stays halted on this track, as it should.
    assert metrics["states_visited"] == ["HALT"]
    # never engaged, so no halt to summarise
    assert metrics["before_halt"] is None and "before the halt" not in out


def test_a_video_and_a_folder_of_images(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    frames = lane_end_frames(start_m=2.0, end_m=3.5, speed_m_s=0.6)
    video = write_video(frames, tmp_path / "clip.mp4")
    capsys.readouterr()
    assert main(["replay", str(video), "--out", str(tmp_path / "v")]) == 0
    metrics = _outputs_written(tmp_path / "v")
    assert (metrics["source_kind"], metrics["frames"]) == ("video", len(frames))
    assert metrics["halted"] is True
    assert str(metrics["first_halt_reason"]).startswith(("LANE_LOST", "DEGRADED_BUDGET"))
    # what perception gave the supervisor before that halt (scenarios/before_halt.py): the
    # tape ended, so the last frames had no usable lane
    before = metrics["before_halt"]
    assert isinstance(before, dict) and before["window_s"] == 2.0
    assert before["unusable"] > 0 and before["frames"] == (
        before["confident"] + before["usable"] + before["unusable"])
    said = [line for line in capsys.readouterr().out.splitlines()
            if line.startswith("  before the halt: last 2 s: ")]
    assert len(said) == 1, said
    folder = write_images(frames[:30], tmp_path / "images")
    assert main(["replay", str(folder), "--no-video", "--out", str(tmp_path / "i")]) == 0
    metrics = json.loads((tmp_path / "i" / "metrics.json").read_text())
    assert (metrics["source_kind"], metrics["frames"]) == ("images", 30)
    assert "video.mp4" not in metrics["outputs"]  # type: ignore[operator]
    capsys.readouterr()


def test_a_video_whose_frames_cannot_be_decoded_is_bad_input(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Its container intact, its picture data zeroed: it replayed '76 steps, 0 frames', exit 0."""
    video = write_video(lane_end_frames(start_m=2.0, end_m=3.5, speed_m_s=0.6),
                        tmp_path / "clip.mp4")
    data = bytearray(video.read_bytes())
    start, end = data.find(b"mdat") + 64, data.find(b"moov") - 64
    data[start:end] = bytes(end - start)
    video.write_bytes(bytes(data))
    assert main(["replay", str(video), "--no-video", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [f"lanewarden: error: SOURCE '{video}': none of its 76 frames "
                                "could be decoded (a damaged or cut file?)"]


def test_an_image_that_does_not_decode_is_no_frame_and_bad_input(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """One file of a folder of images is not an image: the loop gets no frame at its step
    (it had been given the frame before again, and the replay exited 0 without a word), and the
    replay, its outputs written, is bad input naming the file."""
    folder = write_images(lane_end_frames(start_m=2.0, end_m=2.4, speed_m_s=0.6), tmp_path / "i")
    (folder / "frame_5.png").write_bytes(b"not a picture")
    out = tmp_path / "o"
    assert main(["replay", str(folder), "--no-video", "--out", str(out)]) == 2
    err = [line for line in capsys.readouterr().err.splitlines()
           if not line.startswith("replay i: ")]  # (the progress lines)
    assert len(err) == 1, err
    assert err[0].startswith(f"lanewarden: error: SOURCE '{folder}': 1 of its "), err
    assert "frames could not be decoded (counted from 0): frame " in err[0] and (
        "(frame_5.png)" in err[0])
    assert err[0].endswith(f"the loop saw no frame there, outputs in {out}/")
    steps = [json.loads(line) for line in (out / "run.jsonl").read_text().splitlines()]
    unread = int(err[0].split("from 0): frame ")[1].split(" ")[0])
    assert steps[unread]["frame_index"] is None and steps[unread]["observation"] is None
    assert [s["frame_index"] for s in steps if s["frame_index"] is not None] == [
        i for i in range(len(steps)) if i != unread]
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["frames_undecoded"] == [unread]


def test_one_photo_is_a_one_frame_replay_and_a_broken_one_is_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A single photo is read as `detect` reads it (a new user's trial: OpenCV's video reader
    took a cut JPEG for a 1-frame video, exit 0, and a text file named .jpg for a video whose
    only frame it could not decode: a summary, then the error)."""
    folder = write_images(lane_end_frames(start_m=2.0, end_m=2.1, speed_m_s=0.6), tmp_path / "i")
    photo = next(iter(sorted(folder.iterdir())))
    assert main(["replay", str(photo), "--no-video", "--out", str(tmp_path / "o")]) == 0
    metrics = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert (metrics["source_kind"], metrics["frames"]) == ("images", 1)
    cut = tmp_path / "cut.png"
    cut.write_bytes(photo.read_bytes()[:200])
    text = tmp_path / "text.jpg"
    text.write_text("not a picture\n")
    for broken in (cut, text):
        capsys.readouterr()
        out = tmp_path / broken.stem
        assert main(["replay", str(broken), "--no-video", "--out", str(out)]) == 2
        captured = capsys.readouterr()
        (line,) = captured.err.splitlines()
        assert line.startswith(f"lanewarden: error: SOURCE '{broken}': "), line
        assert captured.out == "", "no summary of a replay that never ran"
        assert not out.exists()


def test_ctrl_c_during_a_replay_names_its_partial_marker(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Ctrl-C while the outputs are written (here: the KeyboardInterrupt a Ctrl-C raises, after
    the first step): exit 130 and one line naming the PARTIAL marker that lists the incomplete
    outputs, as `sim` and `demo` say it. It had read "interrupted" alone, the old outputs gone
    and the marker unmentioned."""
    import lanewarden.replay_outputs as replay_outputs

    real_steps = replay_outputs.replay_steps

    def ctrl_c_after_the_first(*args: object, **kwargs: object) -> Iterator[object]:
        for step in real_steps(*args, **kwargs):  # type: ignore[arg-type]
            yield step
            raise KeyboardInterrupt

    monkeypatch.setattr(replay_outputs, "replay_steps", ctrl_c_after_the_first)
    folder = write_images(lane_end_frames(start_m=2.0, end_m=2.2, speed_m_s=0.6)[:3],
                          tmp_path / "lane")
    out = tmp_path / "o"
    assert main(["replay", str(folder), "--no-video", "--out", str(out)]) == 130
    err = [line for line in capsys.readouterr().err.splitlines()
           if not line.startswith("replay lane: ")]  # (the progress lines)
    assert err == [
        f"lanewarden: error: interrupted: {out / 'PARTIAL'} lists the outputs left incomplete"]
    assert "metrics.json" in (out / "PARTIAL").read_text()
    assert not (out / "metrics.json").exists()


def test_a_glob_of_images_is_named_after_its_folder(tmp_path: Path) -> None:
    from lanewarden.replay_sources import open_replay_source

    folder = write_images(lane_end_frames(start_m=2.0, end_m=2.2, speed_m_s=0.6)[:3],
                          tmp_path / "lane")
    # the default output folder is lanewarden-out/replay-<name>: not 'replay-*.png'
    assert open_replay_source(str(folder / "*.png"), 30.0).name == "lane"
    assert open_replay_source(str(folder), 30.0).name == "lane"


def test_not_a_source_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "notes.txt").write_text("hello")
    for source in (tmp_path / "missing", tmp_path / "notes.txt"):
        code = main(["replay", str(source), "--out", str(tmp_path / "o")])
        err = capsys.readouterr().err
        assert code == 2
        assert err.count("\n") == 1 and str(source) in err and "Traceback" not in err


def test_a_clip_replayed_without_the_calibration_beside_it_is_warned(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A sim clip (`sim --camera-out clip.mp4` writes clip.calibration.yaml beside it) replayed
    without --calibration drove on past the tape's end, where with it the replay halted
    LANE_LOST, and said nothing (a new user's walk-through); `run` names the file."""
    video = write_video(lane_end_frames(start_m=2.0, end_m=3.5, speed_m_s=0.6)[:12],
                        tmp_path / "clip.mp4")
    camera = CameraModel()
    beside = tmp_path / "clip.calibration.yaml"
    save_calibration(CameraCalibration(camera.camera_matrix(), camera.distortion(), (640, 480)),
                     beside)
    capsys.readouterr()
    assert main(["replay", str(video), "--no-video", "--out", str(tmp_path / "a")]) == 0
    warned = [line for line in capsys.readouterr().err.splitlines() if "warning" in line]
    assert warned == [f"lanewarden: warning: no --calibration; the clip's own calibration lies "
                      f"beside it: --calibration {beside}"]
    assert main(["replay", str(video), "--no-video", "--calibration", str(beside), "--out",
                 str(tmp_path / "b")]) == 0
    assert "warning" not in capsys.readouterr().err


def test_check_of_what_is_not_a_recorded_run_is_refused_before_the_work(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`replay VIDEO --check` had replayed the whole clip, written its outputs and printed the
    summary before saying there was nothing to compare with (a new user's review)."""
    folder = write_images(lane_end_frames(start_m=2.0, end_m=2.1, speed_m_s=0.6), tmp_path / "i")
    out = tmp_path / "o"
    assert main(["replay", str(folder), "--check", "--no-video", "--out", str(out)]) == 2
    captured = capsys.readouterr()
    assert captured.err == (f"lanewarden: error: --check: {folder} is a folder of images, not a "
                            "recorded run: there is nothing to compare with\n")
    assert captured.out == "" and not out.exists()
