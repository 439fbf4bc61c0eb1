"""`lanewarden detect`: output format, overlays, calibration, and the one-line error contract."""

from __future__ import annotations

import json
import re
from pathlib import Path

import cv2
import pytest

from lanewarden.cli import main
from lanewarden.perception.calibration import CameraCalibration, save_calibration
from lanewarden.scenarios.camera import CameraModel
from tests.perception import synthetic as syn

KEYS = ["image", "left", "right", "slope_sum", "lane_offset_m", "lane_heading_rad", "confidence",
        "components", "decision"]
#: The one line on stderr saying which ground model perception uses.
GROUND_LINE = (
    "lanewarden: ground model: no ground calibration: assuming the simulator's default camera "
    "(70° HFOV, h 0.400 m, pitch 35.0°, 0.150 m ahead of the robot's centre); 640x480: "
    "look-ahead 0.87 m (auto: edges.max_look_ahead_m); there one pixel covers 2.1 mm across a "
    "tape where the lane's tapes run (a tape measures 38.7 mm or more there, a seam at most "
    "26.1 mm)\n"
)


@pytest.fixture(scope="module")
def frames(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("frames")
    cv2.imwrite(str(folder / "straight.png"), syn.frame(syn.STRAIGHT))
    cv2.imwrite(str(folder / "right.png"), syn.frame(syn.BEND_RIGHT))
    cv2.imwrite(str(folder / "tiles.jpg"), syn.frame(syn.TILES_ONLY))
    cv2.imwrite(str(folder / "small.png"), syn.frame(syn.STRAIGHT, 320, 240))
    cv2.imwrite(str(folder / "distorted.png"), syn.frame(syn.STRAIGHT, distorted=True))
    (folder / "empty.png").write_bytes(b"")
    (folder / "notes.png").write_text("not an image\n")
    camera = CameraModel()
    save_calibration(
        CameraCalibration(camera.camera_matrix(), camera.distortion(), (640, 480)),
        folder / "camera.yaml",
    )
    return folder


def run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(args)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_json_lines(frames: Path, capsys: pytest.CaptureFixture[str]) -> None:
    images = [str(frames / n) for n in ("straight.png", "right.png", "tiles.jpg")]
    code, out, err = run(["detect", *images, "--json"], capsys)
    assert code == 0 and err == GROUND_LINE
    lines = [json.loads(line) for line in out.splitlines()]
    assert [list(line) for line in lines] == [KEYS] * 3
    assert [line["image"] for line in lines] == images
    assert [line["decision"] for line in lines] == ["straight", "right", "none"]
    straight, right, tiles = lines
    assert set(straight["left"]) == {"x1", "y1", "x2", "y2", "slope", "offset_m", "heading_rad",
                                    "near_m", "far_m"}
    # the near line on the floor runs from near_m to far_m ahead: at least EVIDENCE_MIN_M (0.10)
    assert straight["left"]["far_m"] >= straight["left"]["near_m"] + 0.10
    assert straight["left"]["slope"] > 0 > straight["right"]["slope"]
    # Metric outputs, robot frame: the inner tape edges 0.276 m either side, the lane straight
    # ahead and centred.
    assert straight["left"]["offset_m"] == pytest.approx(0.276, abs=0.005)
    assert straight["right"]["offset_m"] == pytest.approx(-0.276, abs=0.005)
    assert straight["lane_offset_m"] == pytest.approx(0.0, abs=0.005)
    assert straight["lane_heading_rad"] == pytest.approx(0.0, abs=0.01)
    assert tiles["lane_offset_m"] is not None  # two (seam) edges: measured, and not trusted
    assert right["slope_sum"] < -6
    assert tiles["confidence"] == 0.0 and tiles["components"]["verified_tape"] == 0.0


def test_text_output_and_overlays(
    frames: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out_dir = tmp_path / "annotated"
    code, out, _ = run(
        ["detect", str(frames / "straight.png"), str(frames / "small.png"), "--out", str(out_dir)],
        capsys,
    )
    assert code == 0
    assert out.splitlines()[0] == GROUND_LINE.removeprefix("lanewarden: ").rstrip("\n")
    assert out.splitlines()[1].startswith(f"{frames / 'straight.png'}: straight  slope sum")
    big = cv2.imread(str(out_dir / "straight_detect.png"))
    small = cv2.imread(str(out_dir / "small_detect.png"))
    assert big is not None and big.shape == (480, 640, 3)
    # a smaller frame's picture is enlarged by a whole factor to 480 rows or more, so that
    # perception's text fits its width (a 224x224 frame's had been cut off at its right edge)
    assert small is not None and small.shape == (480, 640, 3)
    below_text = small[240:]  # (the text is drawn after the enlarging, at the top)
    assert (below_text[::2, ::2] == below_text[1::2, 1::2]).all()  # each pixel a 2x2 block


def test_calibration_undistorts_first(frames: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run(
        ["detect", str(frames / "distorted.png"), "--calibration", str(frames / "camera.yaml"),
         "--json"],
        capsys,
    )
    assert code == 0
    assert json.loads(out)["decision"] == "straight"


def test_bad_images_are_named_and_good_results_kept(
    frames: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    missing = frames / "missing.png"
    args = [
        "detect",
        str(frames / "straight.png"),
        str(missing),
        str(frames / "empty.png"),
        str(frames / "notes.png"),
        str(frames),
        str(frames / "right.png"),
        "--json",
    ]
    code, out, err = run(args, capsys)
    assert code == 2
    assert [json.loads(line)["decision"] for line in out.splitlines()] == ["straight", "right"]
    assert err.startswith(GROUND_LINE)
    err = err.removeprefix(GROUND_LINE)
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert err.startswith("lanewarden: error: 4 of 6 images not analysed")
    for name, why in [
        (missing, "no such file"),
        (frames / "empty.png", "empty file"),
        (frames / "notes.png", "not a readable image"),
        (frames, "is a folder, not an image file"),
    ]:
        assert f"{name}: {why}" in err


def test_image_size_differs_from_calibration(
    frames: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The error names the flag and both sizes; no ground line of the calibration's size comes
    first (a new user's review: it said 640x480 of a 320x240 image, then 'undistort: ...')."""
    code, out, err = run(
        ["detect", str(frames / "small.png"), "--calibration", str(frames / "camera.yaml")],
        capsys,
    )
    assert code == 2
    assert out == ""
    assert err.strip() == (
        f"lanewarden: error: 1 of 1 images not analysed: {frames / 'small.png'}: image is "
        f"320x240, but --calibration {frames / 'camera.yaml'} is for 640x480 images")


def test_a_config_refused_at_a_size_is_said_once(
    frames: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """19 mm tape looked for 0.87 m ahead in three 320x240 images: one line says the config
    error once, with how many images it kept out (it was said once per image)."""
    config = frames / "thin.yaml"
    config.write_text("perception:\n  tape: {width_m: 0.019}\n  lane: {width_m: 0.5}\n"
                      "  edges: {look_ahead_m: 0.87}\n", encoding="utf-8")
    small = frames / "small.png"
    names = [small, frames / "small2.png", frames / "small3.png"]
    for name in names[1:]:
        name.write_bytes(small.read_bytes())
    code, out, err = run(["detect", *map(str, names), "--config", str(config)], capsys)
    assert code == 2 and out == ""
    (line,) = err.strip().splitlines()
    assert line.startswith(f"lanewarden: error: 3 of 3 images not analysed: {small} and 2 more "
                           "320x240 images: perception.edges.look_ahead_m = 0.87: at 320x240")
    assert line.count("look_ahead_m = 0.87") == 1


@pytest.mark.parametrize(
    ("extra", "code", "expected"),
    [
        (["--config", "{typo}"], 2, "unknown key 'perception.canny.low_treshold'"),
        (["--config", "{nothing}"], 2,
         "Invalid value for '--config': Path '{nothing}' does not exist; expected a config file"),
        (["--calibration", "{nothing}"], 2, "Invalid value for '--calibration': Path '{nothing}' "
         "does not exist; expected a calibration file"),
        (["--out", "{straight}"], 2, "exists and is not a folder"),
    ],
)
def test_bad_options_are_one_line(
    frames: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    extra: list[str],
    code: int,
    expected: str,
) -> None:
    typo = tmp_path / "typo.yaml"
    typo.write_text("perception:\n  canny: {low_treshold: 10}\n")
    names = {
        "typo": str(typo),
        "nothing": str(tmp_path / "nothing.yaml"),
        "straight": str(frames / "straight.png"),
    }
    args = ["detect", str(frames / "straight.png"), *[e.format(**names) for e in extra]]
    got, out, err = run(args, capsys)
    assert got == code
    assert out == ""
    assert expected.format(**names) in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_a_config_the_camera_cannot_resolve_is_refused_before_any_image(
    frames: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 19 mm tape against seams up to 9.5 mm, judged 0.87 m ahead at 640x480 (2.1 mm per
    pixel): the camera cannot tell them apart there; the line names the key and the distance
    that would work, and that distance, set as advised, is accepted."""
    narrow = tmp_path / "narrow-tape.yaml"
    narrow.write_text("perception:\n  tape: {width_m: 0.019}\n  edges: {look_ahead_m: 0.87}\n")
    code, out, err = run(["detect", str(frames / "straight.png"), "--config", str(narrow)],
                         capsys)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert err.startswith("lanewarden: error: perception.edges.look_ahead_m = 0.87: at 640x480 "
                          "one pixel covers 2.1 mm of floor across the tape there")
    assert err.strip().endswith("expected a look-ahead of 0.82 m or less for this camera (set "
                                "perception.edges.look_ahead_m: 0.82 or auto in a --config file, "
                                "or use a higher resolution) (no camera calibration was "
                                "given: judged as the simulator's default camera; give yours, "
                                "e.g. --calibration)")
    narrow.write_text("perception:\n  tape: {width_m: 0.019}\n  edges: {look_ahead_m: 0.82}\n")
    code, out, err = run(["detect", str(frames / "straight.png"), "--config", str(narrow)],
                         capsys)
    assert code == 0 and "640x480: look-ahead 0.82 m (edges.look_ahead_m)" in out


def test_without_a_look_ahead_the_camera_chooses_and_says_which(
    frames: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The same 19 mm tape with no look-ahead configured: `auto` picks the farthest this camera
    tells tape from seam, 0.82 m, and the ground line says so."""
    narrow = tmp_path / "narrow-tape.yaml"
    narrow.write_text("perception:\n  tape: {width_m: 0.019}\n")
    code, out, _ = run(["detect", str(frames / "straight.png"), "--config", str(narrow)],
                       capsys)
    assert code == 0
    assert ("640x480: look-ahead 0.82 m (auto: the farthest where this camera tells tape from "
            "seam); there one pixel covers 2.0 mm") in out.splitlines()[0]


def test_no_images_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run(["detect"], capsys)
    assert code == 2 and "IMAGE" in err


def test_the_ground_line_is_for_the_images_own_size(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 160x120 frame is described at 160x120 (not the default 640x480), once per size."""
    small, large = tmp_path / "small.png", tmp_path / "large.png"
    cv2.imwrite(str(small), syn.render(syn.STRAIGHT, 160, 120))
    cv2.imwrite(str(large), syn.render(syn.STRAIGHT, 640, 480))
    code, out, _ = run(["detect", str(small), str(small), str(large)], capsys)
    assert code == 0
    grounds = [line for line in out.splitlines() if line.startswith("ground model:")]
    assert len(grounds) == 2
    assert "; 160x120: look-ahead" in grounds[0]
    assert "; 640x480: look-ahead" in grounds[1]


def test_a_video_given_to_detect_says_which_commands_read_videos(
    frames: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`detect tub.mp4` said only "not a readable image" (a new user's review); a file named as
    a video now says where videos go. A photo that is not an image still says only that."""
    video = frames.parent / "tub.mp4"
    video.write_bytes(b"\x00\x00\x00\x18ftypmp42" + bytes(64))  # an MP4's first box, no image
    code, out, err = run(["detect", str(video), str(frames / "notes.png")], capsys)
    assert code == 2
    err = err.removeprefix(GROUND_LINE)
    assert err.strip().splitlines() == [
        f"lanewarden: error: 2 of 2 images not analysed: {video}: not a readable image (a "
        "video: `lanewarden replay` and `lanewarden survey --labels FILE` read videos, "
        f"`lanewarden run --camera` plays one); {frames / 'notes.png'}: not a readable image"]


def test_annotated_images_on_a_full_disk_are_one_short_line(
        small_disk: Path, frames: Path, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """cv2.imwrite answers a full disk with False (and libpng prints "libpng error: Write
    Error"): the line said "cannot write image" with no reason, once per image, every one of
    338 real frames in one line. Now the first with its reason, and how many more."""
    images = []
    for k in range(12):
        images.append(tmp_path / f"frame_{k:02d}.png")
        images[-1].write_bytes((frames / "small.png").read_bytes())
    out = small_disk / "annotated"
    code = main(["detect", *map(str, images), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 1
    last = err.splitlines()[-1]
    found = re.fullmatch(rf"lanewarden: error: {re.escape(str(out))}/frame_(\d\d)_detect\.png: "
                         r"cannot write image \(No space left on device\); (\d+) more annotated "
                         r"images? not written", last)
    assert found is not None, last
    first, more = int(found[1]), int(found[2])
    assert first + 1 + more == 12  # every image from the first that failed on
    assert "libpng" not in err


def test_a_link_to_nothing_says_so(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A photo listed in its folder but linked to a file that is gone had read 'no such file'
    (a new user's review)."""
    link = tmp_path / "shot.jpg"
    link.symlink_to("gone.jpg")
    code, _, err = run(["detect", str(link)], capsys)
    assert code == 2
    assert err.splitlines()[-1] == (f"lanewarden: error: 1 of 1 images not analysed: {link}: a "
                                    "link to 'gone.jpg', which does not exist")
