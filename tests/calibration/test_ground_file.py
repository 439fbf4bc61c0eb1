"""The ground pose in the calibration file: round trips, old files, bad keys, ROS output, and the
one line saying which ground model perception uses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from lanewarden.perception.calibration import (
    CameraCalibration,
    GroundCalibration,
    load_calibration,
    save_calibration,
    save_ros_camera_info,
)
from lanewarden.perception.errors import PerceptionError
from lanewarden.perception.ground import CameraPose, ground_model_for

K = np.array([[457.0, 0.0, 320.0], [0.0, 457.0, 240.0], [0.0, 0.0, 1.0]])
POSE = CameraPose(height_m=0.26, pitch_deg=40.0, roll_deg=-1.5, yaw_deg=2.0, forward_m=0.12,
                  lateral_m=-0.01)
GROUND = GroundCalibration(pose=POSE, method="from a floor chessboard (9x6, 0.03 m squares)",
                           reprojection_error_m=0.0012, date="2025-01-02T03:04:05+00:00")


def calibration(ground: GroundCalibration | None = GROUND) -> CameraCalibration:
    return CameraCalibration(camera_matrix=K, dist_coeffs=np.array([-0.2, 0.05, 0, 0, 0]),
                             image_size=(640, 480), rms=0.2, views_used=15, ground=ground)


def test_ground_pose_round_trips_through_the_opencv_file(tmp_path: Path) -> None:
    path = tmp_path / "camera.yaml"
    save_calibration(calibration(), path)
    text = path.read_text()
    for key in ("ground_height_m", "ground_pitch_deg", "ground_roll_deg", "ground_yaw_deg",
                "ground_forward_m", "ground_lateral_m", "ground_method",
                "ground_reprojection_error_m", "ground_date"):
        assert key in text
    loaded = load_calibration(path)
    assert loaded.ground == GROUND
    np.testing.assert_array_equal(loaded.camera_matrix, K)


def test_a_file_without_a_ground_pose_still_loads(tmp_path: Path) -> None:
    path = tmp_path / "camera.yaml"
    save_calibration(calibration(ground=None), path)
    assert "ground_" not in path.read_text()
    assert load_calibration(path).ground is None


def test_ros_camera_info_carries_the_ground_pose_as_extra_keys(tmp_path: Path) -> None:
    path = tmp_path / "camera.ros.yaml"
    save_ros_camera_info(calibration(), path)
    data = yaml.safe_load(path.read_text())
    assert data["ground_height_m"] == 0.26 and data["ground_pitch_deg"] == 40.0
    assert data["distortion_model"] == "plumb_bob"  # the ROS layout is untouched
    assert load_calibration(path).ground == GROUND


def _with_keys(tmp_path: Path, extra: str) -> Path:
    path = tmp_path / "camera.yaml"
    save_calibration(calibration(ground=None), path)
    path.write_text(path.read_text() + extra)
    return path


@pytest.mark.parametrize(("extra", "message"), [
    ("ground_height_m: 0.3\n", "node 'ground_pitch_deg' is missing"),
    ("ground_pitch_deg: 30.0\n", "node 'ground_height_m' is missing"),
    ("ground_height_m: -0.3\nground_pitch_deg: 30.0\n", "ground_height_m -0.3 must be at least"),
    # a camera on the floor itself: the floor region was then said to be out of view, naming
    # perception.roi and not the file (an attacker's review)
    ("ground_height_m: 1e-9\nground_pitch_deg: 30.0\n",
     "ground_height_m 1e-09 must be at least 0.02 m above the floor and within 10 m of it "
     "(0.02 <= value <= 10)"),
    ("ground_height_m: 0.3\nground_pitch_deg: 130.0\n", "ground_pitch_deg 130 must be within"),
    # a mount no robot has (1e308 had overflowed the floor model into NumPy warnings)
    ("ground_height_m: 1e308\nground_pitch_deg: 30.0\n",
     "ground_height_m 1e+308 must be at least 0.02 m above the floor and within 10 m of it"),
    ("ground_height_m: 0.3\nground_pitch_deg: 30.0\nground_forward_m: -40.0\n",
     "ground_forward_m -40 must be within 10 m of the robot's centre"),
    ("ground_height_m: 0.3\nground_pitch_deg: 30.0\nground_yaw_deg: 720.0\n",
     "ground_yaw_deg 720 must be within -180..180"),
    # upside down: the start-up check had said "no distance in view (3.10 m on) tells the 48 mm
    # tape from seams ...; expected a higher resolution, a narrower lens, ..."
    ("ground_height_m: 0.3\nground_pitch_deg: 30.0\nground_roll_deg: 180.0\n",
     "ground_roll_deg 180 must be within -90..90 (a camera rolled further is upside down"),
    ("ground_height_m: high\nground_pitch_deg: 30.0\n", "node 'ground_height_m' is not a number"),
    # a misspelt pose key had been passed over: the camera taken as not rolled, not offset
    ("ground_height_m: 0.3\nground_pitch_deg: 30.0\nground_roll_degs: 5.0\n",
     "unknown node 'ground_roll_degs': did you mean 'ground_roll_deg'?"),
    ("ground_height_m: 0.3\nground_pitch_deg: 30.0\nground_forward: 0.12\n",
     "unknown node 'ground_forward': did you mean 'ground_forward_m'?"),
    ("ground_height_m: 0.3\nground_pitch_deg: 30.0\nground_reprojection_error_m: -1.0\n",
     "ground_reprojection_error_m -1.0 must be"),
])
def test_bad_ground_keys_name_the_file_and_the_key(tmp_path: Path, extra: str,
                                                   message: str) -> None:
    path = _with_keys(tmp_path, extra)
    with pytest.raises(PerceptionError) as raised:
        load_calibration(path)
    assert str(raised.value).startswith(f"{path}: ")
    assert message in str(raised.value)


def test_roll_yaw_and_offsets_default_to_zero(tmp_path: Path) -> None:
    path = _with_keys(tmp_path, "ground_height_m: 0.3\nground_pitch_deg: 30.0\n")
    ground = load_calibration(path).ground
    assert ground == GroundCalibration(pose=CameraPose(height_m=0.3, pitch_deg=30.0))


def test_which_ground_model_is_used_is_said_in_one_line() -> None:
    model, line = ground_model_for(calibration(), (640, 480), "camera.yaml")
    assert model.pose == POSE
    np.testing.assert_array_equal(model.camera_matrix, K)
    assert line == ("ground calibration from camera.yaml: h 0.260 m, pitch 40.0°, roll -1.5°, "
                    "yaw +2.0°, 0.120 m ahead of the robot's centre, -0.010 m to its left, "
                    "from a floor chessboard (9x6, 0.03 m squares)")

    model, line = ground_model_for(None, (320, 240))
    assert model.pose == CameraPose(height_m=0.40, pitch_deg=35.0, forward_m=0.15)
    assert model.image_size == (320, 240)
    assert line == ("no ground calibration: assuming the simulator's default camera (70° HFOV, "
                    "h 0.400 m, pitch 35.0°, 0.150 m ahead of the robot's centre)")

    model, line = ground_model_for(calibration(ground=None), (640, 480), "camera.yaml")
    np.testing.assert_array_equal(model.camera_matrix, K)
    assert model.pose == CameraPose(height_m=0.40, pitch_deg=35.0, forward_m=0.15)
    assert line.startswith("no ground calibration in the calibration from camera.yaml: "
                           "assuming the simulator's default mount (h 0.400 m, pitch 35.0°")


def test_the_ground_model_follows_the_frame_size() -> None:
    model, _ = ground_model_for(calibration(), (320, 240))
    assert model.image_size == (320, 240)
    assert model.camera_matrix[0, 0] == pytest.approx(228.5)
    assert model.pose == POSE
