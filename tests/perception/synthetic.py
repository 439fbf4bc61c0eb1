"""Synthetic camera frames of a taped lane with known geometry, for perception tests.

The floor is described top-down in the LANE frame (metres; s along the lane centreline, d to its
left): tiles, tapes (solid or dashed, straight or bending), and the robot's pose on it. Every image
pixel is mapped to the floor point it sees through `scenarios.camera.CameraModel` (the simulator's
camera), so the geometry in the image is exactly the camera's: straight floor lines are straight in
the undistorted view and bent by the lens in the distorted one.

Rendering: 2x supersampled, area-averaged down, plus seeded Gaussian noise. Pure function of its
arguments (no clock, no global randomness).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from scenarios.camera import CameraModel

FloatArray = NDArray[np.float64]

TAPE_WIDTH_M = 0.048
TAPE_SPACING_M = 0.60  # between the two tapes' centres
TILE_M = 0.30
GROUT_M = 0.004


@dataclass(frozen=True)
class Bend:
    """The lane turns `direction` with centreline radius `radius_m`, starting `start_m` ahead."""

    direction: Literal["left", "right"]
    radius_m: float = 0.8
    start_m: float = 0.5


@dataclass(frozen=True)
class Scene:
    """A floor, an optional lane on it, and the robot's pose relative to the lane.

    - `lateral_m`: robot position left (+) / right (-) of the lane centreline.
    - `yaw_deg`: robot heading relative to the lane, counter-clockwise (to the left) positive.
    - `tapes`: which tapes exist ("left", "right"); empty for no lane.
    - `dash_m`: (dash, gap) lengths for dashed tape, None for solid.
    - `lane_start_m` / `lane_end_m`: tape starts / stops this far along the lane (None: never
      stops).
    """

    floor_level: float = 175.0
    tiles: bool = False
    grout_level: float = 115.0
    tile_offset_m: tuple[float, float] = (0.10, 0.10)
    tapes: tuple[str, ...] = ("left", "right")
    tape_level: float = 45.0
    dash_m: tuple[float, float] | None = None
    bend: Bend | None = None
    lane_start_m: float = -0.5
    lane_end_m: float | None = None
    lateral_m: float = 0.0
    yaw_deg: float = 0.0
    noise_sigma: float = 3.0
    wall_level: float = 90.0
    seed: int = 0


@lru_cache(maxsize=8)
def _ground_grid(width: int, height: int, distorted: bool) -> tuple[FloatArray, FloatArray]:
    camera = _camera_at(width, height)
    gx, gy = camera.pixel_ground_points(distorted=distorted)
    gx.setflags(write=False)
    gy.setflags(write=False)
    return gx, gy


def _camera_at(width: int, height: int) -> CameraModel:
    """The default camera, scaled to another resolution (same field of view and mount)."""
    return replace(CameraModel(), width_px=width, height_px=height)


def _lane_coordinates(
    x: FloatArray, y: FloatArray, bend: Bend | None
) -> tuple[FloatArray, FloatArray]:
    """Lane-frame floor points -> (s along the centreline, d left of it)."""
    s = x.copy()
    d = y.copy()
    if bend is None:
        return s, d
    r = bend.radius_m
    ahead = x >= bend.start_m
    dx = x[ahead] - bend.start_m
    if bend.direction == "right":
        dy = y[ahead] + r
        dist = np.hypot(dx, dy)
        d[ahead] = dist - r
        phi = np.arctan2(dx, dy)
    else:
        dy = r - y[ahead]
        dist = np.hypot(dx, dy)
        d[ahead] = r - dist
        phi = np.arctan2(dx, dy)
    s[ahead] = bend.start_m + r * phi
    return s, d


def render(
    scene: Scene,
    width: int = 640,
    height: int = 480,
    *,
    distorted: bool = False,
    supersample: int = 2,
) -> np.ndarray:
    """A BGR uint8 (height, width, 3) frame of `scene` seen by the default camera.

    `distorted=True` renders what the real lens delivers (barrel distortion of `CameraModel`);
    otherwise the ideal pinhole view.
    """
    gx, gy = _ground_grid(width * supersample, height * supersample, distorted)
    floor = np.isfinite(gx)
    yaw = math.radians(scene.yaw_deg)
    gxf = np.where(floor, gx, 0.0)
    gyf = np.where(floor, gy, 0.0)
    # Robot frame -> lane frame: rotate by the robot's yaw, shift by its lateral position.
    x = math.cos(yaw) * gxf - math.sin(yaw) * gyf
    y = math.sin(yaw) * gxf + math.cos(yaw) * gyf + scene.lateral_m

    img = np.full(gx.shape, scene.floor_level, dtype=np.float64)
    if scene.tiles:
        ox, oy = scene.tile_offset_m
        gu = np.mod(x - ox, TILE_M) < GROUT_M
        gv = np.mod(y - oy, TILE_M) < GROUT_M
        img[gu | gv] = scene.grout_level
    if scene.tapes:
        s, d = _lane_coordinates(x, y, scene.bend)
        on_tape = np.abs(np.abs(d) - TAPE_SPACING_M / 2.0) <= TAPE_WIDTH_M / 2.0
        side_ok = np.zeros_like(on_tape)
        if "left" in scene.tapes:
            side_ok |= d > 0
        if "right" in scene.tapes:
            side_ok |= d < 0
        on_tape &= side_ok & (s > scene.lane_start_m)
        if scene.dash_m is not None:
            dash, gap = scene.dash_m
            on_tape &= np.mod(s, dash + gap) < dash
        if scene.lane_end_m is not None:
            on_tape &= s < scene.lane_end_m
        img[on_tape] = scene.tape_level
    # Far floor fades into the wall colour (haze), so the horizon is not a razor edge.
    dist = np.where(floor, np.hypot(gxf, gyf), np.inf)
    fade = np.clip((dist - 6.0) / 6.0, 0.0, 1.0)
    img = img * (1.0 - fade) + scene.wall_level * fade
    img[~floor] = scene.wall_level

    small = cv2.resize(img.astype(np.float32), (width, height), interpolation=cv2.INTER_AREA)
    rng = np.random.default_rng(scene.seed)
    small = small + rng.normal(0.0, scene.noise_sigma, small.shape).astype(np.float32)
    gray = np.clip(np.rint(small), 0, 255).astype(np.uint8)
    # A faint colour cast so the detector's BGR->gray path is exercised, not just gray input.
    bgr = np.dstack([gray, gray, gray]).astype(np.int16)
    bgr[..., 0] -= 6
    bgr[..., 2] += 6
    return np.clip(bgr, 0, 255).astype(np.uint8)


@lru_cache(maxsize=64)
def _cached(scene: Scene, width: int, height: int, distorted: bool) -> np.ndarray:
    image = render(scene, width, height, distorted=distorted)
    image.setflags(write=False)
    return image


def frame(
    scene: Scene, width: int = 640, height: int = 480, *, distorted: bool = False
) -> np.ndarray:
    """`render`, memoised (read-only result): tests share frames instead of re-rendering."""
    return _cached(scene, width, height, distorted)


# The acceptance scenes (named so tests, the benchmark and the docs use the same pictures).
STRAIGHT = Scene()
# The robot at the entrance of a bend of 0.8 m radius (lane centreline), which starts 0.3 m ahead
# of its centre, i.e. just below the bottom of the image (the camera sees from 0.36 m on).
BEND_LEFT = Scene(bend=Bend("left", radius_m=0.8, start_m=0.3))
BEND_RIGHT = Scene(bend=Bend("right", radius_m=0.8, start_m=0.3))
ONE_EDGE = Scene(tapes=("left",))
NO_LANE = Scene(tapes=())
TILES_ONLY = Scene(tiles=True, tapes=())
TILES_WITH_TAPE = Scene(tiles=True)
DASHED = Scene(dash_m=(0.15, 0.10))
LIGHT_ON_DARK = Scene(floor_level=70.0, tape_level=225.0, wall_level=40.0)
DARK_ON_LIGHT = Scene(floor_level=200.0, tape_level=35.0)
OFFSET_LEFT = Scene(lateral_m=0.08)  # robot left of the centreline: lane centre right in image
OFFSET_RIGHT = Scene(lateral_m=-0.08)
