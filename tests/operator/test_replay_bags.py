"""`lanewarden replay BAG [--topic NAME]`: a ROS 2 user's bag, written here at test time by other
libraries (rosbags' rosbag2 writer, MCAP and SQLite storage; Foxglove's mcap-ros2-support), with
sensor_msgs/msg/Image or CompressedImage frames of a rendered lane: the same outputs as a video
replay, timed by the images' header stamps, the very observations the same frames give from a
folder of images; and the bag's own problems (several image topics, none, stamps that go back or
span days) are one line."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from mcap_ros2.writer import Writer as Ros2McapWriter
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from lanewarden.cli import main
from lanewarden.run_mcap import COMPRESSED_IMAGE_DEF, IMAGE_DEF, TWIST_DEF
from tests.operator.clips import CLIP_FPS, lane_end_frames, write_images

OUTPUTS = ("video.mp4", "poster.jpg", "plot.png", "metrics.json", "run.jsonl", "report.html")
STORE = get_typestore(Stores.ROS2_HUMBLE)
EPOCH_NS = 1_790_000_000 * 10**9  # stamps in 2026, as a robot's clock gives them
PERIOD_NS = round(1e9 / CLIP_FPS)


@pytest.fixture(scope="module")
def frames() -> list[np.ndarray]:
    return lane_end_frames(start_m=2.0, end_m=3.5, speed_m_s=0.6)


def _header(i: int) -> Any:
    stamp = EPOCH_NS + i * PERIOD_NS
    return STORE.types["std_msgs/msg/Header"](
        stamp=STORE.types["builtin_interfaces/msg/Time"](sec=stamp // 10**9,
                                                         nanosec=stamp % 10**9),
        frame_id="camera")


def _raw_rgb(i: int, frame: np.ndarray) -> Any:
    rgb = np.ascontiguousarray(frame[:, :, ::-1])
    return STORE.types["sensor_msgs/msg/Image"](
        header=_header(i), height=rgb.shape[0], width=rgb.shape[1], encoding="rgb8",
        is_bigendian=0, step=rgb.shape[1] * 3, data=rgb.reshape(-1))


def _compressed(i: int, frame: np.ndarray) -> Any:
    return STORE.types["sensor_msgs/msg/CompressedImage"](
        header=_header(i), format="png",
        data=np.frombuffer(cv2.imencode(".png", frame)[1].tobytes(), np.uint8))


def write_rosbag2(folder: Path, frames: list[np.ndarray], storage: StoragePlugin,
                  kind: str) -> Path:
    """A rosbag2 folder as `ros2 bag record` leaves it: metadata.yaml + one storage file, the
    camera topic and /cmd_vel; log times 40 ms after the stamps (the transport's delay)."""
    make, topic, msgtype = ((_raw_rgb, "/camera/image_raw", "sensor_msgs/msg/Image")
                            if kind == "raw" else
                            (_compressed, "/camera/image_raw/compressed",
                             "sensor_msgs/msg/CompressedImage"))
    twist = STORE.types["geometry_msgs/msg/Twist"]
    vector = STORE.types["geometry_msgs/msg/Vector3"]
    with Writer(folder, version=9, storage_plugin=storage) as writer:
        camera = writer.add_connection(topic, msgtype, typestore=STORE)
        cmd_vel = writer.add_connection("/cmd_vel", "geometry_msgs/msg/Twist", typestore=STORE)
        for i, frame in enumerate(frames):
            logged = EPOCH_NS + i * PERIOD_NS + 40_000_000
            writer.write(camera, logged, STORE.serialize_cdr(make(i, frame), msgtype))
            writer.write(cmd_vel, logged, STORE.serialize_cdr(
                twist(linear=vector(x=0.1, y=0.0, z=0.0), angular=vector(x=0.0, y=0.0, z=0.0)),
                "geometry_msgs/msg/Twist"))
    return folder


def _observations(out: Path) -> list[tuple[object, object]]:
    lines = [json.loads(line) for line in (out / "run.jsonl").read_text().splitlines()]
    return [(line["observation"]["slope_sum"], line["observation"]["confidence"])
            for line in lines if line["observation"] is not None]


def test_a_rosbag2_mcap_bag_replays_like_a_video(frames: list[np.ndarray], tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_rosbag2(tmp_path / "bag", frames, StoragePlugin.MCAP, "compressed")
    code = main(["replay", str(bag), "--out", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "topic /camera/image_raw/compressed, timed by its header stamps" in out
    for name in OUTPUTS:
        assert (tmp_path / "out" / name).stat().st_size > 0, name
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert (metrics["source_kind"], metrics["frames"]) == ("bag", len(frames))
    assert metrics["sim_time_s"] == pytest.approx((len(frames) - 1) * PERIOD_NS / 1e9, abs=1e-6)
    assert metrics["halted"] is True
    # the same frames from a folder of images: the very same observations, frame by frame
    images = write_images(frames, tmp_path / "images")
    assert main(["replay", str(images), "--no-video", "--out", str(tmp_path / "img")]) == 0
    capsys.readouterr()
    assert _observations(tmp_path / "out") == _observations(tmp_path / "img")


def test_a_sqlite_bag_of_raw_rgb_images(frames: list[np.ndarray], tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    """ROS 2 Humble's default storage (.db3, no message definitions inside) and raw rgb8."""
    bag = write_rosbag2(tmp_path / "bag", frames[:30], StoragePlugin.SQLITE3, "raw")
    assert main(["replay", str(bag), "--no-video", "--out", str(tmp_path / "out")]) == 0
    capsys.readouterr()
    images = write_images(frames[:30], tmp_path / "images")
    assert main(["replay", str(images), "--no-video", "--out", str(tmp_path / "img")]) == 0
    capsys.readouterr()
    observations = _observations(tmp_path / "out")
    assert len(observations) == 30 and observations == _observations(tmp_path / "img")
    # the .db3 file on its own is the same bag
    (db3,) = bag.glob("*.db3")
    assert main(["replay", str(db3), "--no-video", "--out", str(tmp_path / "db3")]) == 0
    assert _observations(tmp_path / "db3") == observations


def _two_camera_mcap(path: Path, frames: list[np.ndarray]) -> Path:
    """A bare .mcap by Foxglove's ROS 2 writer: two image topics and /cmd_vel."""
    with path.open("wb") as stream:
        writer = Ros2McapWriter(stream)
        compressed = writer.register_msgdef("sensor_msgs/msg/CompressedImage",
                                            COMPRESSED_IMAGE_DEF)
        raw = writer.register_msgdef("sensor_msgs/msg/Image", IMAGE_DEF)
        twist = writer.register_msgdef("geometry_msgs/msg/Twist", TWIST_DEF)
        for i, frame in enumerate(frames):
            stamp = EPOCH_NS + i * PERIOD_NS
            header = {"stamp": {"sec": stamp // 10**9, "nanosec": stamp % 10**9},
                      "frame_id": "front"}
            writer.write_message("/front/compressed", compressed, {
                "header": header, "format": "jpeg",
                "data": cv2.imencode(".jpg", frame)[1].tobytes()}, log_time=stamp)
            writer.write_message("/rear/image", raw, {
                "header": header, "height": frame.shape[0], "width": frame.shape[1],
                "encoding": "bgr8", "is_bigendian": 0, "step": frame.shape[1] * 3,
                "data": frame.tobytes()}, log_time=stamp)
            writer.write_message("/cmd_vel", twist, {}, log_time=stamp)
        writer.finish()
    return path


def test_several_image_topics_need_topic(frames: list[np.ndarray], tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    bag = _two_camera_mcap(tmp_path / "cameras.mcap", frames[:10])
    code = main(["replay", str(bag), "--no-video", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert ("several image topics, choose one with --topic: /front/compressed "
            "(CompressedImage, 10 images), /rear/image (Image, 10 images)") in err
    code = main(["replay", str(bag), "--topic", "/cmd_vel", "--no-video", "--out",
                 str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "--topic /cmd_vel: is geometry_msgs/msg/Twist, not an image topic" in err
    # a topic the bag does not have: the bag's image topics listed (it had said "none", since
    # only the named topic had been read)
    code = main(["replay", str(bag), "--topic", "/nope", "--no-video", "--out",
                 str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert err.strip().endswith(f"--topic /nope: has no images in {bag}; image topics: "
                                "/front/compressed (CompressedImage), /rear/image (Image)"), err
    assert main(["replay", str(bag), "--topic", "/rear/image", "--no-video", "--out",
                 str(tmp_path / "rear")]) == 0
    metrics = json.loads((tmp_path / "rear" / "metrics.json").read_text())
    assert (metrics["source_kind"], metrics["frames"]) == ("bag", 10)


def test_stamps_that_go_back_or_span_days_are_refused(frames: list[np.ndarray], tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    for name, stamps in (("back", [0, 2, 1]), ("days", [0, 1, 200_000])):
        path = tmp_path / f"{name}.mcap"
        with path.open("wb") as stream:
            writer = Ros2McapWriter(stream)
            schema = writer.register_msgdef("sensor_msgs/msg/CompressedImage",
                                            COMPRESSED_IMAGE_DEF)
            for i, sec in enumerate(stamps):
                writer.write_message("/camera", schema, {
                    "header": {"stamp": {"sec": 1_790_000_000 + sec, "nanosec": 0}},
                    "format": "png", "data": cv2.imencode(".png", frames[i])[1].tobytes()},
                    log_time=i)
            writer.finish()
        code = main(["replay", str(path), "--no-video", "--out", str(tmp_path / "out")])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
        # the frame counted from 0, as frames_undecoded and the undecodable frames' line
        # count them (it had said "image 3", counted from 1)
        assert {"back": "/camera: frame 2 (counted from 0) is at 1790000001.0 s, not after "
                "frame 1 (1790000002.0 s); times must increase",
                "days": "spans 200000 s, more than"}[name] in err


def test_no_image_topic_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "cmd.mcap"
    with path.open("wb") as stream:
        writer = Ros2McapWriter(stream)
        twist = writer.register_msgdef("geometry_msgs/msg/Twist", TWIST_DEF)
        writer.write_message("/cmd_vel", twist, {}, log_time=1)
        writer.finish()
    code = main(["replay", str(path), "--no-video", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "no sensor_msgs/msg/Image or CompressedImage messages (topics: /cmd_vel)" in err


def test_a_bag_cut_short_replays_what_it_has_and_says_so(
        frames: list[np.ndarray], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """An .mcap bag cut in half (`ros2 bag record` killed, a full disk, half a copy) replays
    the images before the cut and says the bag is incomplete, in metrics.json too, and
    `--check` refuses it; one cut before its first image (0, 5 or 100 bytes left) says so. Both
    had replayed what there was with exit 0 and no word, or called the bag one without images
    ("topics: none")."""
    whole = tmp_path / "whole.mcap"
    with whole.open("wb") as stream:
        writer = Ros2McapWriter(stream, chunk_size=64 * 1024)  # a chunk every frame or two
        schema = writer.register_msgdef("sensor_msgs/msg/CompressedImage", COMPRESSED_IMAGE_DEF)
        for i, frame in enumerate(frames[:20]):
            stamp = EPOCH_NS + i * PERIOD_NS
            writer.write_message("/camera", schema, {
                "header": {"stamp": {"sec": stamp // 10**9, "nanosec": stamp % 10**9}},
                "format": "png", "data": cv2.imencode(".png", frame)[1].tobytes()},
                log_time=stamp)
        writer.finish()
    data = whole.read_bytes()
    half = tmp_path / "half.mcap"
    half.write_bytes(data[: len(data) // 2])
    out = tmp_path / "out"
    assert main(["replay", str(half), "--no-video", "--out", str(out)]) == 0
    stdout = capsys.readouterr().out
    metrics = json.loads((out / "metrics.json").read_text())
    assert 0 < metrics["steps"] < 20
    assert f"the recording is incomplete: half.mcap was cut short after {metrics['steps']} " \
        f"images on /camera (it ends at byte {len(data) // 2} inside a record" in stdout, stdout
    assert len(metrics["incomplete"]) == 1 and "cut short" in metrics["incomplete"][0]
    code = main(["replay", str(half), "--no-video", "--out", str(out), "--check"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    # (a bag has no recorded steps to compare with: refused before the work, as any source
    # that is not a recorded run is)
    assert err == (f"lanewarden: error: --check: {half} is a ROS bag, not a recorded run: there "
                   "is nothing to compare with\n")
    for size, what in ((0, "empty (0 bytes)"),
                       (5, "cut short before any image (it ends at byte 5, before MCAP's "
                        "first record)"),
                       (100, "cut short before any image (it ends at byte 100 inside a record "
                        "that starts at byte 70)")):
        stub = tmp_path / f"stub{size}.mcap"
        stub.write_bytes(data[:size])
        code = main(["replay", str(stub), "--no-video", "--out", str(tmp_path / "o")])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1, err
        assert f"{stub}: {what}; a recording killed at its start, or its disk full?" in err, err


@pytest.mark.parametrize("count", [1, 3])
def test_a_bag_of_which_no_image_decodes_is_one_line(tmp_path: Path, count: int) -> None:
    """A CompressedImage whose data is not a picture (a PNG signature, then garbage), the bag's
    only image or all three: bad input in one line. Run as a user runs it, so that nothing else
    reaches stderr: OpenCV's own message for each frame it cannot decode, and matplotlib's
    warning about a plot of one step, had added lines to it."""
    import subprocess
    import sys

    msgtype = "sensor_msgs/msg/CompressedImage"
    bag = tmp_path / "bag"
    with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        camera = writer.add_connection("/camera/image_raw/compressed", msgtype, typestore=STORE)
        for i in range(count):
            message = STORE.types[msgtype](
                header=_header(i), format="png",
                data=np.frombuffer(b"\x89PNG\r\n\x1a\n" + b"garbage" * 10, np.uint8))
            writer.write(camera, EPOCH_NS + i * PERIOD_NS, STORE.serialize_cdr(message, msgtype))
    done = subprocess.run([sys.executable, "-m", "lanewarden", "replay", str(bag), "--no-video",
                           "--out", str(tmp_path / "out")], capture_output=True, text=True,
                          timeout=120)
    what = ("its only frame could not be decoded" if count == 1
            else "none of its 3 frames could be decoded")
    assert done.returncode == 2, done.stderr
    assert done.stderr.splitlines() == [
        f"lanewarden: error: SOURCE '{bag}': {what} (a damaged or cut file?)"]
    assert f"bag (bag, config: defaults): {count} step{'s' if count > 1 else ''}, 0 frames" in (
        done.stdout)


def test_a_message_and_its_frame_have_one_number(frames: list[np.ndarray], tmp_path: Path,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """The bag's fourth image is frame 3 in every line, counted from 0 as docs/operator.md says
    (`frame 3` when it does not decode); a problem with its message had named it "/camera
    message 4", counted from 1."""
    lines = {}
    for damage in ("data", "stamp"):
        path = tmp_path / f"{damage}.mcap"
        with path.open("wb") as stream:
            writer = Ros2McapWriter(stream)
            schema = writer.register_msgdef("sensor_msgs/msg/CompressedImage",
                                            COMPRESSED_IMAGE_DEF)
            for i in range(6):
                stamp = EPOCH_NS + i * PERIOD_NS
                nanosec = 2_000_000_000 if (damage, i) == ("stamp", 3) else stamp % 10**9
                data = (b"\x89PNG\r\n\x1a\n" + b"garbage" * 10 if (damage, i) == ("data", 3)
                        else cv2.imencode(".png", frames[i])[1].tobytes())
                writer.write_message("/camera", schema, {
                    "header": {"stamp": {"sec": stamp // 10**9, "nanosec": nanosec}},
                    "format": "png", "data": data}, log_time=stamp)
            writer.finish()
        code = main(["replay", str(path), "--no-video", "--out", str(tmp_path / damage)])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
        lines[damage] = err
    assert "1 of its 6 frames could not be decoded (counted from 0): frame 3 " in lines["data"]
    assert lines["stamp"] == (f"lanewarden: error: {tmp_path / 'stamp.mcap'}: /camera message 3 "
                              "(counted from 0): header.stamp.nanosec = 2000000000: expected 0 "
                              "to 999999999\n")


def test_one_listing_of_image_topics_serves_both_lines() -> None:
    """`_candidates` lists the image topics for both one-line errors: with their image counts
    when there are several, with their types only when --topic names another (only that topic
    was read); it had been written out twice."""
    from lanewarden.replay_sources import _candidates
    from lanewarden.ros_bag import BagTopic

    topics = {name: BagTopic(name, kind, "cdr") for name, kind in (
        ("/rear/image", "sensor_msgs/msg/Image"),
        ("/front/compressed", "sensor_msgs/msg/CompressedImage"),
        ("/cmd_vel", "geometry_msgs/msg/Twist"))}
    assert _candidates(topics, {"/rear/image": [0.0, 0.1], "/front/compressed": [0.0]}) == (
        "/front/compressed (CompressedImage, 1 images), /rear/image (Image, 2 images)")
    assert _candidates(topics) == "/front/compressed (CompressedImage), /rear/image (Image)"
    assert _candidates({"/cmd_vel": topics["/cmd_vel"]}) == "none"
    assert _candidates(topics, {}) == "none"
