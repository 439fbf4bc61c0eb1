"""The ground model: floor <-> image in metres, horizon and pixel size, against worked cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lanewarden.perception.ground import (
    CameraPose,
    GroundModel,
    camera_matrix_for_fov,
    default_ground_model,
)

K_640 = np.array([[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]])


def test_a_level_camera_sees_the_horizon_through_its_principal_point() -> None:
    model = GroundModel(K_640, CameraPose(height_m=0.5, pitch_deg=0.0), (640, 480))
    assert model.horizon_v() == pytest.approx(240.0)
    # a floor point 2 m ahead is 0.5 m below the axis: v = cy + f * 0.5 / 2
    u, v = model.pixel_at(2.0, 0.0)
    assert (u, v) == pytest.approx((320.0, 240.0 + 500.0 * 0.25))
    # 0.4 m to the LEFT appears left of centre
    u_left, _ = model.pixel_at(2.0, 0.4)
    assert u_left == pytest.approx(320.0 - 500.0 * 0.2)


def test_pitch_down_moves_the_horizon_up_by_f_tan_pitch() -> None:
    model = GroundModel(K_640, CameraPose(height_m=0.4, pitch_deg=30.0), (640, 480))
    assert model.horizon_v() == pytest.approx(240.0 - 500.0 * math.tan(math.radians(30.0)))
    # the principal point looks at the floor h / tan(pitch) ahead of the camera
    x, y = model.image_to_floor(np.array([[320.0, 240.0]]))[0]
    assert x == pytest.approx(0.4 / math.tan(math.radians(30.0)))
    assert y == pytest.approx(0.0, abs=1e-12)


def test_camera_position_shifts_the_floor_it_sees() -> None:
    pose = CameraPose(height_m=0.4, pitch_deg=30.0, forward_m=0.15, lateral_m=0.05)
    model = GroundModel(K_640, pose, (640, 480))
    x, y = model.image_to_floor(np.array([[320.0, 240.0]]))[0]
    assert x == pytest.approx(0.15 + 0.4 / math.tan(math.radians(30.0)))
    assert y == pytest.approx(0.05)


def test_floor_and_image_round_trip_and_the_sky_has_no_floor() -> None:
    pose = CameraPose(height_m=0.3, pitch_deg=40.0, roll_deg=3.0, yaw_deg=-5.0, forward_m=0.1)
    model = GroundModel(K_640, pose, (640, 480))
    floor = np.array([[0.6, 0.0], [1.0, 0.3], [0.8, -0.25], [2.5, 0.1]])
    back = model.image_to_floor(model.floor_to_image(floor))
    np.testing.assert_allclose(back, floor, atol=1e-9)
    above = model.horizon_v(320.0) - 5.0
    assert np.all(np.isnan(model.image_to_floor(np.array([[320.0, above]]))))
    # behind the camera: no pixel
    assert np.all(np.isnan(model.floor_to_image(np.array([[-1.0, 0.0]]))))


def test_roll_left_side_up_tilts_the_horizon() -> None:
    level = GroundModel(K_640, CameraPose(height_m=0.4, pitch_deg=20.0), (640, 480))
    rolled = GroundModel(K_640, CameraPose(height_m=0.4, pitch_deg=20.0, roll_deg=5.0),
                         (640, 480))
    assert level.horizon_v(0.0) == pytest.approx(level.horizon_v(640.0))
    # left side up: the world turns clockwise in the image, so the horizon's left end drops
    assert rolled.horizon_v(0.0) > rolled.horizon_v(640.0)
    slope = (rolled.horizon_v(640.0) - rolled.horizon_v(0.0)) / 640.0
    assert slope == pytest.approx(-math.tan(math.radians(5.0)), rel=1e-6)


def test_yaw_left_moves_the_floor_straight_ahead_to_the_right_of_the_image() -> None:
    model = GroundModel(K_640, CameraPose(height_m=0.4, pitch_deg=30.0, yaw_deg=10.0),
                        (640, 480))
    u, _ = model.pixel_at(1.0, 0.0)
    assert u > 320.0


def test_pixel_size_on_the_floor_follows_distance() -> None:
    # level camera: at distance d a pixel across covers d / f metres (d along the optical axis)
    model = GroundModel(K_640, CameraPose(height_m=0.5, pitch_deg=0.0), (640, 480))
    _, v = model.pixel_at(2.0, 0.0)
    assert model.metres_per_px_across(320.0, v) == pytest.approx(2.0 / 500.0, rel=1e-6)
    assert model.row_at_distance(2.0) == pytest.approx(v)
    assert model.distance_at_row(v) == pytest.approx(2.0)
    # along the column the floor is foreshortened: d^2 / (f h) per pixel
    assert model.metres_per_px_along(320.0, v) == pytest.approx(4.0 / (500.0 * 0.5), rel=1e-3)
    assert math.isnan(model.metres_per_px_across(320.0, 100.0))  # above the horizon


def test_scaling_the_image_keeps_the_floor() -> None:
    pose = CameraPose(height_m=0.4, pitch_deg=35.0, forward_m=0.15)
    big = GroundModel.from_fov(70.0, (640, 480), pose)
    small = big.scaled_to((320, 240))
    u, v = big.pixel_at(1.0, 0.2)
    assert small.pixel_at(1.0, 0.2) == pytest.approx((u / 2.0, v / 2.0))
    assert small.metres_per_px_across(u / 2, v / 2) == pytest.approx(
        2.0 * big.metres_per_px_across(u, v), rel=1e-3)


def test_fov_gives_the_pinhole_focal_length() -> None:
    k = camera_matrix_for_fov(90.0, (640, 480))
    assert k[0, 0] == pytest.approx(320.0)
    assert (k[0, 2], k[1, 2]) == (320.0, 240.0)


@pytest.mark.parametrize("bad", [
    dict(camera_matrix=np.diag([0.0, 500.0, 1.0]), pose=CameraPose(0.4, 30.0)),
    dict(camera_matrix=np.diag([np.nan, 500.0, 1.0]), pose=CameraPose(0.4, 30.0)),
    dict(camera_matrix=K_640, pose=CameraPose(-0.1, 30.0)),
    dict(camera_matrix=K_640, pose=CameraPose(0.0, 30.0)),
])
def test_impossible_cameras_are_refused(bad: dict[str, object]) -> None:
    with pytest.raises(ValueError):
        GroundModel(bad["camera_matrix"], bad["pose"], (640, 480))  # type: ignore[arg-type]


def test_the_default_ground_model_is_the_simulators_default_camera() -> None:
    from lanewarden.scenarios.camera import CameraModel

    model = default_ground_model((640, 480))
    np.testing.assert_allclose(model.floor_to_image_h,
                               CameraModel().ground_to_image_homography())
    assert model.pose == CameraPose(height_m=0.40, pitch_deg=35.0, forward_m=0.15)
