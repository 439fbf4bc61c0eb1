"""run.mcap is a ROS 2 recording other tools open: read back by a different library than the one
that wrote it (rosbags, with its own MCAP reader and CDR decoder, from the schemas the file
carries), it has the image, Twist, feedback and step channels with the right message types,
encodings, counts and offered QoS, and their contents are what the run did; the `mcap` library
finds its summary section (statistics, chunk indexes), meta, config, summary and the image
channel's description. Its frames (perception's prepared input by default, the camera's gray
frames with --record-gray) replay a run that saw colour frames through a distorting lens
exactly."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader
from rosbags.interfaces import QosDurability, QosHistory, QosReliability

from lanewarden.cli import main
from lanewarden.config import LanewardenConfig
from lanewarden.perception.calibration import Undistorter, save_calibration
from lanewarden.perception.detector import LaneDetector, PreparedImage, perception_gray
from lanewarden.run_mcap import CAMERA_GRAY, PERCEPTION_INPUT
from lanewarden.scenarios.camera import CameraModel
from tests.operator.clips import lane_end_frames
from tests.operator.recordings import record_run

PERCEPTION_TOPIC = "/lanewarden/perception_input/compressed"


@pytest.fixture(scope="module")
def clip() -> list[np.ndarray]:
    return lane_end_frames(start_m=2.2, end_m=3.3, speed_m_s=0.6)


def test_rosbags_reads_what_the_mcap_libraries_wrote(clip: list[np.ndarray],
                                                     tmp_path: Path) -> None:
    run = tmp_path / "run"
    records = record_run(run, clip, LanewardenConfig(), stop_at_step=20)
    with AnyReader([run / "run.mcap"]) as reader:
        topics = {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
        assert topics == {
            PERCEPTION_TOPIC: ("sensor_msgs/msg/CompressedImage", len(clip)),
            "/cmd_vel": ("geometry_msgs/msg/Twist", len(records)),
            "/lanewarden/step": ("lanewarden_msgs/msg/Step", len(records)),
            "/lanewarden/base_feedback": ("lanewarden_msgs/msg/BaseFeedback", len(records)),
        }
        assert {c.ext.serialization_format for c in reader.connections} == {"cdr"}
        for connection in reader.connections:  # rosbags parses rosbag2's QoS YAML
            (qos,) = connection.ext.offered_qos_profiles
            assert (qos.history, qos.depth, qos.reliability, qos.durability) == (
                QosHistory.KEEP_LAST, 10, QosReliability.RELIABLE, QosDurability.VOLATILE)
        seen: dict[str, list[object]] = {topic: [] for topic in topics}
        for connection, _, raw in reader.messages():
            seen[connection.topic].append(reader.deserialize(raw, connection.msgtype))
    steps = seen["/lanewarden/step"]
    assert [s.state for s in steps] == [r.state for r in records]
    assert [list(s.events) for s in steps] == [list(r.events) for r in records]
    assert [s.halt_reason or None for s in steps] == [r.halt_reason for r in records]
    assert [(t.linear.x, t.angular.z) for t in seen["/cmd_vel"]] == [
        (r.command.linear_m_s, r.command.angular_rad_s) for r in records]
    confident = [r for r in records if r.observation is not None]
    assert [s.confidence for s in steps if not np.isnan(s.confidence)] == [
        r.observation.confidence for r in confident if r.observation is not None]
    first = seen[PERCEPTION_TOPIC][0]
    assert first.format == "mono8; png compressed" and first.header.frame_id == "camera"
    image = cv2.imdecode(np.frombuffer(first.data, np.uint8), cv2.IMREAD_UNCHANGED)
    prepared = LaneDetector(LanewardenConfig().perception).prepare(clip[0])
    assert np.array_equal(image, prepared), "what the detector consumed, bit for bit"
    assert not np.array_equal(image, perception_gray(clip[0])), "blurred: not the camera's gray"
    assert first.header.stamp.sec == 1_700_001_000  # the frame's time on the wall clock


def test_the_mcap_library_finds_the_summary_section(clip: list[np.ndarray],
                                                    tmp_path: Path) -> None:
    run = tmp_path / "run"
    records = record_run(run, clip[:12], LanewardenConfig())
    with (run / "run.mcap").open("rb") as stream:
        reader = make_reader(stream)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        counts = {summary.channels[c].topic: n
                  for c, n in summary.statistics.channel_message_counts.items()}
        assert counts[PERCEPTION_TOPIC] == 12 and counts["/cmd_vel"] == len(records)
        assert len(summary.chunk_indexes) >= 2, "chunked, with chunk indexes"
        assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
        channels = {c.topic: c.metadata for c in summary.channels.values()}
        for metadata in channels.values():  # rosbag2's key, YAML as rosbag2 writes it
            assert yaml.safe_load(metadata["offered_qos_profiles"]) == [{
                "history": 1, "depth": 10, "reliability": 1, "durability": 2,
                "deadline": {"sec": 9223372036, "nsec": 854775807},
                "lifespan": {"sec": 9223372036, "nsec": 854775807}, "liveliness": 1,
                "liveliness_lease_duration": {"sec": 9223372036, "nsec": 854775807},
                "avoid_ros_namespace_conventions": False}]
        assert channels[PERCEPTION_TOPIC]["lanewarden.image"].startswith(
            "perception input: the camera frame's gray version, undistorted, blurred, before "
            "contrast normalisation")
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        meta = json.loads(metadata["lanewarden"]["meta"])
        assert (meta["format"], meta["image"], meta["frames"]) == (
            3, PERCEPTION_INPUT, PERCEPTION_TOPIC)
        assert json.loads(metadata["lanewarden.summary"]["summary"])["steps"] == len(records)
        assert [a.name for a in reader.iter_attachments()] == ["config.yaml"]


@pytest.mark.parametrize("image_kind", [PERCEPTION_INPUT, CAMERA_GRAY])
def test_frames_replay_a_calibrated_colour_run_exactly(
        image_kind: str, clip: list[np.ndarray], tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    camera = CameraModel(width_px=320, height_px=240)
    calibration = camera.calibration()
    assert np.any(calibration.dist_coeffs), "a lens that distorts: frames are remapped"
    path = tmp_path / "camera.yaml"
    save_calibration(calibration, path)
    detector = LaneDetector(LanewardenConfig().perception, Undistorter(calibration))
    for k in (0, 9, 17):
        colour = detector.detect(clip[k], k, 0.0)
        assert detector.detect(perception_gray(clip[k]), k, 0.0) == colour
        prepared = detector.prepare(clip[k])
        assert isinstance(prepared, PreparedImage) and prepared.shape == (240, 320)
        assert detector.detect(prepared, k, 0.0) == colour
    config = LanewardenConfig()
    run = tmp_path / "run"
    records = record_run(run, clip, config, calibration=path, loaded_calibration=calibration,
                         image_kind=image_kind)
    assert len({r.state for r in records}) > 1
    code = main(["replay", str(run), "--check", "--no-video", "--out", str(tmp_path / "out")])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "config: recorded" in out and f"reproduced: all {len(records)} steps" in out
