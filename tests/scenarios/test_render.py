"""The synthetic camera: geometry (a floor point lands where the camera model says), distortion,
noise, blur, and the ground-truth tape visibility against perception's ROI."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from lanewarden.actuation.base import Pose2D
from lanewarden.assembly import build_stack
from lanewarden.perception.detector import perception_gray
from lanewarden.scenarios.camera import CameraModel
from lanewarden.scenarios.render import CameraRenderer
from lanewarden.scenarios.texture import GroundTexture, paint_ground
from lanewarden.scenarios.world import build_world
from tests.scenarios.helpers import straight_spec

RES = 0.002  # m per texture pixel


def dot_texture(points: list[tuple[float, float]], radius_m: float = 0.012,
                radii_m: list[float] | None = None) -> GroundTexture:
    """A plain light floor, 8 x 8 m from (-2, -4), with dark dots at world `points`."""
    size = int(8.0 / RES)
    gray = np.full((size, size), 200, np.uint8)
    texture = GroundTexture(gray=gray, bgr=None, m_per_px=RES, x_min=-2.0, y_max=4.0,
                            fill_gray=200, fill_bgr=(200, 200, 200))
    radii = radii_m or [radius_m] * len(points)
    for px, r in zip(texture.world_to_px(np.array(points)), radii, strict=True):
        cv2.circle(gray, (round(px[0] * 16), round(px[1] * 16)), round(r / RES * 16), 20,
                   -1, cv2.LINE_AA, shift=4)
    return texture


def dark_centroid(image: np.ndarray, near: np.ndarray, window: int = 25) -> np.ndarray:
    x0, y0 = max(0, int(near[0]) - window), max(0, int(near[1]) - window)
    patch = image[y0:int(near[1]) + window, x0:int(near[0]) + window].astype(np.float64)
    weight = np.clip(200.0 - patch, 0, None)
    ys, xs = np.mgrid[0:patch.shape[0], 0:patch.shape[1]]
    total = weight.sum()
    return np.array([(weight * xs).sum() / total + x0, (weight * ys).sum() / total + y0])


@pytest.mark.parametrize("size", [(640, 480), (320, 240)])
@pytest.mark.parametrize("pose", [Pose2D(0.0, 0.0, 0.0), Pose2D(0.3, -0.2, math.radians(25)),
                                  Pose2D(-0.1, 0.2, math.radians(100))])
def test_floor_point_lands_where_the_camera_model_says(size: tuple[int, int], pose: Pose2D) -> None:
    camera = CameraModel(width_px=size[0], height_px=size[1])
    # Floor points in the robot frame: centre, near corners (strong distortion), far.
    robot_points = np.array([[0.7, 0.0], [0.42, 0.26], [0.45, -0.28], [1.6, 0.5], [2.5, -0.3]])
    c, s = math.cos(pose.theta_rad), math.sin(pose.theta_rad)
    world_points = [(pose.x_m + c * x - s * y, pose.y_m + s * x + c * y) for x, y in robot_points]
    # Dots a few pixels wide whatever their distance.
    radii = [0.012 * float(np.hypot(x, y)) / 0.5 * 640 / size[0] for x, y in robot_points]
    renderer = CameraRenderer(dot_texture(world_points, radii_m=radii), camera, noise_sigma=0.0,
                              exposure_s=0.0)
    image = renderer.render_gray(pose, np.empty((size[1], size[0]), np.uint8))
    expected = camera.project_ground(robot_points, distort=True)
    ideal = camera.project_ground(robot_points, distort=False)
    scale = size[0] / 640
    # A disc's image centroid is the mean of the projections of its area (perspective shifts it
    # slightly from the projection of its centre).
    gx, gy = np.meshgrid(np.linspace(-1, 1, 41), np.linspace(-1, 1, 41))
    disc = np.column_stack([gx.ravel(), gy.ravel()])
    disc = disc[(disc**2).sum(axis=1) <= 1.0]
    for point, radius, want in zip(robot_points, radii, expected, strict=True):
        assert 0 <= want[0] < size[0] and 0 <= want[1] < size[1]
        centroid = camera.project_ground(point + radius * disc).mean(axis=0)
        found = dark_centroid(image, want, window=max(8, round(25 * scale)))
        # Far away a pixel point-samples several cm of floor: allow for that quantisation.
        tolerance = 0.25 if np.hypot(*point) < 1.0 else 0.6
        assert np.hypot(*(found - centroid)) < tolerance, (found, centroid)
    # Distortion matters: near the corners the real pixel is far from the pinhole one.
    assert np.hypot(*(expected[1] - ideal[1])) > 10 * scale


def test_undistorted_rendering_matches_the_pinhole_projection() -> None:
    camera = CameraModel()
    robot_points = np.array([[0.6, 0.1], [0.45, 0.25]])
    renderer = CameraRenderer(dot_texture([tuple(p) for p in robot_points]), camera,
                              noise_sigma=0.0, exposure_s=0.0, distorted=False)
    image = renderer.render_gray(Pose2D(), np.empty((480, 640), np.uint8))
    for want in camera.project_ground(robot_points, distort=False):
        assert np.hypot(*(dark_centroid(image, want) - want)) < 0.35


def test_noise_is_seeded_and_blur_smears_sideways_when_turning() -> None:
    camera = CameraModel(width_px=320, height_px=240)
    texture = dot_texture([(0.7, 0.0)])
    out = np.empty((240, 320), np.uint8)

    def frame(seed: int, velocity: tuple[float, float] = (0.0, 0.0), sigma: float = 3.0,
              exposure: float = 0.0) -> np.ndarray:
        r = CameraRenderer(texture, camera, noise_sigma=sigma, exposure_s=exposure, seed=seed)
        return r.render_gray(Pose2D(), out, velocity, r.next_noise_index()).copy()

    assert np.array_equal(frame(1), frame(1))
    assert not np.array_equal(frame(1), frame(2))
    assert 1.5 < np.std(frame(1).astype(float) - frame(1, sigma=0.0)) < 4.5
    sharp = frame(0, sigma=0.0, exposure=0.02)
    turning = frame(0, (0.0, 1.5), sigma=0.0, exposure=0.02)
    centre = camera.project_ground(np.array([[0.7, 0.0]]))[0].round().astype(int)
    row_sharp = sharp[centre[1], centre[0] - 15:centre[0] + 15].astype(int)
    row_blur = turning[centre[1], centre[0] - 15:centre[0] + 15].astype(int)
    # The dot is spread sideways: wider, with softer edges.
    assert (row_blur < 190).sum() > (row_sharp < 190).sum() + 4
    assert np.abs(np.diff(row_blur)).max() < np.abs(np.diff(row_sharp)).max() / 2


@pytest.mark.parametrize("bank", [2, 3, 12])
def test_a_still_camera_never_delivers_the_same_image_twice_in_a_row(bank: int) -> None:
    """A real sensor never repeats its noise; the supervisor does not count an image identical
    to the previous one towards engaging (a frozen camera), so a robot standing still in the
    simulator must see a new image every frame, and every noise frame of the bank is used."""
    camera = CameraModel(width_px=160, height_px=120)
    renderer = CameraRenderer(dot_texture([(0.7, 0.0)]), camera, noise_sigma=2.0, seed=5,
                              noise_bank_frames=bank)
    out = np.empty((120, 160), np.uint8)
    indices, previous = [], None
    for _ in range(200):
        index = renderer.next_noise_index()
        image = renderer.render_gray(Pose2D(), out, (0.0, 0.0), index).copy()
        assert previous is None or not np.array_equal(image, previous)
        indices.append(index)
        previous = image
    assert all(a != b for a, b in zip(indices, indices[1:], strict=False))
    assert sorted(set(indices)) == list(range(bank))


def test_texture_is_deterministic_per_seed_and_gray_matches_colour() -> None:
    world = build_world(straight_spec(1.0), margin_m=1.0)
    a = paint_ground(world, 0.005, seed=3, color=True)
    b = paint_ground(world, 0.005, seed=3, color=False)
    c = paint_ground(world, 0.005, seed=4, color=False)
    assert np.array_equal(a.gray, b.gray)
    assert not np.array_equal(b.gray, c.gray)
    assert a.bgr is not None
    luma = perception_gray(a.bgr).astype(int)
    assert np.abs(luma - a.gray.astype(int)).max() <= 2
    # Tape pixels are dark, floor pixels light (default dark tape on light tiles).
    tape_px = a.world_to_px(np.array([[0.5, 0.3], [0.5, -0.3]])).round().astype(int)
    floor_px = a.world_to_px(np.array([[0.55, 0.1]])).round().astype(int)
    assert all(a.gray[r, col] < 70 for col, r in tape_px)
    assert a.gray[floor_px[0, 1], floor_px[0, 0]] > 150


@pytest.mark.parametrize("size", [(640, 480), (320, 240)])
def test_default_roi_sees_both_tapes_at_the_start_of_straight(size: tuple[int, int]) -> None:
    from lanewarden.config import LanewardenConfig
    from lanewarden.scenarios.library import resolve_scenario
    from lanewarden.scenarios.metrics import points_in_polygon
    from lanewarden.scenarios.simulator import Simulation, effective_config
    from lanewarden.scenarios.spec import with_overrides

    spec = resolve_scenario("straight")
    overrides = {"simulation": {"width_px": size[0], "height_px": size[1],
                                "texture_mm_per_px": 2.5 * 640 / size[0]}}
    config = effective_config(with_overrides(LanewardenConfig(), overrides, "test"), spec)
    sim = Simulation(spec, config, build_stack)
    start = sim.world.start_pose
    h_cam = sim.camera.ground_to_image_homography()
    w, h = size
    # Ground truth: each tape has floor points inside perception's (default) ROI, in the image.
    for tape in sim.world.tapes:
        pts = tape.surface_samples()
        rel = pts - (start.x_m, start.y_m)  # the lane starts along +x at the origin
        ahead = rel[rel[:, 0] > 0.0]
        hom = np.column_stack([ahead, np.ones(len(ahead))]) @ h_cam.T
        uv = hom[:, :2] / hom[:, 2:3]
        in_image = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
        assert points_in_polygon(uv[in_image], sim.roi_polygon_px).sum() > 50, tape.side
    # And the real detector finds both edges, confidently, in the rendered frame.
    image = sim.renderer.render_gray(start, np.empty((h, w), np.uint8))
    observation = sim.detector.detect(image, 0, 0.0)
    assert observation.left is not None and observation.right is not None
    assert observation.confidence >= config.supervisor.confidence_confident_min
    assert observation.slope_sum is not None and abs(observation.slope_sum) < 1.0


@pytest.mark.parametrize("floor", [
    {"kind": "tiles", "grid_angle_deg": 20.0}, {"kind": "plain"}, {"kind": "wood"},
    {"kind": "noisy"}])
def test_every_floor_kind_paints_a_floor_the_tape_stands_out_on(floor: dict[str, object]) -> None:
    from tests.scenarios.helpers import spec_from

    spec = spec_from({"floor": floor, "lane": {"segments": [{"straight_m": 1.0}]}})
    texture = paint_ground(build_world(spec, margin_m=1.0), 0.004, seed=0, color=False)
    tape = texture.world_to_px(np.array([[0.5, 0.3]])).round().astype(int)[0]
    floor_patch = texture.gray[:100, :100].astype(float)
    assert texture.gray[tape[1], tape[0]] < floor_patch.mean() - 60
    assert floor_patch.std() > 1.0  # textured, not flat
